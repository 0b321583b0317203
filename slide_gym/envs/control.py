"""Control modes: how an action becomes arm joint targets and a hand command.

A controller keeps the arm's joint targets between steps. :meth:`ArmControl.apply` validates
an action, updates the targets and returns them with the hand command u in [0, 1]; the
environment sends both to the robot. The last action entry is always the hand command:
``u = (a + 1) / 2`` (0 = open, 1 = close).
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from slide_gym.robot import ARM_LOWER, ARM_UPPER

CONTROL_MODES = ("joint_delta",)
"""``"joint_delta"``: arm joint-position increments."""


class ArmControl:
    """Base class: joint targets kept between steps, and the action's validation."""

    action_space: spaces.Box

    def __init__(self) -> None:
        self.target = np.zeros(7)

    def reset(self, arm_q: np.ndarray) -> None:
        """Start an episode with the targets at the arm's joint angles ``arm_q`` (7,)."""
        self.target = np.array(arm_q, dtype=float)

    def apply(self, action: np.ndarray) -> tuple[np.ndarray, float]:
        """The arm targets (7,) and hand command u for ``action`` (clipped to [-1, 1])."""
        n = self.action_space.shape[0]
        a = np.asarray(action, dtype=float).reshape(-1)
        if a.shape != (n,) or not np.all(np.isfinite(a)):
            raise ValueError(f"action must be {n} finite numbers in [-1, 1], got {action!r}")
        a = np.clip(a, -1.0, 1.0)
        self.target = np.clip(self._arm_targets(a[:-1]), ARM_LOWER, ARM_UPPER)
        return self.target, float((a[-1] + 1.0) / 2.0)

    def _arm_targets(self, arm_action: np.ndarray) -> np.ndarray:
        raise NotImplementedError


class JointDeltaControl(ArmControl):
    """``Box(-1, 1, (8,))``: entries 0-6 times ``max_joint_step`` (rad) are added to the arm's
    joint targets (clipped to the joint limits); entry 7 is the hand command."""

    def __init__(self, max_joint_step: float):
        super().__init__()
        if not (np.isfinite(max_joint_step) and max_joint_step > 0):
            raise ValueError(f"max_joint_step must be a positive number, got {max_joint_step}")
        self.max_joint_step = float(max_joint_step)
        self.action_space = spaces.Box(-1.0, 1.0, (8,), np.float32)

    def _arm_targets(self, arm_action: np.ndarray) -> np.ndarray:
        return self.target + self.max_joint_step * arm_action


def make_control(mode: str, max_joint_step: float) -> ArmControl:
    """The controller of ``mode`` (one of :data:`CONTROL_MODES`)."""
    if mode == "joint_delta":
        return JointDeltaControl(max_joint_step)
    raise ValueError(f"control_mode must be one of {', '.join(CONTROL_MODES)}, got {mode!r}")
