"""The environment's observations: the ``Dict`` spaces and how one is read.

:class:`StateObservation` declares the proprioceptive, object and scene entries (see the
table in :class:`~slide_gym.envs.top_slide.TopSlideEnv`) and packs them from the robot and
the task's :class:`~slide_gym.task.SceneState`, clipped to the declared bounds. Every entry
is a 1-D float32 box, which Stable-Baselines3's ``check_env`` accepts without warnings: the
outlines are flattened ``(x0, y0, x1, y1, ...)``. :class:`RgbdObservation` (``"rgbd"``) adds
the scene and wrist cameras' images (:mod:`slide_gym.envs.cameras`),
:class:`PointCloudObservation` (``"pointcloud"``) a fixed number of world-frame points fused
from both cameras' depth, with RGB and a segmentation label (:mod:`slide_gym.envs.pointcloud`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import shapely
from gymnasium import spaces

from slide_gym.envs.cameras import (
    FAR,
    NEAR,
    OBS_IMAGE_SIZE,
    WRIST_FOV,
    WRIST_LINK,
    Camera,
    CameraModel,
    image_size,
    render_rgbd,
    wrist_view,
)
from slide_gym.envs.pointcloud import (
    NUM_POINTS,
    SEGMENT_NAMES,
    check_num_points,
    fuse,
    sample_indices,
)
from slide_gym.geometry import ObjectShape, TableShape, outline_descriptor
from slide_gym.robot import ARM_LOWER, ARM_UPPER, FINGER_LOWER, FINGER_UPPER, WamT42
from slide_gym.task import SceneState

OBS_MODES = ("state", "rgbd", "pointcloud")
"""Observation modes: ``"state"`` (the Dict below), ``"rgbd"`` (plus camera images) and
``"pointcloud"`` (plus a point cloud)."""
OBJECT_OUTLINE_POINTS = 32
TABLE_OUTLINE_POINTS = 64
MAX_HOLES = 4
"""Holes the observation describes (the largest by area; any others are left out)."""
HOLE_POINTS = 16
"""Points per hole, evenly spaced by arc length along its ring."""
IMAGE_KEYS = ("scene_rgb", "scene_depth", "wrist_rgb", "wrist_depth")
"""The ``"rgbd"`` mode's extra entries."""
POINT_KEYS = ("pointcloud_xyz", "pointcloud_rgb", "pointcloud_segmentation")
"""The ``"pointcloud"`` mode's extra entries."""
POS_BOUND = 3.0
VEL_BOUND = 20.0
OUTLINE_BOUND = 3.0
FLAT_KEYS = (
    "arm_qpos",
    "arm_qvel",
    "finger_qpos",
    "finger_qvel",
    "hand_command",
    "fingertip_pose",
    "object_pose",
    "object_velocity",
)
"""Observation entries read from the simulator each step, in the order they are packed."""
SCENE_KEYS = (
    "object_outline",
    "object_holes",
    "object_hole_mask",
    "table_outline",
    "table_height",
)
"""Observation entries fixed for an episode (the scene's descriptors)."""


def box(low: Any, high: Any, shape: tuple[int, ...]) -> spaces.Box:
    """A float32 Box with ``low`` and ``high`` broadcast to ``shape``."""
    return spaces.Box(
        np.broadcast_to(np.asarray(low, np.float32), shape).copy(),
        np.broadcast_to(np.asarray(high, np.float32), shape).copy(),
        shape,
        np.float32,
    )


def state_space() -> spaces.Dict:
    """The state observation space (every entry float32)."""
    pose_low = np.r_[[-POS_BOUND] * 3, [-1.0] * 4]
    return spaces.Dict(
        {
            "arm_qpos": box(np.asarray(ARM_LOWER) - 0.2, np.asarray(ARM_UPPER) + 0.2, (7,)),
            "arm_qvel": box(-VEL_BOUND, VEL_BOUND, (7,)),
            "finger_qpos": box(
                np.asarray(FINGER_LOWER) - 0.5, np.asarray(FINGER_UPPER) + 0.5, (4,)
            ),
            "finger_qvel": box(-5 * VEL_BOUND, 5 * VEL_BOUND, (4,)),
            "hand_command": box(0.0, 1.0, (1,)),
            "fingertip_pose": box(pose_low, -pose_low, (7,)),
            "object_pose": box(pose_low, -pose_low, (7,)),
            "object_velocity": box(-VEL_BOUND, VEL_BOUND, (6,)),
            "object_outline": box(-OUTLINE_BOUND, OUTLINE_BOUND, (2 * OBJECT_OUTLINE_POINTS,)),
            "object_holes": box(-OUTLINE_BOUND, OUTLINE_BOUND, (2 * MAX_HOLES * HOLE_POINTS,)),
            "object_hole_mask": box(0.0, 1.0, (MAX_HOLES,)),
            "table_outline": box(-OUTLINE_BOUND, OUTLINE_BOUND, (2 * TABLE_OUTLINE_POINTS,)),
            "table_height": box(-POS_BOUND, POS_BOUND, (1,)),
        }
    )


