"""A goal-conditioned slide (``SlideGym/TopSlideGoal-v0``), in panda-gym's convention.

The desired goal is a graspable plate pose drawn at reset; achieved and desired goals are
``(x, y, cos yaw, sin yaw)``; :meth:`TopSlideGoalEnv.compute_reward` is vectorised, so
Stable-Baselines3's ``HerReplayBuffer`` can relabel goals.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import shapely
from gymnasium import spaces

from slide_gym.envs.observation import POS_BOUND, box
from slide_gym.envs.top_slide import TopSlideEnv
from slide_gym.geometry import ObjectShape, TableShape, overhang, transform_polygon
from slide_gym.planning.params import SlideParams
from slide_gym.planning.plate_goals import PlateGoalPoses
from slide_gym.planning.regions import goal_band
from slide_gym.robot.model import PINCH_EDGE_CLEARANCE
from slide_gym.task import ADMISSIBLE_CENTROID_MARGIN, REACH_MAX, REACH_MIN, SceneState

POS_TOLERANCE = 0.02
"""Largest plate position error (m) that counts as reaching the goal."""
YAW_TOLERANCE = 0.3
"""Largest plate yaw error (rad) that counts as reaching the goal."""
GOAL_EXTRA_OVERHANG = (0.005, 0.025)
"""A drawn goal overhangs by ``u*`` plus an amount in this range (m)."""
GOAL_CENTROID_MARGIN = 0.01
"""A drawn goal keeps the plate's centroid this far (m) inside the table outline."""
_BAND_WIDTH = SlideParams.goal_band_width  # m: the planner's goal band P_g


def goal_vector(pose: Any) -> np.ndarray:
    """``(x, y, yaw)`` -> the goal vector ``(x, y, cos yaw, sin yaw)``, float32."""
    x, y, yaw = (float(v) for v in pose)
    return np.array([x, y, math.cos(yaw), math.sin(yaw)], dtype=np.float32)


