"""Gymnasium environments for pre-grasp top-sliding with the WAM + Yale T42 robot."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from slide_gym.envs.cameras import RENDER_SIZE, Camera, CameraModel, image_size, render_frame
from slide_gym.envs.control import MAX_ROT_STEP, MAX_TIP_STEP, make_control
from slide_gym.envs.observation import OBS_MODES, make_observation
from slide_gym.envs.randomization import (
    apply_to_scene,
    apply_to_world,
    draw,
    episode_rng,
    hand_params,
    parse,
)
from slide_gym.envs.reward import DenseReward, sparse_terms
from slide_gym.envs.scene import RESET_OPTIONS, SceneChoice
from slide_gym.geometry import ObjectShape, TableShape
from slide_gym.robot import ARM_LOWER, ARM_UPPER, READY_ARM_Q, WamT42
from slide_gym.robot.wam_t42 import STATE_SIZE as ROBOT_STATE_SIZE
from slide_gym.sim import OBJECT_STATE_SIZE, PhysicsParams, Simulation, versioned_physics
from slide_gym.task import (
    SceneState,
    TaskParams,
    TopSlideTask,
    sample_start_pose,
    validate_start_pose,
)

_FAR_ROBOT = (-100.0, -100.0, 100.0)
_FAR_OBJECT = (100.0, 100.0, 100.0)
"""Where :meth:`TopSlideEnv._restore` moves the bodies for a collision pass that frees their
contact caches: far from the table and from each other."""
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

    ``control_mode="ee_delta"``: ``Box(-1, 1, (7,), float32)``. Entries 0-2 move the target
    position of the ``fingertip_contact`` frame (world axes, times ``max_tip_step`` m), entries
    3-5 turn its target orientation by a world-frame rotation vector (times ``max_rot_step``
    rad; entry 5 is yaw about world z), entry 6 is the hand command. Damped least squares turns
    the target pose into joint targets (joint limits, at most ``max_joint_step`` per joint);
    an unreachable target is pulled back to the reached pose (``slide_gym.envs.control``).

    ## Observation Space
    A ``Dict`` of 1-D float32 boxes (``obs_mode="state"``, the default):

    | key | shape | meaning |
    |---|---|---|
    | ``arm_qpos`` / ``arm_qvel`` | (7,) | arm joint angles (rad) and velocities (rad/s) |
    | ``finger_qpos`` / ``finger_qvel`` | (4,) | finger A (proximal, distal), finger B (same) |
    | ``hand_command`` | (1,) | the current u in [0, 1] |
    | ``fingertip_pose`` | (7,) | world position and quaternion (xyzw) of ``fingertip_contact`` |
    | ``object_pose`` | (7,) | world position (bottom-face centroid) and quaternion of the object |
    | ``object_velocity`` | (6,) | linear and angular velocity of the object |
    | ``object_outline`` | (64,) | 32 outline points in the object frame (m), ``x0, y0, x1, ...`` |
    | ``object_holes`` | (128,) | up to 4 holes (largest first) x 16 points each, same layout |
    | ``object_hole_mask`` | (4,) | 1 for each hole slot in use, 0 for the zero-padded ones |
    | ``table_outline`` | (128,) | 64 table outline points in the world (m), same layout |
    | ``table_height`` | (1,) | world z of the table top |

    Outlines and holes are resampled evenly by arc length, counter-clockwise, from where the
    ray from their centroid along +x leaves them, and flattened (``reshape(-1, 2)`` gives the
    points back). The descriptors have a fixed size, so one policy can serve every shape.
    Values are clipped to the declared bounds; Stable-Baselines3's ``check_env`` accepts the
    space without warnings.

    ``obs_mode="rgbd"`` adds four images (``render_width`` x ``render_height``, default
    128 x 128), rendered headless with the TinyRenderer at every reset and step:

    | key | shape | meaning |
    |---|---|---|
    | ``scene_rgb`` / ``wrist_rgb`` | (H, W, 3) uint8 | RGB of the scene / wrist camera |
    | ``scene_depth`` / ``wrist_depth`` | (H, W, 1) float32 | depth along the optical axis (m) |

    Depth lies in [0.01, 10] m (10 where nothing is in view). The scene camera is ``camera``
    (see Arguments). The wrist camera is fixed to the palm, 6 cm to its side, looking along
    the hand's approach axis between the fingers (60 degree field of view). SB3's
    ``check_env`` takes any 3-D box for an image and warns that the depth images are not
    uint8 in [0, 255]; they stay float metres so that mm-thin plates show.

    ``obs_mode="pointcloud"`` adds ``num_points`` points (default 1024) instead of images:
    both cameras' depth (``render_width`` x ``render_height`` pixels each) turned into
    world-frame points (the pixels that see nothing left out), thinned to one point per
    1 cm voxel and body, then farthest-point sampled from a start drawn from the reset
    seed's generator (fewer points than asked: all, then seeded repeats):

    | key | shape | meaning |
    |---|---|---|
    | ``pointcloud_xyz`` | (N, 3) float32 | world position of each point (m) |
    | ``pointcloud_rgb`` | (N, 3) uint8 | its colour |
    | ``pointcloud_segmentation`` | (N,) uint8 | 0 plate, 1 table, 2 robot |

    ``env.unwrapped.cameras`` gives both modes' cameras as they are now
    (:class:`~slide_gym.envs.cameras.CameraModel`: intrinsics K, ``world_from_camera``,
    width, height, near and far, in OpenCV's axes).

    ## Rewards
    ``reward_type="sparse"``: 1 on success, 0 otherwise (falling off also pays 0: it ends the
    episode, forfeiting any later success, so it is never better than staying).
    ``"dense"`` (:class:`~slide_gym.envs.reward.DenseReward`) pays a sum of named terms,
    reported every step (and at reset, for the reset state) in ``info["reward_terms"]``:

    | term | value |
    |---|---|
    | ``reach`` | ``w * (1 - tanh(d / 0.1 m))``, d: fingertip contact to the object's top centre |
    | ``progress`` | ``w * min(u / u*, 1)``, u: the overhang |
    | ``lift`` | ``goal="grasp"``: ``0.5 * clip(clearance / lift_height, 0, 1)``; else 0 |
    | ``success`` | ``+H`` on the step that succeeds |
    | ``fall_off`` | ``-H`` on the step the object falls off (that step pays no shaping) |

    with w = 0.5 (slide) or 0.25 (grasp), so a step's shaping lies in [0, 1], and H = 1200
    steps, the longest registered time limit. Why it cannot be gamed: shaping is never
    negative, so ending the episode forfeits future reward, and the penalty makes every episode
    that drops the object score below 0, below any episode that does not; an episode that
    succeeds scores at least H, above anything lingering short of success can collect within
    H steps (or ``1 / (1 - gamma)`` discounted). Hence, for episodes of at most H steps,
    ``return(fell off) < 0 <= return(neither) <= H <= return(success)``.

    ## Starting State
    The arm is at a ready pose with the hand pointing down above the table, fingers open and at
    rest. The object lies flat at a seeded random pose fully on the table, within reach, and not
    graspable. The world is rebuilt on every reset, so a seed replays exactly; for a named
    object and table the pose is :func:`slide_gym.task.seeded_start_pose` of the seed, the one
    ``slide-gym plan --seed`` and ``slide-gym run --seed`` start from. ``reset(options=...)``
    takes (all optional):

    - ``object``, ``table``, ``scale``, ``thickness``: this episode's scene, as the arguments
      below (the env's own stay for later resets); ``info["object"]`` and ``info["table"]``
      name what was drawn;
    - ``object_pose``: ``(x, y, yaw)`` of the object (m, rad), instead of the random pose;
    - ``arm_qpos``: the arm's 7 joint angles (rad, within the joint limits) instead of the
      ready pose;
    - ``randomization``: a dict as the argument below (or ``"default"``) for this episode,
      over the env's own: the keys it names replace the env's ranges (a number sets that
      exact value), the others keep them.

    ## Domain Randomisation
    ``randomization`` (see Arguments) draws per episode, uniformly within each range:

    | key | unit | allowed | ``"default"`` |
    |---|---|---|---|
    | ``plate_table_friction`` | - | 0.01-2 | 0.24-0.40 (fixed world: 0.32) |
    | ``pad_friction`` | - | 0.05-3 | 0.8-1.2 (1.0), finger pads on the plate |
    | ``plate_density`` | kg/m^3 | 100-10000 | 800-1600 (the plate's, 1200) |
    | ``plate_thickness`` | m | 0.0003-0.05 | 0.003-0.005 (the plate's, 0.004) |
    | ``table_height`` | m | -0.10-0.05 | -0.05-0.03 (the table's, 0) |
    | ``finger_stiffness`` | N m/rad | 0.3-6 | 0.9-1.5 (1.2), proximal; distal twice it |

    Frictions are those of the contact pair (PyBullet multiplies the bodies' coefficients:
    the table's and the finger links' are set to the pair's over the plate's 0.8). Values
    come from a generator seeded with the reset seed, apart from ``np_random``: the same seed
    gives the same draws, scene and start pose (resets without a seed continue the
    generator). ``info["randomization"]`` holds the episode's values (``{}`` without
    randomisation); ``reset(options={"randomization": info["randomization"]})`` with the
    seed starts the episode again. A drawn thickness or table height replaces the shape's
    (``env.unwrapped.task.object`` and ``.table`` are the episode's shapes), and the
    ``table_height`` observation shows it.

    ## Episode End
    ``goal="slide"`` succeeds when the object rests in a graspable pose (overhang ``u >= u*``
    past the line of the nearest table edge, centroid still over the table) and the robot no
    longer touches it. ``goal="grasp"`` succeeds when the object has been held for
    ``lift_hold_s`` (1 s): its lowest point at least ``lift_height`` (5 cm) above the table top,
    touching both fingers and not the table, at every control step of that second. Success
    terminates the episode; so does the object falling off the table (a failure). Truncation
    comes from the registered time limit. ``info["is_success"]`` is a Python bool at reset and
    every step; ``info["lift_held_s"]`` is how long the current lift has held, and
    ``info["pinched"]`` whether the object touches both fingers.

    ## Arguments
    - ``object``: a catalog name (see ``slide_gym.OBJECT_NAMES``), a path to a JSON shape, an
      ``ObjectShape``, ``"random"`` (a catalog object drawn each episode) or ``"procedural"``
      (a generated plate, 4-30 cm across, 0.5-6 mm thick, convex or not, with or without
      holes: the plate of the reset seed, or of a seed drawn from the env's generator;
      shrunk if needed to fit the table, and redrawn from the seed if it cannot overhang u*,
      :func:`slide_gym.task.draw_procedural_plate`; ``info["object"]`` names it).
    - ``table``: likewise with ``slide_gym.TABLE_NAMES``.
    - ``scale``: object scale factor (> 0); ``thickness``: the object's thickness (m, 0.3 mm
      to 5 cm) instead of its own.
    - ``goal``: ``"slide"`` or ``"grasp"``; ``reward_type``: ``"sparse"`` or ``"dense"``.
    - ``render_mode``: ``None``, ``"rgb_array"`` (headless TinyRenderer) or ``"human"`` (GUI).
    - ``obs_mode``: ``"state"`` (default), ``"rgbd"`` or ``"pointcloud"`` (see Observation
      Space), with ``num_points`` (``"pointcloud"`` only, default 1024);
      ``render_width``, ``render_height``: image size in pixels of the cameras of
      ``"rgbd"`` and ``"pointcloud"`` (default 128 x 128) and of ``render()`` (default
      480 x 360); ``camera``: the scene
      camera of all three, a :class:`~slide_gym.envs.cameras.Camera` or a dict of its fields
      (``target`` (world, m), ``distance`` (m), ``yaw``, ``pitch``, ``fov`` (degrees);
      default ``(0.45, 0, 0.15)``, 1.35, 60, -30, 45).
    - ``control_hz`` (default 20), ``physics_hz`` (default 240), ``max_joint_step`` (rad per
      control step, default 0.05), ``task_params``: a :class:`TaskParams` or a dict of its
      fields (``{"table_friction": 0.2}``).
    - ``physics``: a :class:`~slide_gym.sim.PhysicsParams` or a dict of its fields other
      than ``timestep`` (``physics_hz`` sets it), e.g. ``{"friction_anchor": True}``: the
      robot's contacts keep their friction anchors (small plates slip less under the
      fingertip; on in the v1 ids, off in v0). A dict overrides single settings of the
      version's; a ``PhysicsParams`` replaces them all.
    - ``version``: the registered id's version, which ``gym.make`` sets (0 or 1): the physics
      defaults that differ between versions (:data:`~slide_gym.sim.ENV_VERSION_PHYSICS`).
    - ``control_mode``: ``"joint_delta"`` (default) or ``"ee_delta"`` (see Action Space), with
      ``max_tip_step`` (m per control step, default 0.01) and ``max_rot_step`` (rad, 0.05).
    - ``randomization``: ``None`` (default: the fixed world), ``"default"`` (every key over
      the ranges above that the expert still solves) or a dict of key -> ``(low, high)`` or
      number (see Domain Randomisation); a ValueError names a bad key or value and what is
      allowed.
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
        task_params: TaskParams | dict[str, Any] | None = None,
        thickness: float | None = None,
        control_mode: str = "joint_delta",
        obs_mode: str = "state",
        max_tip_step: float = MAX_TIP_STEP,
        max_rot_step: float = MAX_ROT_STEP,
        render_width: int | None = None,
        render_height: int | None = None,
        camera: Camera | dict[str, Any] | None = None,
        num_points: int | None = None,
        randomization: str | dict[str, Any] | None = None,
        physics: PhysicsParams | dict[str, Any] | None = None,
        version: int = 0,
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
        self.control = make_control(control_mode, max_joint_step, max_tip_step, max_rot_step)
        self.control_mode, self.obs_mode = control_mode, obs_mode
        self.goal, self.reward_type, self.render_mode = goal, reward_type, render_mode
        self.n_substeps = int(round(substeps))
        self.metadata = {**self.metadata, "render_fps": control_hz}
        self.camera = Camera.of(camera)
        self.render_size = image_size(render_width, render_height, RENDER_SIZE)
        self.observer = make_observation(
            obs_mode, render_width, render_height, self.camera, num_points
        )

        self.scene = SceneChoice(object, table, scale, thickness)
        self.randomization = parse(randomization)
        """The env's randomisation ranges, key -> (low, high) (an exact value: low == high)."""
        self.randomization_values: dict[str, float] = {}
        """The values the last reset drew (``info["randomization"]``)."""
        self._randomization_rng: np.random.Generator | None = None

        self.task = TopSlideTask(task_params)
        self.version = version
        physics = versioned_physics(version, physics)
        self.sim = Simulation(render_mode, PhysicsParams.of(physics, timestep=1.0 / physics_hz))
        self.robot = WamT42(self.sim)
        self._hand = self.robot.hand
        self._u = 0.0
        self._state: SceneState | None = None
        self._lift_steps = 0  # consecutive control steps the object has been held up
        self._is_success = False
        self._put_state: np.ndarray | None = None  # set_state's vector until the next step
        self.start_pose = np.zeros(3)
        """``(x, y, yaw)`` the last reset placed the object at (before it settled): with the
        reset's seed and options and ``object_pose=start_pose``, a reset gives the same
        episode start."""
        self.dense_reward = DenseReward()
        self._reward_terms: dict[str, float] = {}

        self.action_space = self.control.action_space
        self.observation_space = self.observer.space

    @property
    def scale(self) -> float:
        """The object scale factor the env draws with (a reset option may differ)."""
        return self.scene.scale

    @property
    def max_joint_step(self) -> float:
        """Largest arm joint target change per control step (rad), in every control mode."""
        return self.control.max_joint_step

    @property
    def dt(self) -> float:
        """Seconds of simulated time per :meth:`step` (physics timestep x substeps)."""
        return self.n_substeps * self.sim.settings.timestep

    @property
    def state_size(self) -> int:
        """Length of :meth:`get_state`."""
        return ROBOT_STATE_SIZE + OBJECT_STATE_SIZE + self.control.state_size + 3

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
        unknown = set(options) - set(RESET_OPTIONS)
        if unknown:
            raise ValueError(
                f"unknown reset options {sorted(unknown)}; allowed: {', '.join(RESET_OPTIONS)}"
            )
        ranges = self.randomization | parse(
            options.get("randomization"), "reset option randomization"
        )
        choice = self.scene.with_options(options)
        obj, table = choice.draw(self.np_random, seed, p.start_margin)
        if options.get("object_pose") is not None:
            pose = validate_start_pose(obj, table, options["object_pose"])
        else:
            pose = sample_start_pose(obj, table, self.np_random, p.start_margin)
        self.start_pose = np.asarray(pose, dtype=float).copy()
        values = self.randomization_values = self._draw_randomization(ranges, seed)
        obj, table = apply_to_scene(values, obj, table)
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
        apply_to_world(values, self.sim, self.robot, p.object_friction)
        self.robot.set_hand(hand_params(values, self._hand))
        self.robot.reset(arm_q)
        self.control.reset(arm_q)
        self._u = 0.0
        self.robot.set_hand_command(0.0)
        self.robot.set_arm_targets(self.control.target)
        for _ in range(_SETTLE_STEPS):
            self.robot.step_physics()
        # The observation's own generator (the point cloud's sampling): a child of the reset
        # seed's, so it draws nothing from the env's stream.
        self.observer.set_scene(obj, table, self.np_random.spawn(1)[0])
        self._put_state = None
        self._state = self._read_state()
        self._lift_steps = 0
        self._is_success = self._success(self._state)
        self._reward(self._state, self._is_success)  # the reset state's info["reward_terms"]
        return self._observation(), self._info(self._state)

    def step(
        self, action: np.ndarray
    ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        if self._state is None:
            raise RuntimeError("call reset() before step()")
        self._put_state = None
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

    def get_state(self) -> np.ndarray:
        """The whole state of the episode as one float64 vector (:attr:`state_size`):

        | part | size | contents |
        |---|---|---|
        | robot | 37 | joint angles, velocities, hand controller (``WamT42.get_state``) |
        | object | 13 | position, quaternion xyzw, linear and angular velocity of its base |
        | control | 7 (19) | the arm's joint targets (``"ee_delta"``: and its target pose) |
        | episode | 3 | hand command u, control steps the lift has held, success (0/1) |

        It is not everything PyBullet keeps: between physics steps it also caches the contact
        points of every touching pair (with their friction anchors and warm-start impulses),
        and no API reads or writes them. :meth:`set_state` therefore restores the world to
        within those caches (see there); an exact replay resets with the episode's seed and
        options and steps the same actions (the world is rebuilt on every reset, so that is
        bit for bit).
        """
        if self._put_state is not None:
            return self._put_state.copy()
        return np.concatenate(
            [
                self.robot.get_state(),
                self.sim.body_state("object"),
                self.control.get_state(),
                [self._u, float(self._lift_steps), float(self._is_success)],
            ]
        )

    def set_state(self, state: np.ndarray) -> None:
        """Put the episode in ``state`` (from :meth:`get_state` of an env with the same
        arguments, after a reset with the same seed and options: the scene is not part of
        the state). The next :meth:`observation` or :meth:`step` continues from it.

        PyBullet's contact caches (see :meth:`get_state`) are dropped, and rebuilt from the
        geometry on the next physics step, so the continuation is close to the original but
        not bit for bit (``slide-gym replay --mode states`` measures by how much). Dropping
        them at every step would make restores exact, but it costs the friction anchors that
        hold a pinched plate (in a trial of that change, 3 of 6 expert lifts lost the plate).
        """
        if self._state is None:
            raise RuntimeError("call reset() before set_state(): the state holds no scene")
        s = np.array(state, dtype=float).reshape(-1)
        if s.shape != (self.state_size,) or not np.all(np.isfinite(s)):
            raise ValueError(
                f"state must be {self.state_size} finite numbers (get_state() of an env with "
                f"control_mode={self.control_mode!r}), got shape {np.shape(state)}"
            )
        self._restore(s)
        self._put_state = s
        self._state = self._read_state()

    @property
    def cameras(self) -> dict[str, CameraModel]:
        """The observation's cameras as they are now (``"scene"`` and ``"wrist"``; none for
        ``obs_mode="state"``): intrinsics, pose in the world (the wrist camera's moves with
        the hand: read it after each step), size and clip planes, to turn the ``"rgbd"``
        depth images into points (:meth:`CameraModel.unproject`)."""
        if self._state is None:
            raise RuntimeError("call reset() before reading cameras: the robot is not built")
        return self.observer.cameras(self.robot)

    def observation(self) -> dict[str, np.ndarray]:
        """The observation of the current state (as :meth:`step` would return it)."""
        return self._observation()

    def _restore(self, s: np.ndarray) -> None:
        """Move the robot and the object apart, drop PyBullet's contact caches, then put
        every body and controller in ``s`` (see :meth:`get_state`)."""
        r, o = ROBOT_STATE_SIZE, ROBOT_STATE_SIZE + OBJECT_STATE_SIZE
        c = o + self.control.state_size
        self.robot.move_apart(_FAR_ROBOT)
        self.sim.set_body_state("object", np.r_[_FAR_OBJECT, 0, 0, 0, 1, np.zeros(6)])
        self.sim.drop_contacts()
        self.robot.set_state(s[:r])
        self.sim.set_body_state("object", s[r:o])
        self.robot.move_back()
        self.control.set_state(s[o:c])
        u, lift_steps, success = s[c:]
        self._u, self._lift_steps, self._is_success = float(u), int(lift_steps), bool(success)

    def _draw_randomization(
        self, ranges: dict[str, tuple[float, float]], seed: int | None
    ) -> dict[str, float]:
        """This episode's values of ``ranges``, from the generator of the last reset seed
        (:func:`~slide_gym.envs.randomization.episode_rng`), which resets without a seed
        continue."""
        if seed is not None:
            self._randomization_rng = None
        if not ranges:
            return {}
        if self._randomization_rng is None:
            first = self.np_random_seed  # -1 if np_random was set directly: fresh entropy
            self._randomization_rng = episode_rng(first) if first >= 0 else np.random.default_rng()
        return draw(ranges, self._randomization_rng)

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
            return render_frame(self.sim.client, self.camera, *self.render_size)
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
        """This step's reward: the sum of its terms, kept for ``info["reward_terms"]``."""
        if self.reward_type == "sparse":
            self._reward_terms = sparse_terms(success)
        else:
            tip, _ = self.robot.fingertip_pose()
            assert self.task.object is not None
            self._reward_terms = self.dense_reward.terms(
                self.goal, s, tip, self.task.object.thickness, self.task.params, success
            )
        return float(sum(self._reward_terms.values()))

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
            "pinched": s.touching_finger_a and s.touching_finger_b,
            "fell_off": s.fell_off,
            "object_pose_2d": s.object_pose,
            "object": self.task.object.name,
            "table": self.task.table.name,
            "reward_terms": dict(self._reward_terms),
            "randomization": dict(self.randomization_values),
        }

    def _observation(self) -> dict[str, np.ndarray]:
        assert self._state is not None
        return self.observer.read(self.robot, self._state, self._u)
