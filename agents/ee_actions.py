"""The expert's actions in ``control_mode="ee_delta"``: fingertip-pose increments toward its
joint targets, with an exact mirror of the environment's controller."""

from __future__ import annotations

import numpy as np

from slide_gym.envs.control import EEDeltaControl, rotation_vector
from slide_gym.robot.model import ARM_LOWER, ARM_UPPER


class EEActions:
    """Turns desired joint targets into ``ee_delta`` actions.

    The fingertip pose of the desired targets is compared with the target pose of a copy of
    the environment's :class:`~slide_gym.envs.control.EEDeltaControl`, which is fed the same
    actions: from the same start, its joint targets (:attr:`q_cmd`) equal the environment's
    bit for bit (the expert starts it, as in joint mode, from the observed arm angles, about
    1e-6 rad from the environment's start targets after the reset settles). The increment
    (position and rotation vector) is scaled to the step sizes and, if larger than one step,
    shrunk as a whole so the pose moves straight toward the desired one. While the pose lags
    that way, :meth:`hold` tells the expert to repeat its last target instead of taking the
    next one, so fast legs are slowed down rather than cut short (at most ``MAX_HOLD`` steps
    in a row).

    Args:
        max_joint_step, max_tip_step, max_rot_step: the environment's values.
    """

    MAX_HOLD = 40

    def __init__(self, max_joint_step: float, max_tip_step: float, max_rot_step: float):
        self.control = EEDeltaControl(max_joint_step, max_tip_step, max_rot_step)
        self.last: tuple[np.ndarray, float, float] | None = None  # target, hand, limit
        self.behind = False  # the last action fell short of its target's pose
        self._held = 0

    def reset(self, arm_q: np.ndarray) -> None:
        """Start from the arm's joint angles, as the environment's controller does at reset."""
        self.control.reset(arm_q)
        self.last, self.behind, self._held = None, False, 0

    def hold(self) -> bool:
        """Whether to repeat the last target (the pose lags it) rather than take the next."""
        if self.last is None or not self.behind or self._held >= self.MAX_HOLD:
            self._held = 0
            return False
        self._held += 1
        return True

    @property
    def q_cmd(self) -> np.ndarray:
        """The controller's joint targets (a copy)."""
        return self.control.target.copy()

    def action(self, target_q: np.ndarray, hand: float, limit: float = 1.0) -> np.ndarray:
        """The action (7,) moving the target pose toward ``target_q``'s fingertip pose, with
        hand command ``hand`` in [0, 1]; the mirror controller applies it. ``limit`` (at most
        1) caps the action's largest arm entry (a re-timed plan's speed)."""
        c = self.control
        move = _pose_move(
            c.chain.forward(np.clip(target_q, ARM_LOWER, ARM_UPPER)), c.target_pose, c
        )
        scale = float(np.abs(move).max())
        self.behind = scale > limit
        move /= max(1.0, scale / limit)
        self.last = (np.array(target_q, dtype=float), float(hand), float(limit))
        action = np.r_[move, 2.0 * hand - 1.0].astype(np.float32)
        c.apply(action)
        return action

    def step_size(self, q_from: np.ndarray, q_to: np.ndarray) -> float:
        """The largest arm entry of the action that moves the fingertip pose of ``q_from`` to
        that of ``q_to`` (a plan's speed between two consecutive targets, in action units)."""
        c = self.control
        poses = c.chain.forward(np.clip(np.stack([q_to, q_from]), ARM_LOWER, ARM_UPPER))
        return float(np.abs(_pose_move(poses[0], poses[1], c)).max())


def _pose_move(want: np.ndarray, have: np.ndarray, c: EEDeltaControl) -> np.ndarray:
    """The unscaled action (6,) that moves pose ``have`` (4x4) to ``want``."""
    return np.r_[
        (want[:3, 3] - have[:3, 3]) / c.max_tip_step,
        rotation_vector(want[:3, :3] @ have[:3, :3].T) / c.max_rot_step,
    ]
