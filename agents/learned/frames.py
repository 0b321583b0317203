"""Fingertip targets in a task frame: the ``"targets"`` action representation.

Per-step increments (``"deltas"``) say how to move, not where to go, so a grasp that is learned
as increments lands wherever their errors add up to. With ``"targets"`` a chunk holds where
the fingertip should be after each step, as a pose in a frame fixed to the task when the
policy (or skill) starts acting, and each step's ``ee_delta`` action is the clipped step from
the measured fingertip pose toward the current target:

- the frame's origin is the plate's bottom-face centroid, its x axis the outward normal of
  the table edge nearest the plate (:func:`~agents.learned.features.task_features`) and its z
  axis world up. Every grasp of a slid plate approaches that edge, so in this frame the
  demonstrated grasps nearly coincide wherever the plate ended up;
- a target is the position (3) and the first two columns of the orientation (6, the
  continuous 6-D rotation of Zhou et al. 2019) of the fingertip in that frame;
- the fingertip pose is the one the ``ee_delta`` controller commands: the forward kinematics
  of the observed arm joints with the hand at rest (:func:`arm_fingertip_poses`). The
  observation's ``fingertip_pose`` also moves with the finger springs: closing the hand swings
  it a few centimetres, which a target would turn into an arm motion;
- the label of step ``t`` is that pose after it (observation ``t + 1``).

Only ``control_mode="ee_delta"`` demonstrations (7 action entries) can be represented this
way; a chunk then has :data:`TARGET_SIZE` + 1 entries (the hand command last).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from agents.learned.features import TASK_FEATURES, task_features
from slide_gym.envs.control import MAX_ROT_STEP, MAX_TIP_STEP, rotation_vector

TARGET_SIZE = 9
"""Entries of a target: position (3) and the orientation's first two columns (6)."""
_NAMES = [name for name, _ in TASK_FEATURES]
_EDGE = sum(size for _, size in TASK_FEATURES[: _NAMES.index("edge_direction")])
"""Column of the ``edge_direction`` feature in :func:`task_features`."""


def task_frames(obs: Mapping[str, np.ndarray]) -> np.ndarray:
    """(N, 4, 4) task frames (see the module docstring) of a batch of observations."""
    plate = np.asarray(obs["object_pose"], np.float64)
    normal = task_features(obs)[:, _EDGE : _EDGE + 2].astype(np.float64)
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
    frames = np.zeros((len(plate), 4, 4))
    frames[:, 0, 0], frames[:, 1, 0] = normal[:, 0], normal[:, 1]
    frames[:, 0, 1], frames[:, 1, 1] = -normal[:, 1], normal[:, 0]
    frames[:, 2, 2] = 1.0
    frames[:, :3, 3] = plate[:, :3]
    frames[:, 3, 3] = 1.0
    return frames


def arm_fingertip_poses(arm_qpos: np.ndarray) -> np.ndarray:
    """(N, 4, 4) world poses of the ``fingertip_contact`` frame for arm joint angles (N, 7),
    the hand at rest: the frame the ``ee_delta`` controller moves."""
    from slide_gym.robot.kinematics import fingertip_chain

    return fingertip_chain().forward(np.asarray(arm_qpos, np.float64).reshape(-1, 7))


def targets_in_frame(poses: np.ndarray, frame: np.ndarray) -> np.ndarray:
    """(N, :data:`TARGET_SIZE`) float32: poses (N, 4, 4) in one task frame (4, 4)."""
    rot_f, origin = frame[:3, :3], frame[:3, 3]
    pos = (poses[:, :3, 3] - origin) @ rot_f
    rot = np.einsum("ji,njk->nik", rot_f, poses[:, :3, :3])
    return np.column_stack([pos, rot[:, :, 0], rot[:, :, 1]]).astype(np.float32)


def _orthonormal(six: np.ndarray) -> np.ndarray:
    """The rotation (3, 3) whose first two columns are nearest the 6-D vector (Gram-Schmidt)."""
    a, b = six[:3], six[3:6]
    x = a / max(float(np.linalg.norm(a)), 1e-9)
    y = b - x * float(x @ b)
    y /= max(float(np.linalg.norm(y)), 1e-9)
    return np.column_stack([x, y, np.cross(x, y)])


def step_toward(
    target: np.ndarray,
    frame: np.ndarray,
    arm_qpos: np.ndarray,
    max_tip_step: float = MAX_TIP_STEP,
    max_rot_step: float = MAX_ROT_STEP,
) -> np.ndarray:
    """(6,) float32: the arm part of an ``ee_delta`` action from the fingertip pose of the
    observed ``arm_qpos`` (7,) toward ``target`` (:data:`TARGET_SIZE`,) in ``frame``, each
    entry clipped to [-1, 1]."""
    target = np.asarray(target, np.float64)
    now = arm_fingertip_poses(arm_qpos)[0]
    pos = frame[:3, 3] + frame[:3, :3] @ target[:3]
    rot = frame[:3, :3] @ _orthonormal(target[3:])
    move = (pos - now[:3, 3]) / max_tip_step
    turn = rotation_vector(rot @ now[:3, :3].T) / max_rot_step
    return np.clip(np.concatenate([move, turn]), -1.0, 1.0).astype(np.float32)
