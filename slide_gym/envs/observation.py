"""The environment's observations: the state ``Dict`` space and how one is read.

:class:`StateObservation` declares the proprioceptive, object and scene entries (see the
table in :class:`~slide_gym.envs.top_slide.TopSlideEnv`) and packs them from the robot and
the task's :class:`~slide_gym.task.SceneState`, clipped to the declared bounds.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from slide_gym.geometry import ObjectShape, TableShape
from slide_gym.robot import ARM_LOWER, ARM_UPPER, FINGER_LOWER, FINGER_UPPER, WamT42
from slide_gym.task import SceneState

OBS_MODES = ("state",)
"""Observation modes: ``"state"`` (the Dict below)."""
OBJECT_OUTLINE_POINTS = 32
TABLE_OUTLINE_POINTS = 64
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
            "object_outline": box(-OUTLINE_BOUND, OUTLINE_BOUND, (OBJECT_OUTLINE_POINTS, 2)),
            "table_outline": box(-OUTLINE_BOUND, OUTLINE_BOUND, (TABLE_OUTLINE_POINTS, 2)),
            "table_height": box(-POS_BOUND, POS_BOUND, (1,)),
        }
    )


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

    def set_scene(self, obj: ObjectShape, table: TableShape) -> None:
        """The episode's outline descriptors and table height."""
        space = self.space
        self._scene = {
            "object_outline": np.clip(
                obj.descriptor(OBJECT_OUTLINE_POINTS),
                space["object_outline"].low,
                space["object_outline"].high,
            ).astype(np.float32),
            "table_outline": np.clip(
                table.descriptor(TABLE_OUTLINE_POINTS),
                space["table_outline"].low,
                space["table_outline"].high,
            ).astype(np.float32),
            "table_height": np.array([table.height], dtype=np.float32),
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
