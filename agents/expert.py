"""One episode of the planner-driven expert: plan, press, slide, re-aim, grasp, lift.

:class:`SlideGraspExpert` turns a :class:`~slide_gym.planning.TopSlidePlanner` result into the
environment's joint-increment actions. It reads everything from observations (scene outlines,
object pose, fingertip pose) and keeps its own copy of the environment's arm targets.

Phases: ``approach`` (joint-space move to a pose above the press point, via a raised pose if
the direct move would hit something), ``press`` (straight down to the planned contact depth),
``slide`` (the planned path), then a check of the real plate pose against Eq. 2's prediction.
A graspable plate gets a grasp re-aimed at its measured pose: ``lift_off``, ``transfer`` (around
to a stand-off outside the table edge), ``approach_grasp``, ``close``, ``lift``. A plate left
ungraspable is re-planned from where it lies, within the total planning budget.

While pressing and sliding the fingertip drags the plate, and finger compliance shifts the tip
sideways as it is pressed; a small integral loop on the observed fingertip position adds a
Cartesian correction to the planned joint targets so the real tip follows the planned one.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np
import shapely

from agents.scene import SceneLibrary
from agents.trajectory import Segment, time_segment
from slide_gym.geometry import ObjectShape, TableShape, overhang, transform_polygon
from slide_gym.planning.api import (
    GraspParams,
    IKParams,
    IKTarget,
    SlideParams,
    TopSlidePlanner,
    TopSlideProblem,
    fingertip_chain,
    grasp_chain,
    planar_pose,
    slid_object_pose,
    solve_ik,
)
from slide_gym.planning.kin import FastChain
from slide_gym.robot.model import ARM_LOWER, ARM_UPPER

EXPERT_SLIDE_PARAMS = SlideParams(
    dz=(0.012, 0.02),
    press_radius=0.015,
    press_edge_margin=0.008,
    u_star=0.04,
    centroid_margin=0.015,
    max_rotation=0.8,
    grasp=GraspParams(retreat=0.06),
)
"""Planner settings the expert uses by default, with margins for the real slide:

- contact depth 1.2-2.0 cm: shallower presses let the fingertip slip over the plate, deeper
  ones bring finger B within millimetres of the plate top;
- press points at least 8 mm inside the plate's outline (a rounded tip slips off an edge),
  and of those, the ones within 1.5 cm of the one nearest the plate's centroid (the plate
  then hardly spins about the tip);
- a planned overhang of 4 cm (1 cm more than the task's u*) with the centroid at least
  1.5 cm inside the edge;
- at most 0.8 rad of plate rotation: in larger turns the plate slips about the fingertip;
- the grasp approached from a stand-off 6 cm out, clear of the plate's corners."""


@dataclass(frozen=True)
class ExpertParams:
    """Execution speeds, heights and gains (SI units)."""

    approach_speed: float = 1.0  # rad/s, free-space joint speed
    pre_contact_height: float = 0.05  # m above the press point before pressing
    press_speed: float = 0.02  # m/s fingertip speed while pressing
    press_hold_s: float = 0.3
    slide_speed: float = 0.03  # m/s fingertip speed along the slide
    transfer_speed: float = 0.6  # rad/s
    transfer_tip_speed: float = 0.1  # m/s of the grasp frame during the transfer
    lift_off_height: float = 0.06  # m the fingertip rises off the plate after the slide
    grasp_budget: float = 1.0  # s to re-aim the grasp at the measured pose
    settle_s: float = 0.5  # s at the stand-off pose: the arm settles before the approach
    grasp_speed: float = 0.04  # m/s on the final approach to the grasp
    close_s: float = 0.8  # hand closing time before lifting
    lift: float = 0.12  # m the grasp frame rises
    lift_speed: float = 0.05  # m/s
    tip_gain: float = 0.3  # per control step, integral gain of the fingertip loop
    object_gain: float = 0.02  # per control step, integral gain of the plate-pose loop
    max_object_correction: float = 0.03  # m
    slide_settle_s: float = 0.5  # s at the slide's end: the plate comes to rest, still pressed
    contact_deflection: float = 0.05  # rad of finger A's proximal joint: it is pressing
    max_correction: float = 0.04  # m, largest Cartesian correction of the fingertip
    max_replans: int = 2
    pull_back_margin: float = 0.012  # m: a slid plate's centroid closer to the edge is pulled back
    grasp_u_star: float = 0.032  # m, least real overhang to go for the grasp (task: 0.03)

    def __post_init__(self) -> None:
        for name, value in dataclasses.asdict(self).items():
            if name == "max_replans":
                if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                    raise ValueError(f"max_replans must be an integer >= 0, got {value!r}")
            elif not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"ExpertParams.{name} must be a finite positive number: {value}")


