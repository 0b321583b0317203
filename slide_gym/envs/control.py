"""Control modes: how an action becomes arm joint targets and a hand command.

A controller keeps the arm's joint targets between steps. :meth:`ArmControl.apply` validates
an action, updates the targets and returns them with the hand command u in [0, 1]; the
environment sends both to the robot. The last action entry is always the hand command:
``u = (a + 1) / 2`` (0 = open, 1 = close). :func:`rotation_vector` and
:func:`rotation_matrix` convert between rotation matrices and world-frame rotation vectors
(the ``"ee_delta"`` rotation increments).
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from slide_gym.planning.ik import IKParams, IKTarget, pose_error
from slide_gym.robot.kinematics import fingertip_chain
from slide_gym.robot.model import ARM_LOWER, ARM_UPPER

MAX_TIP_STEP = 0.01
"""m: the default ``ee_delta`` position step (an action entry of 1)."""
MAX_ROT_STEP = 0.05
"""rad: the default ``ee_delta`` rotation step."""
EE_ACTION_SIZE = 7
"""Entries of an ``ee_delta`` action: position (3), rotation vector (3), hand command (1)."""
CONTROL_MODES = ("joint_delta", "ee_delta")
"""``"joint_delta"``: arm joint-position increments; ``"ee_delta"``: fingertip-pose increments."""


class ArmControl:
    """Base class: joint targets kept between steps, and the action's validation."""

    action_space: spaces.Box
    max_joint_step: float  # rad: the largest joint target change per step

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

    @property
    def state_size(self) -> int:
        """Length of :meth:`get_state`."""
        return 7

    def get_state(self) -> np.ndarray:
        """What the controller carries between steps: the joint targets (7,)."""
        return self.target.copy()

    def set_state(self, state: np.ndarray) -> None:
        """Restore :meth:`get_state`."""
        self.target = np.array(state[:7], dtype=float)


class JointDeltaControl(ArmControl):
    """``Box(-1, 1, (8,))``: entries 0-6 times ``max_joint_step`` (rad) are added to the arm's
    joint targets (clipped to the joint limits); entry 7 is the hand command."""

    def __init__(self, max_joint_step: float):
        super().__init__()
        self.max_joint_step = _positive("max_joint_step", max_joint_step)
        self.action_space = spaces.Box(-1.0, 1.0, (8,), np.float32)

    def _arm_targets(self, arm_action: np.ndarray) -> np.ndarray:
        return self.target + self.max_joint_step * arm_action