def holes_descriptor(obj: ObjectShape) -> tuple[np.ndarray, np.ndarray]:
    """The object's holes, largest first: (MAX_HOLES * HOLE_POINTS * 2,) points in the object
    frame (each hole's ring resampled like an outline, CCW, flattened x, y; zeros where no
    hole) and a (MAX_HOLES,) mask (1 where a hole is described)."""
    rings = [shapely.Polygon(ring) for ring in obj.polygon.interiors]
    rings.sort(key=lambda ring: -ring.area)  # stable: equal holes keep the shape's order
    points = np.zeros((MAX_HOLES, HOLE_POINTS, 2))
    mask = np.zeros(MAX_HOLES)
    for i, ring in enumerate(rings[:MAX_HOLES]):
        points[i] = outline_descriptor(ring, HOLE_POINTS)
        mask[i] = 1.0
    return points.reshape(-1), mask


class StateObservation:
    """Reads the state observation; the scene entries are fixed per episode (:meth:`set_scene`)."""

    def __init__(self) -> None:
        self.space = state_space()
        self._slices: dict[str, tuple[int, int]] = {}
        start = 0
        for key in FLAT_KEYS:
            size = self.space[key].shape[0]
            self._slices[key] = (start, start + size)
            start += size
        self._low = np.concatenate([self.space[k].low for k in FLAT_KEYS])
        self._high = np.concatenate([self.space[k].high for k in FLAT_KEYS])
        self._scene: dict[str, np.ndarray] = {}
        self.rng = np.random.default_rng(0)

    def set_scene(self, obj: ObjectShape, table: TableShape, rng: np.random.Generator) -> None:
        """The episode's outline and hole descriptors, the table height, and the generator
        the episode's observations draw from (only the point cloud's sampling does)."""
        self.rng = rng
        holes, mask = holes_descriptor(obj)
        scene = {
            "object_outline": obj.descriptor(OBJECT_OUTLINE_POINTS).reshape(-1),
            "object_holes": holes,
            "object_hole_mask": mask,
            "table_outline": table.descriptor(TABLE_OUTLINE_POINTS).reshape(-1),
            "table_height": np.array([table.height]),
        }
        self._scene = {
            key: np.clip(value, self.space[key].low, self.space[key].high).astype(np.float32)
            for key, value in scene.items()
        }

    def read(self, robot: WamT42, state: SceneState, hand_command: float) -> dict[str, np.ndarray]:
        """This step's observation (``state``: the object as read once after the step)."""
        q, dq = robot.joint_state()  # arm then finger joints
        tip_pos, tip_quat = robot.fingertip_pose()
        flat = np.concatenate(
            [
                q[:7],
                dq[:7],
                q[7:],
                dq[7:],
                [hand_command],
                tip_pos,
                tip_quat,
                state.object_position,
                state.object_quat,
                state.object_velocity,
            ]
        )
        flat = np.minimum(np.maximum(flat, self._low), self._high).astype(np.float32)
        obs = {key: flat[a:b] for key, (a, b) in self._slices.items()}
        obs.update({key: value.copy() for key, value in self._scene.items()})
        return obs

    def cameras(self, robot: WamT42) -> dict[str, CameraModel]:
        """The cameras the observation renders, as they are now (none for the state)."""
        return {}


