"""Gymnasium environments for pre-grasp top-sliding with the WAM + Yale T42 robot."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from slide_gym.envs.control import CONTROL_MODES, make_control
from slide_gym.envs.observation import OBS_MODES, StateObservation
from slide_gym.geometry import (
    OBJECT_NAMES,
    TABLE_NAMES,
    ObjectShape,
    TableShape,
    get_object,
    get_table,
)
from slide_gym.robot import ARM_LOWER, ARM_UPPER, READY_ARM_Q, WamT42
from slide_gym.sim import PhysicsParams, Simulation
from slide_gym.task import (
    PROCEDURAL,
    SceneState,
    TaskParams,
    TopSlideTask,
    check_scene,
    fit_procedural_object,
    sample_start_pose,
    validate_start_pose,
)

_SETTLE_STEPS = 24
"""Physics steps at reset before the first observation: the plate comes to rest."""


class TopSlideEnv(gym.Env):
    """Slide a thin object over a table edge with a fingertip press, and optionally lift it.

    A Barrett WAM arm with a compliant two-finger Yale T42 hand faces a table carrying one thin
    plate. The plate is too flat to grasp where it lies: the robot presses finger A's tip on it
    and drags it by friction until part of it overhangs the table edge, then (``goal="grasp"``)
    grasps the overhang from the side and lifts it.

    ## Action Space
    ``Box(-1, 1, (8,), float32)``. Entries 0-6 are arm joint-position increments, scaled by
    ``max_joint_step`` (rad per control step) and added to the current joint targets (clipped
    to the joint limits). Entry 7 is the hand command: ``u = (a + 1) / 2`` in [0, 1] scales the
    tendon torque (0 = open, 1 = close). The finger joints are springs; they are not commanded.

    ## Observation Space
    A ``Dict`` of float32 boxes:

    | key | shape | meaning |
    |---|---|---|
    | ``arm_qpos`` / ``arm_qvel`` | (7,) | arm joint angles (rad) and velocities (rad/s) |
    | ``finger_qpos`` / ``finger_qvel`` | (4,) | finger A (proximal, distal), finger B (same) |
    | ``hand_command`` | (1,) | the current u in [0, 1] |
    | ``fingertip_pose`` | (7,) | world position and quaternion (xyzw) of ``fingertip_contact`` |
    | ``object_pose`` | (7,) | world position (bottom-face centroid) and quaternion of the object |
    | ``object_velocity`` | (6,) | linear and angular velocity of the object |
    | ``object_outline`` | (32, 2) | object outline in its own frame (m), resampled by arc length |
    | ``table_outline`` | (64, 2) | table outline in the world (m), resampled by arc length |
    | ``table_height`` | (1,) | world z of the table top |

    The outline descriptors have a fixed size, so one policy can serve every shape. Values are
    clipped to the declared bounds.

    ## Rewards
    ``reward_type="sparse"``: 1 on success, 0 otherwise. ``"dense"`` adds shaping (metres,
    negative): minus the fingertip-to-object distance, minus the missing overhang
    ``max(0, u* - u)``, and for ``goal="grasp"`` minus the missing lift height; plus 1 on success.

    ## Starting State
    The arm is at a ready pose with the hand pointing down above the table, fingers open and at
    rest. The object lies flat at ``options["object_pose"] = (x, y, yaw)`` if given, otherwise at
    a seeded random pose fully on the table, within reach, and not graspable. The world is
    rebuilt on every reset, so a seed replays exactly.

    ## Episode End
    ``goal="slide"`` succeeds when the object rests in a graspable pose (overhang ``u >= u*``
    past the line of the nearest table edge, centroid still over the table) and the robot no
    longer touches it. ``goal="grasp"`` succeeds when the object has been held for
    ``lift_hold_s`` (1 s): its lowest point at least ``lift_height`` (5 cm) above the table top,
    touching both fingers and not the table, at every control step of that second. Success
    terminates the episode; so does the object falling off the table (a failure). Truncation
    comes from the registered time limit. ``info["is_success"]`` is a Python bool at reset and
    every step; ``info["lift_held_s"]`` is how long the current lift has held.

    ## Arguments
    - ``object``: a catalog name (see ``slide_gym.OBJECT_NAMES``), a path to a JSON shape, an
      ``ObjectShape``, ``"random"`` (a catalog object drawn each episode) or ``"procedural"``
      (a generated plate, 4-30 cm across, 0.5-6 mm thick, convex or not, with or without
      holes: the plate of the reset seed, or of a seed drawn from the env's generator;
      shrunk if needed to fit the table; ``info["object"]`` names it).
    - ``table``: likewise with ``slide_gym.TABLE_NAMES``.
    - ``scale``: object scale factor (> 0).
    - ``goal``: ``"slide"`` or ``"grasp"``; ``reward_type``: ``"sparse"`` or ``"dense"``.
    - ``render_mode``: ``None``, ``"rgb_array"`` (headless TinyRenderer) or ``"human"`` (GUI).
    - ``control_hz`` (default 20), ``physics_hz`` (default 240), ``max_joint_step`` (rad per
      control step, default 0.05), ``task_params``: a :class:`TaskParams`.
    """

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 20}

    def __init__(
        self,
        object: str | ObjectShape = "square",  # noqa: A002 - the public argument name
        table: str | TableShape = "square",
        scale: float = 1.0,
        goal: str = "slide",
        reward_type: str = "sparse",
        render_mode: str | None = None,
        control_hz: float = 20.0,
        physics_hz: float = 240.0,
        max_joint_step: float = 0.05,
        task_params: TaskParams | None = None,
        control_mode: str = "joint_delta",
        obs_mode: str = "state",
    ):
        if goal not in ("slide", "grasp"):
            raise ValueError(f"goal must be 'slide' or 'grasp', got {goal!r}")
        if reward_type not in ("sparse", "dense"):
            raise ValueError(f"reward_type must be 'sparse' or 'dense', got {reward_type!r}")
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(
                f"render_mode must be None, 'rgb_array' or 'human', got {render_mode!r}"
            )
        for name, value in (("control_hz", control_hz), ("physics_hz", physics_hz)):
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value}")
        substeps = physics_hz / control_hz
        if abs(substeps - round(substeps)) > 1e-9 or round(substeps) < 1:
            raise ValueError(
                f"physics_hz ({physics_hz}) must be a whole multiple of control_hz ({control_hz})"
            )
        if obs_mode not in OBS_MODES:
            raise ValueError(f"obs_mode must be one of {', '.join(OBS_MODES)}, got {obs_mode!r}")
        if control_mode not in CONTROL_MODES:
            raise ValueError(
                f"control_mode must be one of {', '.join(CONTROL_MODES)}, got {control_mode!r}"
            )
        self.control = make_control(control_mode, max_joint_step)
        self.control_mode, self.obs_mode = control_mode, obs_mode
        self.goal, self.reward_type, self.render_mode = goal, reward_type, render_mode
        self.n_substeps = int(round(substeps))
        self.max_joint_step = float(max_joint_step)
        self.metadata = {**self.metadata, "render_fps": control_hz}

        self._object_spec = self._resolve(
            "object", object, OBJECT_NAMES, lambda s: get_object(s, scale)
        )
        self._table_spec = self._resolve("table", table, TABLE_NAMES, get_table)
        self.scale = float(scale)
        objects = self._candidates(self._object_spec, OBJECT_NAMES, lambda n: get_object(n, scale))
        for table_shape in self._candidates(self._table_spec, TABLE_NAMES, get_table):
            for object_shape in objects:
                check_scene(object_shape, table_shape)

        self.task = TopSlideTask(task_params)
        self.sim = Simulation(render_mode, PhysicsParams(timestep=1.0 / physics_hz))
        self.robot = WamT42(self.sim)
        self._u = 0.0
        self._state: SceneState | None = None
        self._lift_steps = 0  # consecutive control steps the object has been held up
        self._is_success = False

        self.observer = StateObservation()
        self.action_space = self.control.action_space
        self.observation_space = self.observer.space

    @property
    def dt(self) -> float:
        """Seconds of simulated time per :meth:`step` (physics timestep x substeps)."""
        return self.n_substeps * self.sim.settings.timestep

    # ------------------------------------------------------------------ set-up
    @staticmethod
    def _resolve(kind: str, spec: Any, names: tuple[str, ...], load: Any) -> Any:
        """Validate at construction; keep ``"random"`` (a catalog shape per episode) and, for
        objects, ``"procedural"`` (a generated plate per episode)."""
        if isinstance(spec, str) and (spec == "random" or (kind, spec) == ("object", PROCEDURAL)):
            return spec
        if spec is None:
            raise ValueError(f"{kind} must be one of {', '.join(names)}, 'random' or a .json path")
        return load(spec)

    # --------------------------------------------------------------- gym API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        if seed is not None and (
            isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0
        ):
            raise ValueError(f"seed must be None or a non-negative integer, got {seed!r}")
        super().reset(seed=seed)
        options = dict(options or {})
        p = self.task.params
        unknown = set(options) - {"object_pose", "arm_qpos"}
        if unknown:
            raise ValueError(
                f"unknown reset options {sorted(unknown)}; allowed: object_pose, arm_qpos"
            )
        table = self._pick(self._table_spec, TABLE_NAMES, get_table)
        if self._object_spec == PROCEDURAL:
            plate_seed = seed if seed is not None else int(self.np_random.integers(2**31))
            obj = fit_procedural_object(plate_seed, table, self.scale, p.start_margin)
        else:
            obj = self._pick(self._object_spec, OBJECT_NAMES, lambda s: get_object(s, self.scale))
        check_scene(obj, table)
        if options.get("object_pose") is not None:
            pose = validate_start_pose(obj, table, options["object_pose"])
        else:
            pose = sample_start_pose(obj, table, self.np_random, p.start_margin)
        arm_q = np.array(READY_ARM_Q, dtype=float)
        if options.get("arm_qpos") is not None:
            arm_q = np.asarray(options["arm_qpos"], dtype=float).reshape(-1)
            if arm_q.shape != (7,) or not np.all(np.isfinite(arm_q)):
                raise ValueError(
                    f"arm_qpos must be 7 finite joint angles, got {options['arm_qpos']!r}"
                )
            if np.any(arm_q < ARM_LOWER) or np.any(arm_q > ARM_UPPER):
                raise ValueError(f"arm_qpos {arm_q.tolist()} is outside the joint limits")

        # Rebuilding the world each reset clears PyBullet's solver caches: same seed, same run.
        self.sim.clear()
        self.robot.load()
        self.task.build(self.sim, obj, table, pose)
        self.robot.reset(arm_q)
        self.control.reset(arm_q)
        self._u = 0.0
        self.robot.set_hand_command(0.0)
        self.robot.set_arm_targets(self.control.target)
        for _ in range(_SETTLE_STEPS):
            self.robot.step_physics()
        self.observer.set_scene(obj, table)
        self._state = self._read_state()
        self._lift_steps = 0
        self._is_success = self._success(self._state)
        return self._observation(), self._info(self._state)

    @staticmethod
    def _candidates(spec: Any, names: tuple[str, ...], load: Any) -> list[Any]:
        if spec == PROCEDURAL:
            return []  # drawn per episode, shrunk to fit the table
        return [load(n) for n in names] if spec == "random" else [spec]

    def _pick(self, spec: Any, names: tuple[str, ...], load: Any) -> Any:
        if isinstance(spec, str) and spec == "random":
            return load(names[int(self.np_random.integers(len(names)))])
        return spec

    def step(
        self, action: np.ndarray
    ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        if self._state is None:
            raise RuntimeError("call reset() before step()")
        target, self._u = self.control.apply(action)
        span = self._command_arm(target)
        self.robot.set_hand_command(self._u)
        for _ in range(self.n_substeps // span):
            self.robot.step_physics()
        s = self._state = self._read_state()
        self._lift_steps = self._lift_steps + 1 if self.task.lifted(s) else 0
        success = self._is_success = self._success(s)
        reward = self._reward(s, success)
        terminated = success or s.fell_off
        return self._observation(), reward, terminated, False, self._info(s)

    def _command_arm(self, target: np.ndarray) -> int:
        """Pick this control period's physics settings (:meth:`Simulation.adapt`: full ones
        near the object, ``free_step_factor`` times longer steps while the robot is free),
        then send the arm targets; return how many base physics steps each step spans.

        The settings come first: PyBullet caps a motor's impulse per step with the step
        length in force when the command arrives, and the robot scales its position gains by
        the step span in force (within 0.3 mrad of the base rate; unscaled 2.6 mrad).
        """
        span = self.sim.adapt(self.n_substeps)
        self.robot.set_arm_targets(target)
        return span

    def render(self) -> np.ndarray | None:
        if self.render_mode == "rgb_array":
            return self.sim.render()
        return None

    def close(self) -> None:
        self.sim.close()

    # --------------------------------------------------------------- helpers
    def _read_state(self) -> SceneState:
        return self.task.scene_state(self.sim, self.robot.finger_a_links, self.robot.finger_b_links)

    def _success(self, s: SceneState) -> bool:
        if self.goal == "slide":
            return self.task.slide_success(s)
        hold = self.task.params.lift_hold_s
        return self._lift_steps * self.dt >= hold - 1e-9

    def _reward(self, s: SceneState, success: bool) -> float:
        if self.reward_type == "sparse":
            return float(success)
        p = self.task.params
        tip, _ = self.robot.fingertip_pose()
        obj_top = np.array([s.object_pose[0], s.object_pose[1], s.object_z])
        reward = -float(np.linalg.norm(tip - obj_top)) - max(0.0, p.u_star - s.overhang_m)
        if self.goal == "grasp":
            reward -= max(0.0, p.lift_height - s.lift_m)
        return reward + float(success)

    def _info(self, s: SceneState) -> dict[str, Any]:
        return {
            "is_success": self._is_success,
            "overhang_m": s.overhang_m,
            "graspable": s.graspable,
            "lift_m": s.lift_m,
            "clearance_m": s.clearance_m,
            "lift_held_s": self._lift_steps * self.dt,
            "touching_robot": s.touching_robot,
            "touching_table": s.touching_table,
            "fell_off": s.fell_off,
            "object_pose_2d": s.object_pose,
            "object": self.task.object.name,
            "table": self.task.table.name,
        }

    def _observation(self) -> dict[str, np.ndarray]:
        assert self._state is not None
        return self.observer.read(self.robot, self._state, self._u)