def quat_yaw(quat: np.ndarray) -> float:
    """Yaw (rad) of an xyzw quaternion."""
    x, y, z, w = (float(v) for v in quat)
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def wrap_angle(a: float) -> float:
    """``a`` wrapped to [-pi, pi)."""
    return (a + math.pi) % (2 * math.pi) - math.pi


_LOCAL_IK = IKParams(n_restarts=1)  # the seed only: no jump to another IK branch
_LINE_STEP = 0.01  # m between the IK waypoints of a straight Cartesian move
_LINE_MAX_JOINT_STEP = 0.3  # rad: a larger change between waypoints means a branch switch


@dataclass
class _Step:
    q: np.ndarray
    hand: float
    phase: str
    track: bool
    object_xy: np.ndarray | None = None  # where Eq. 2 puts the plate at this step


class SlideGraspExpert:
    """The planner as a closed-loop controller for one episode (see the module docstring).

    Args:
        planner: ``"regions"``, ``"cbirrt"`` or ``"cbirrt2"``.
        time_budget: total planning time (s) over the first plan and any replans.
        slide_params: planner parameters.
        params: execution parameters.
        seed: seeds the planner and the expert's own IK restarts (with the observed pose).
        library: known shapes for recognising the scene.
        control_dt: seconds per environment step; ``max_joint_step``: the env's action scale.
    """

    def __init__(
        self,
        planner: str,
        time_budget: float,
        slide_params: SlideParams,
        params: ExpertParams,
        seed: int,
        library: SceneLibrary,
        control_dt: float,
        max_joint_step: float,
    ):
        self.planner_name, self.time_budget = planner, float(time_budget)
        self.slide_params, self.params, self.seed = slide_params, params, int(seed)
        self.library, self.dt, self.max_joint_step = library, control_dt, max_joint_step
        self.tip: FastChain = fingertip_chain()
        self.hand: FastChain = grasp_chain()
        self.queue: deque[_Step] = deque()
        self.phase = "plan"
        self.q_cmd: np.ndarray | None = None
        self.hand_cmd = 0.0
        self.correction = np.zeros(2)
        self.object_offset = np.zeros(2)
        self.planner: TopSlidePlanner | None = None
        self.obj: ObjectShape | None = None
        self.table: TableShape | None = None
        self.rng = np.random.default_rng(self.seed)
        self.report: dict[str, Any] = {
            "planned": False,
            "replans": 0,
            "planning_time_s": 0.0,
            "plan_status": None,
            "failure": None,
            "object_predicted_pose": None,
            "object_slid_pose": None,
            "slide_error_m": None,
            "slide_error_rad": None,
            "events": [],
        }

    # ------------------------------------------------------------------ act
    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """The next action (8,) for observation ``obs``."""
        if self.q_cmd is None:
            self.q_cmd = np.asarray(obs["arm_qpos"], dtype=float).copy()
            self.obj = self.library.object_from(obs["object_outline"])
            self.table = self.library.table_from(obs["table_outline"], obs["table_height"][0])
        while not self.queue and self.phase not in ("done", "failed"):
            self._advance(obs)
        if not self.queue:
            return self._action(self.q_cmd, self.hand_cmd)
        step = self.queue.popleft()
        self.phase = step.phase
        if not step.track:  # untracked legs start from the command, corrections included
            self.correction[:] = 0.0
            self.object_offset[:] = 0.0
        target = step.q + self._track(step, obs) if step.track else step.q
        return self._action(target, step.hand)

    def _action(self, target: np.ndarray, hand: float) -> np.ndarray:
        assert self.q_cmd is not None
        target = np.clip(target, ARM_LOWER, ARM_UPPER)
        delta = np.clip((target - self.q_cmd) / self.max_joint_step, -1.0, 1.0)
        self.q_cmd = np.clip(self.q_cmd + self.max_joint_step * delta, ARM_LOWER, ARM_UPPER)
        self.hand_cmd = hand
        return np.r_[delta, 2.0 * hand - 1.0].astype(np.float32)

    def _track(self, step: _Step, obs: dict[str, np.ndarray]) -> np.ndarray:
        """Joint offset that moves the real fingertip onto the planned one (xy only).

        While sliding, a slower outer loop shifts that fingertip target by the plate's lag
        behind its Eq. 2 pose (the tip creeps a little over the plate as it drags it).
        """
        p = self.params
        t, jac = self.tip.jacobian(step.q)
        pressing = float(obs["finger_qpos"][0]) > p.contact_deflection
        if step.object_xy is not None and pressing:
            lag = step.object_xy - np.asarray(obs["object_pose"][:2], dtype=float)
            limit = p.max_object_correction
            self.object_offset = np.clip(self.object_offset + p.object_gain * lag, -limit, limit)
        setpoint = t[:2, 3] + self.object_offset
        error = setpoint - np.asarray(obs["fingertip_pose"][:2], dtype=float)
        limit = p.max_correction
        self.correction = np.clip(self.correction + p.tip_gain * error, -limit, limit)
        twist = np.r_[self.correction + self.object_offset, 0.0, 0.0, 0.0, 0.0]
        return jac.T @ np.linalg.solve(jac @ jac.T + 1e-4 * np.eye(6), twist)

    # --------------------------------------------------------------- stages
    def _advance(self, obs: dict[str, np.ndarray]) -> None:
        """Queue the next stage's targets (called when the queue runs dry)."""
        if self.phase == "plan":
            self._plan(obs)
        elif self.phase == "slide":
            self._pull_back_or_lift_off(obs)
        elif self.phase == "pull_back":
            self._lift_off()
        elif self.phase == "lift_off":
            self._after_lift_off(obs)
        elif self.phase == "lift":
            self.phase = "done"
        else:
            self._fail(f"nothing follows phase {self.phase!r}")

    def _fail(self, why: str) -> None:
        self.report["failure"] = why
        self.phase = "failed"
        self.queue.clear()
        if self.planner is not None:
            self.planner.close()
            self.planner = None

    def _object_pose(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        pose = obs["object_pose"]
        return np.array([float(pose[0]), float(pose[1]), quat_yaw(pose[3:7])])

    def _plan(self, obs: dict[str, np.ndarray]) -> None:
        assert self.obj is not None and self.table is not None and self.q_cmd is not None
        budget = self.time_budget - self.report["planning_time_s"]
        if budget <= 0.05:
            return self._fail("planning budget used up")
        pose = self._object_pose(obs)
        replan = self.report["replans"] > 0
        try:
            problem = TopSlideProblem(
                self.obj, self.table, pose, self.slide_params, allow_overhang=replan
            )
        except ValueError as exc:
            return self._fail(f"cannot plan from the object's pose: {exc}")
        if self.planner is not None:
            self.planner.close()
        key = [self.seed, self.report["replans"], *(np.round(pose * 1e4).astype(np.int64) % 2**32)]
        rng = np.random.default_rng(np.random.SeedSequence(key))
        self.planner = TopSlidePlanner(problem, self.planner_name, rng)
        t0 = time.perf_counter()
        result = self.planner.solve(budget)
        self.report["planning_time_s"] += time.perf_counter() - t0
        self.report["plan_status"] = result.status.value
        if not result.solved:
            return self._fail(f"planner: {result.reason}")
        self.report["planned"] = True
        self.object_start = pose
        self.result = result
        gamma_s, gamma_g = planar_pose(
            self.tip.forward(np.stack([result.start_config, result.goal_config]))
        )
        self.predicted = slid_object_pose(gamma_s, gamma_g, pose)
        self.report["object_predicted_pose"] = self.predicted.tolist()
        self._queue_press_and_slide(result.start_config, result.path, pose)

    def _ik(self, chain: FastChain, t: np.ndarray, seed: np.ndarray) -> np.ndarray | None:
        return solve_ik(chain, IKTarget(t[:3, 3], t[:3, :3]), self.rng, seed[None])

    def _line(self, chain: FastChain, q0: np.ndarray, offset: np.ndarray) -> np.ndarray | None:
        """Joint waypoints that move ``chain``'s frame by ``offset`` (world, m) along a straight
        line, orientation kept. Each IK starts from the previous waypoint only, so the arm
        stays on one IK branch (a joint-space move between branches can sweep the hand)."""
        start = chain.forward(q0)
        n = max(1, math.ceil(float(np.linalg.norm(offset)) / _LINE_STEP))
        path = [np.asarray(q0, dtype=float)]
        for k in range(1, n + 1):
            pos = start[:3, 3] + offset * k / n
            q = solve_ik(chain, IKTarget(pos, start[:3, :3]), self.rng, path[-1][None], _LOCAL_IK)
            if q is None or np.abs(q - path[-1]).max() > _LINE_MAX_JOINT_STEP:
                return None
            path.append(q)
        return np.array(path)

    def _queue_press_and_slide(self, q_s: np.ndarray, path: np.ndarray, pose: np.ndarray) -> None:
        p, planner = self.params, self.planner
        assert planner is not None and self.q_cmd is not None
        down = self._line(self.tip, q_s, np.array([0.0, 0.0, p.pre_contact_height]))
        if down is None:
            return self._fail("no IK solution above the press point")
        down = down[::-1]  # from above the press point straight down to it
        q_pre = down[0]
        high = self.tip.forward(q_pre)
        high[2, 3] += 0.15
        q_high = self._ik(self.tip, high, q_pre)
        checker = planner.checker
        checker.place_object(pose)
        routes = [[self.q_cmd, q_pre]] + (
            [[self.q_cmd, q_high, q_pre]] if q_high is not None else []
        )
        try:
            route = next(
                (
                    r
                    for r in routes
                    if all(
                        checker.segment_free(a, b, "full", 0.02)
                        for a, b in zip(r[:-1], r[1:], strict=True)
                    )
                ),
                routes[-1],
            )
        finally:
            checker.place_object(None)
        self._push(Segment("approach", np.array(route), p.approach_speed), self.tip)
        press = Segment("press", down, 1.0, p.press_speed, hold_s=p.press_hold_s)
        self._push(press, self.tip, track=True)
        first = len(self.queue)
        slide = Segment("slide", path, 1.0, p.slide_speed, hold_s=p.slide_settle_s)
        self._push(slide, self.tip, track=True)
        targets = [step.q for step in list(self.queue)[first:]]
        gammas = planar_pose(self.tip.forward(np.stack([q_s, *targets])))
        for step, gamma in zip(list(self.queue)[first:], gammas[1:], strict=True):
            step.object_xy = slid_object_pose(gammas[0], gamma, pose)[:2]
        self.q_slide_end = np.asarray(path[-1], dtype=float)

    def _push(self, segment: Segment, chain: FastChain | None, track: bool = False) -> None:
        for q in time_segment(segment, self.dt, chain):
            self.queue.append(_Step(q, segment.hand, segment.name, track))

    def _pull_back_or_lift_off(self, obs: dict[str, np.ndarray]) -> None:
        """If the slide left the plate's centroid at (or past) the table edge, drag it back
        inward while still pressing; a plate lifted off there would tip over the edge."""
        assert self.table is not None
        pose = self._object_pose(obs)
        centroid = shapely.Point(pose[0], pose[1])
        ring = self.table.polygon.exterior
        edge_point = np.asarray(ring.interpolate(ring.project(centroid)).coords[0])
        inside = self.table.polygon.contains(centroid)
        depth = centroid.distance(ring) * (1.0 if inside else -1.0)
        if depth >= self.params.pull_back_margin:
            return self._lift_off()
        inward = (pose[:2] - edge_point) * (1.0 if inside else -1.0)
        inward /= max(float(np.linalg.norm(inward)), 1e-9)
        shift = np.r_[inward * (self.params.pull_back_margin - depth + 0.005), 0.0]
        line = self._line(self.tip, self.q_slide_end, shift)
        if line is None:
            return self._lift_off()
        self.report["events"].append(f"centroid {depth:.3f} m inside the edge: pulled back")
        self._push(Segment("pull_back", line, 1.0, self.params.press_speed), self.tip, track=True)
        self.q_slide_end = line[-1]

    def _lift_off(self) -> None:
        """Raise the fingertip off the plate, still holding its xy (the finger unloads)."""
        assert self.q_cmd is not None
        q_end = self.q_slide_end  # the nominal (uncorrected) end of the slide
        line = self._line(self.tip, q_end, np.array([0.0, 0.0, self.params.lift_off_height]))
        if line is None:
            return self._fail("no IK solution to lift the fingertip off the plate")
        self._push(Segment("lift_off", line, 1.0, self.params.press_speed), self.tip, track=True)

    def _after_lift_off(self, obs: dict[str, np.ndarray]) -> None:
        """Compare the real slid pose with Eq. 2; re-aim the grasp at it, or replan."""
        assert self.planner is not None and self.q_cmd is not None
        assert self.obj is not None and self.table is not None
        actual = self._object_pose(obs)
        self.report["object_slid_pose"] = actual.tolist()
        self.report["slide_error_m"] = float(np.linalg.norm(actual[:2] - self.predicted[:2]))
        self.report["slide_error_rad"] = abs(wrap_angle(actual[2] - self.predicted[2]))
        placed = transform_polygon(self.obj.polygon, *actual)
        ov = overhang(placed, self.table.polygon)
        ok, info = False, {"reason": "overhang below u_star or centroid off the table"}
        if ov.graspable(self.params.grasp_u_star):
            validator = self.planner.validator
            t0 = time.perf_counter()
            validator.deadline = t0 + self.params.grasp_budget
            ok, info = validator.check_placement(
                actual, self.q_cmd, self.params.grasp_u_star, lifted=True, centroid_margin=0.0
            )
            self.report["planning_time_s"] += time.perf_counter() - t0
        self.report["events"].append(
            f"slid: overhang {ov.u:.3f} m, error {self.report['slide_error_m']:.3f} m "
            f"{self.report['slide_error_rad']:.3f} rad, grasp {'ok' if ok else info.get('reason')}"
        )
        if ok:
            return self._queue_grasp(np.asarray(info["transfer_path"]))
        if self.report["replans"] >= self.params.max_replans:
            return self._fail(f"not graspable after the slide ({info.get('reason')})")
        self.report["replans"] += 1
        self._plan(obs)

    def _queue_grasp(self, transfer: np.ndarray) -> None:
        p = self.params
        assert self.q_cmd is not None
        q_grasp = transfer[-1]
        lift_path = None
        for height in (p.lift, 0.75 * p.lift, 0.5 * p.lift):  # near the edge of the workspace
            lift_path = self._line(self.hand, q_grasp, np.array([0.0, 0.0, height]))
            if lift_path is not None:
                break
        if lift_path is None:  # blocked by a joint limit: any IK branch, a joint-space move
            up = self.hand.forward(q_grasp)
            up[2, 3] += p.lift
            q_up = self._ik(self.hand, up, q_grasp)
            if q_up is None:
                return self._fail("no IK solution for lifting the grasped object")
            lift_path = np.array([q_grasp, q_up])
        route = np.vstack([self.q_cmd, transfer[1:-1]])
        transfer_leg = Segment(
            "transfer", route, p.transfer_speed, p.transfer_tip_speed, hold_s=p.settle_s
        )
        self._push(transfer_leg, self.hand)
        self._push(Segment("approach_grasp", transfer[-2:], 1.0, p.grasp_speed), self.hand)
        self._push(Segment("close", transfer[-1:], hand=1.0, hold_s=p.close_s), None)
        lift = Segment("lift", lift_path, 1.0, p.lift_speed, hand=1.0, hold_s=1.0)
        self._push(lift, self.hand)
        if self.planner is not None:
            self.planner.close()
            self.planner = None

    def close(self) -> None:
        """Release the planner's collision world."""
        if self.planner is not None:
            self.planner.close()
            self.planner = None