class EEDeltaControl(ArmControl):
    """``Box(-1, 1, (7,))``: fingertip-pose increments, solved to joint targets.

    Entries 0-2 times ``max_tip_step`` (m) move the target position of the fingertip frame
    (``fingertip_contact``, finger A's contact) in the world frame; entries 3-5 times
    ``max_rot_step`` (rad) are a world-frame rotation vector applied to its target orientation
    (entry 5 turns it about world z: position and yaw alone leave 3 and 4 at 0); entry 6 is
    the hand command. The target pose starts at the arm's pose at reset. Each step a few
    damped-least-squares iterations (the IK's damping) move the joint targets from where they
    were toward the new pose, within the joint limits and at most ``max_joint_step`` (rad) per
    joint. If that misses the pose by more than 1 mm or 0.01 rad (out of reach, at a joint
    limit, too fast), the target pose becomes the reached one, so it cannot run away.
    """

    ITERATIONS = 4
    RESYNC_POS, RESYNC_ROT = 1e-3, 1e-2  # m, rad: misses larger than this re-sync the target

    def __init__(
        self,
        max_joint_step: float,
        max_tip_step: float = MAX_TIP_STEP,
        max_rot_step: float = MAX_ROT_STEP,
    ):
        super().__init__()
        self.max_joint_step = _positive("max_joint_step", max_joint_step)
        self.max_tip_step = _positive("max_tip_step", max_tip_step)
        self.max_rot_step = _positive("max_rot_step", max_rot_step)
        self.action_space = spaces.Box(-1.0, 1.0, (EE_ACTION_SIZE,), np.float32)
        self.chain = fingertip_chain()
        ik = IKParams()
        self._damping = ik.damping**2 * np.eye(6)
        self._tol = (ik.pos_tol, ik.rot_tol)
        self.target_pose = self.chain.forward(self.target)

    def reset(self, arm_q: np.ndarray) -> None:
        super().reset(arm_q)
        self.target_pose = self.chain.forward(self.target)

    @property
    def state_size(self) -> int:
        return 7 + 12

    def get_state(self) -> np.ndarray:
        """The joint targets (7,), then the target pose's top three rows (12,), row-major."""
        return np.concatenate([self.target, self.target_pose[:3].ravel()])

    def set_state(self, state: np.ndarray) -> None:
        super().set_state(state)
        pose = np.eye(4)
        pose[:3] = np.asarray(state[7:19], dtype=float).reshape(3, 4)
        self.target_pose = pose

    def _arm_targets(self, arm_action: np.ndarray) -> np.ndarray:
        pose = self.target_pose.copy()
        pose[:3, 3] += self.max_tip_step * arm_action[:3]
        pose[:3, :3] = rotation_matrix(self.max_rot_step * arm_action[3:6]) @ pose[:3, :3]
        q, err = self._solve(pose)
        missed = np.linalg.norm(err[:3]) > self.RESYNC_POS
        missed |= np.linalg.norm(err[3:]) > self.RESYNC_ROT
        self.target_pose = self.chain.forward(q) if missed else pose
        return q

    def _solve(self, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Joint targets near ``pose`` from the current ones, and their pose error (6,)."""
        lo = np.maximum(ARM_LOWER, self.target - self.max_joint_step)
        hi = np.minimum(ARM_UPPER, self.target + self.max_joint_step)
        goal = IKTarget(pose[:3, 3], pose[:3, :3])
        q = self.target.copy()
        for _ in range(self.ITERATIONS):
            tip, jac = self.chain.jacobian(q)
            err = pose_error(tip, goal)
            if np.linalg.norm(err[:3]) <= self._tol[0] and np.linalg.norm(err[3:]) <= self._tol[1]:
                return q, err
            q = np.clip(q + jac.T @ np.linalg.solve(jac @ jac.T + self._damping, err), lo, hi)
        return q, pose_error(self.chain.forward(q), goal)


def _positive(name: str, value: float) -> float:
    if isinstance(value, bool) or not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a positive number, got {value!r}")
    return float(value)


def rotation_matrix(rotvec: np.ndarray) -> np.ndarray:
    """The rotation (3, 3) of a rotation vector (3,) (axis times angle, rad)."""
    v = np.asarray(rotvec, dtype=float)
    angle = float(np.linalg.norm(v))
    if angle < 1e-12:
        return np.eye(3)
    x, y, z = v / angle
    k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * (k @ k)


def rotation_vector(rot: np.ndarray) -> np.ndarray:
    """The rotation vector (3,) (axis times angle in [0, pi]) of a rotation matrix (3, 3)."""
    r = np.asarray(rot, dtype=float)
    w = 0.5 * np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])  # sin * axis
    c = float(np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0))
    s = float(np.linalg.norm(w))
    angle = float(np.arctan2(s, c))
    if c > -0.9:  # angle below ~2.7 rad: sin is large enough (or the angle is tiny)
        return w * (angle / s) if s > 0.0 else np.zeros(3)
    outer = ((r + r.T) / 2.0 - c * np.eye(3)) / (1.0 - c)  # axis axis^T
    k = int(np.argmax(np.diag(outer)))
    axis = outer[:, k] / np.sqrt(outer[k, k])
    return angle * (axis if axis @ w >= 0.0 else -axis)


def make_control(
    mode: str,
    max_joint_step: float,
    max_tip_step: float = MAX_TIP_STEP,
    max_rot_step: float = MAX_ROT_STEP,
) -> ArmControl:
    """The controller of ``mode`` (one of :data:`CONTROL_MODES`); the step sizes are checked
    whatever the mode."""
    if mode not in CONTROL_MODES:
        raise ValueError(f"control_mode must be one of {', '.join(CONTROL_MODES)}, got {mode!r}")
    _positive("max_tip_step", max_tip_step)
    _positive("max_rot_step", max_rot_step)
    if mode == "ee_delta":
        return EEDeltaControl(max_joint_step, max_tip_step, max_rot_step)
    return JointDeltaControl(max_joint_step)