class CameraObservation(StateObservation):
    """The state entries; :meth:`cameras` are the scene camera and the wrist camera, both
    ``width`` x ``height`` pixels."""

    def __init__(
        self,
        width: int | None = None,
        height: int | None = None,
        camera: Camera | Mapping[str, Any] | None = None,
    ) -> None:
        super().__init__()
        self.width, self.height = image_size(width, height, OBS_IMAGE_SIZE)
        self.camera = Camera.of(camera)

    def cameras(self, robot: WamT42) -> dict[str, CameraModel]:
        client = robot.sim.client
        w, h = self.width, self.height
        wrist = wrist_view(client, *robot.link_pose(WRIST_LINK))
        return {
            "scene": CameraModel(w, h, self.camera.fov, NEAR, FAR, self.camera.view(client)),
            "wrist": CameraModel(w, h, WRIST_FOV, NEAR, FAR, wrist),
        }


class RgbdObservation(CameraObservation):
    """The state entries plus RGB (uint8) and depth (float32, metres along the optical axis)
    images of the scene camera and of the wrist camera, rendered headless every step."""

    def __init__(
        self,
        width: int | None = None,
        height: int | None = None,
        camera: Camera | Mapping[str, Any] | None = None,
    ) -> None:
        super().__init__(width, height, camera)
        h, w = self.height, self.width
        rgb = spaces.Box(0, 255, (h, w, 3), np.uint8)
        depth = box(NEAR, FAR, (h, w, 1))
        images = dict(zip(IMAGE_KEYS, (rgb, depth, rgb, depth), strict=True))
        self.space = spaces.Dict({**self.space.spaces, **images})

    def read(self, robot: WamT42, state: SceneState, hand_command: float) -> dict[str, np.ndarray]:
        """The state entries and this step's four images."""
        obs = super().read(robot, state, hand_command)
        cameras = self.cameras(robot)
        scene = render_rgbd(robot.sim.client, cameras["scene"])
        wrist = render_rgbd(robot.sim.client, cameras["wrist"])
        obs.update(zip(IMAGE_KEYS, (*scene, *wrist), strict=True))
        return obs


class PointCloudObservation(CameraObservation):
    """The state entries plus ``num_points`` points fused from the scene and wrist cameras'
    depth (:mod:`slide_gym.envs.pointcloud`): world positions (float32, m), RGB (uint8) and
    labels (uint8, :data:`SEGMENT_NAMES`), sampled with the episode's generator."""

    def __init__(
        self,
        width: int | None = None,
        height: int | None = None,
        camera: Camera | Mapping[str, Any] | None = None,
        num_points: int | None = None,
    ) -> None:
        super().__init__(width, height, camera)
        n = self.num_points = NUM_POINTS if num_points is None else check_num_points(num_points)
        points = {
            "pointcloud_xyz": box(-POS_BOUND, POS_BOUND, (n, 3)),
            "pointcloud_rgb": spaces.Box(0, 255, (n, 3), np.uint8),
            "pointcloud_segmentation": spaces.Box(0, len(SEGMENT_NAMES) - 1, (n,), np.uint8),
        }
        self.space = spaces.Dict({**self.space.spaces, **points})

    def read(self, robot: WamT42, state: SceneState, hand_command: float) -> dict[str, np.ndarray]:
        """The state entries and this step's point cloud."""
        obs = super().read(robot, state, hand_command)
        cameras = self.cameras(robot).values()
        xyz, rgb, labels = fuse(robot.sim.client, cameras, robot.sim.bodies)
        keep = sample_indices(xyz, labels, self.num_points, self.rng)
        obs["pointcloud_xyz"] = np.clip(xyz[keep], -POS_BOUND, POS_BOUND)
        obs["pointcloud_rgb"] = rgb[keep]
        obs["pointcloud_segmentation"] = labels[keep]
        return obs


def make_observation(
    obs_mode: str,
    width: int | None = None,
    height: int | None = None,
    camera: Camera | Mapping[str, Any] | None = None,
    num_points: int | None = None,
) -> StateObservation:
    """The observation of ``obs_mode`` (one of :data:`OBS_MODES`); ``num_points`` only for
    ``"pointcloud"``."""
    if obs_mode not in OBS_MODES:
        raise ValueError(f"obs_mode must be one of {', '.join(OBS_MODES)}, got {obs_mode!r}")
    if num_points is not None and obs_mode != "pointcloud":
        raise ValueError(f"num_points goes with obs_mode='pointcloud', not {obs_mode!r}")
    if obs_mode == "pointcloud":
        return PointCloudObservation(width, height, camera, num_points)
    if obs_mode == "rgbd":
        return RgbdObservation(width, height, camera)
    return StateObservation()