def goal_errors(achieved: np.ndarray, desired: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position (m) and yaw (rad) errors between goal vectors, over any leading batch axes."""
    a, d = np.asarray(achieved, dtype=float), np.asarray(desired, dtype=float)
    pos = np.linalg.norm(a[..., :2] - d[..., :2], axis=-1)
    cross = a[..., 2] * d[..., 3] - a[..., 3] * d[..., 2]
    dot = a[..., 2] * d[..., 2] + a[..., 3] * d[..., 3]
    return pos, np.abs(np.arctan2(cross, dot))


def sample_goal_pose(
    obj: ObjectShape,
    table: TableShape,
    rng: np.random.Generator,
    u_star: float,
    tries: int = 20000,
) -> np.ndarray:
    """A random graspable pose ``(x, y, yaw)``: overhang ``u* + GOAL_EXTRA_OVERHANG`` past an
    edge stretch where a side grasp is within the arm's reach (the planner's goal band), the
    centroid ``GOAL_CENTROID_MARGIN`` inside the table and between ``REACH_MIN`` and
    ``REACH_MAX`` from the robot base.

    A plate too small for that (its circumradius short of the largest such overhang plus the
    margin) gets a pose from the planner's size-aware goal poses instead
    (:class:`~slide_gym.planning.plate_goals.PlateGoalPoses`: its farthest point faces the
    edge, overhang at least u*, centroid ``ADMISSIBLE_CENTROID_MARGIN`` inside), so every
    plate the task admits has goals."""
    band = goal_band(
        table.polygon, _BAND_WIDTH, table.height + 0.5 * obj.thickness, PINCH_EDGE_CLEARANCE
    )
    inner = table.polygon.buffer(-GOAL_CENTROID_MARGIN)
    if band.is_empty or inner.is_empty:
        raise ValueError(f"table {table.name!r} has no reachable edge to slide a plate over")
    shapely.prepare(inner)
    minx, miny, maxx, maxy = table.polygon.bounds
    lo, hi = (u_star + extra for extra in GOAL_EXTRA_OVERHANG)
    if obj.circumradius < hi + GOAL_CENTROID_MARGIN:
        return _small_plate_goal(obj, table, band, rng, u_star, tries)
    for _ in range(tries):
        x, y = rng.uniform(minx, maxx), rng.uniform(miny, maxy)
        yaw = rng.uniform(-math.pi, math.pi)
        if not REACH_MIN <= math.hypot(x, y) <= REACH_MAX or not shapely.contains_xy(inner, x, y):
            continue
        over = overhang(transform_polygon(obj.polygon, x, y, yaw), table.polygon)
        if lo <= over.u <= hi and band.distance(over.outside.centroid) <= over.u:
            return np.array([x, y, yaw])
    raise ValueError(
        f"found no graspable goal pose for object {obj.name!r} on table {table.name!r} in "
        f"{tries} random tries (overhang {lo:.3f}-{hi:.3f} m with the centroid on the table)"
    )


def _small_plate_goal(
    obj: ObjectShape,
    table: TableShape,
    band: shapely.Geometry,
    rng: np.random.Generator,
    u_star: float,
    tries: int,
) -> np.ndarray:
    margin = ADMISSIBLE_CENTROID_MARGIN
    if not obj.can_overhang(u_star, margin):
        raise ValueError(
            f"object {obj.name!r} cannot overhang u* = {u_star} m with its centroid {margin} m "
            f"on the table (its farthest point is {obj.circumradius:.3f} m from its centroid)"
        )
    poses = PlateGoalPoses(obj.polygon, table.polygon, band, u_star, margin)
    for _ in range(tries):
        pose = poses.sample(rng)
        if pose is not None and REACH_MIN <= math.hypot(pose[0], pose[1]) <= REACH_MAX:
            return pose
    raise ValueError(
        f"found no graspable goal pose for object {obj.name!r} on table {table.name!r} in "
        f"{tries} draws of its size-aware goal poses"
    )


class TopSlideGoalEnv(TopSlideEnv):
    """Slide a plate to a given graspable pose: the slide task, goal-conditioned for HER.

    The world, actions and ``reset`` options are those of
    :class:`~slide_gym.envs.top_slide.TopSlideEnv` with ``goal="slide"``.

    ## Observation Space
    A ``Dict`` of float32 boxes:

    - ``observation``: every entry of ``TopSlideEnv``'s state observation (joint states,
      hand command, fingertip and object poses, object velocity, outline descriptors, table
      height; 368 values), flattened and concatenated in the order of its sorted keys;
    - ``achieved_goal``: the plate's ``(x, y, cos yaw, sin yaw)`` (m, world);
    - ``desired_goal``: the same for the goal pose.

    ## Goal
    Drawn at reset from the env's generator (so a seed gives the same goal): a graspable pose,
    the plate overhanging the line of a reachable table edge by ``u*`` + 0.5-2.5 cm with its
    centroid at least 1 cm inside the table and within reach (:func:`sample_goal_pose`).
    ``reset(options={"goal": (x, y, yaw)})`` sets it instead (any finite pose).
    ``info["goal_pose"]`` holds it as ``(x, y, yaw)``.

    ## Rewards
    :meth:`compute_reward` ``(achieved_goal, desired_goal, info)``: 0 if the plate lies within
    ``pos_tolerance`` (2 cm) and ``yaw_tolerance`` (0.3 rad) of the goal, else -1 (panda-gym's
    sparse convention), vectorised over leading batch axes. It is a function of the goals
    alone, as HER needs: reaching the goal does not ask the hand to let go, and a pose within
    tolerance is not always graspable (``info["graspable"]`` says; a 2 cm shortfall can cost
    the 0.5 cm margin). ``info["reward_terms"]`` is ``{"goal": reward}``.

    ## Episode End
    Success (``info["is_success"]``, the same test as the reward) terminates, as does the
    plate falling off the table; the registered time limit is 800 steps. ``info`` carries
    ``TopSlideEnv``'s keys plus ``goal_pose``, ``goal_distance_m`` and ``goal_angle_rad``.

    ## Arguments
    ``TopSlideEnv``'s, except ``goal``, ``reward_type`` and ``obs_mode`` (fixed: ``"slide"``,
    goal-based, ``"state"``), plus ``pos_tolerance`` and ``yaw_tolerance``.
    """

    def __init__(
        self,
        object: str | ObjectShape = "square",  # noqa: A002 - the public argument name
        table: str | TableShape = "square",
        pos_tolerance: float = POS_TOLERANCE,
        yaw_tolerance: float = YAW_TOLERANCE,
        **kwargs: Any,
    ):
        fixed = sorted({"goal", "reward_type", "obs_mode"} & set(kwargs))
        if fixed:
            raise ValueError(f"TopSlideGoalEnv fixes {', '.join(fixed)}; do not pass them")
        for name, value in (("pos_tolerance", pos_tolerance), ("yaw_tolerance", yaw_tolerance)):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value}")
        self.pos_tolerance, self.yaw_tolerance = float(pos_tolerance), float(yaw_tolerance)
        self._goal_pose = np.zeros(3)
        super().__init__(object=object, table=table, goal="slide", reward_type="sparse", **kwargs)
        state = self.observer.space
        self._keys = tuple(state.spaces)
        low = np.concatenate([state[k].low.reshape(-1) for k in self._keys])
        high = np.concatenate([state[k].high.reshape(-1) for k in self._keys])
        goal_low = np.array([-POS_BOUND, -POS_BOUND, -1.0, -1.0], dtype=np.float32)
        self.observation_space = spaces.Dict(
            {
                "observation": box(low, high, low.shape),
                "achieved_goal": box(goal_low, -goal_low, (4,)),
                "desired_goal": box(goal_low, -goal_low, (4,)),
            }
        )

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        options = dict(options or {})
        goal = options.pop("goal", None)
        if goal is not None:
            try:
                arr = np.asarray(goal, dtype=float).reshape(-1)
            except (TypeError, ValueError):
                arr = np.array([])
            if arr.shape != (3,) or not np.all(np.isfinite(arr)):
                raise ValueError(f"goal must be 3 finite numbers (x, y, yaw), got {goal!r}")
        super().reset(seed=seed, options=options)
        assert self._state is not None and self.task.object is not None
        if goal is None:
            p = self.task.params
            arr = sample_goal_pose(self.task.object, self.task.table, self.np_random, p.u_star)
        self._goal_pose = arr
        self._is_success = self._success(self._state)
        self._reward(self._state, self._is_success)
        return self._observation(), self._info(self._state)

    def compute_reward(
        self, achieved_goal: np.ndarray, desired_goal: np.ndarray, info: Any
    ) -> np.ndarray:
        """0 where the achieved goal is within tolerance of the desired one, else -1 (float32,
        the batch shape of the inputs; ``info`` is not used)."""
        pos, ang = goal_errors(achieved_goal, desired_goal)
        reached = (pos <= self.pos_tolerance) & (ang <= self.yaw_tolerance)
        return -(~reached).astype(np.float32)

    # --------------------------------------------------------------- helpers
    def _achieved(self, s: SceneState) -> np.ndarray:
        return goal_vector(s.object_pose)

    def _success(self, s: SceneState) -> bool:
        return bool(self.compute_reward(self._achieved(s), goal_vector(self._goal_pose), None) == 0)

    def _reward(self, s: SceneState, success: bool) -> float:
        reward = float(self.compute_reward(self._achieved(s), goal_vector(self._goal_pose), None))
        self._reward_terms = {"goal": reward}
        return reward

    def _info(self, s: SceneState) -> dict[str, Any]:
        pos, ang = goal_errors(self._achieved(s), goal_vector(self._goal_pose))
        return {
            **super()._info(s),
            "goal_pose": tuple(float(v) for v in self._goal_pose),
            "goal_distance_m": float(pos),
            "goal_angle_rad": float(ang),
        }

    def _observation(self) -> dict[str, np.ndarray]:
        obs = super()._observation()
        assert self._state is not None
        flat = np.concatenate([obs[k].reshape(-1) for k in self._keys]).astype(np.float32)
        bounds = self.observation_space["desired_goal"]  # the same for both goals
        return {
            "observation": flat,
            "achieved_goal": np.clip(self._achieved(self._state), bounds.low, bounds.high),
            "desired_goal": np.clip(goal_vector(self._goal_pose), bounds.low, bounds.high),
        }
