"""What a learned policy sees: the state observation flattened, plus task features computed
from it.

Everything here is a function of the observation alone (nothing privileged from the
simulator), vectorised over a leading batch axis so that training data and a policy's inputs
go through the same code. :func:`task_features` gives, per observation:

| feature | size | meaning |
|---|---|---|
| ``plate_in_tip`` | 3 | plate position (bottom-face centroid) in the fingertip frame (m) |
| ``plate_yaw_in_tip`` | 2 | cos, sin of the plate's yaw minus the fingertip's yaw |
| ``edge_distance`` | 1 | plate centroid to the nearest table edge (m; negative: off the table) |
| ``edge_direction`` | 2 | that edge's outward unit normal (world xy) |
| ``overhang`` | 1 | how far the plate outline reaches past that edge's line (m, >= 0) |

The table edges are the segments between the observation's resampled table outline points,
and the overhang is measured against the edge nearest the plate's centroid, so it reads
close to, not exactly, the env's ``info["overhang_m"]`` (which uses the exact polygons).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from slide_gym.envs.observation import FLAT_KEYS, SCENE_KEYS
from slide_gym.robot.model import MIN_CONTACT_SIZE

STATE_KEYS = (*FLAT_KEYS, *SCENE_KEYS)
"""The state observation's entries, in the order :func:`flatten` packs them."""
TASK_FEATURES = (
    ("plate_in_tip", 3),
    ("plate_yaw_in_tip", 2),
    ("edge_distance", 1),
    ("edge_direction", 2),
    ("overhang", 1),
)
TASK_FEATURE_SIZE = sum(size for _, size in TASK_FEATURES)
SLIDE_DONE_OVERHANG = MIN_CONTACT_SIZE
"""m: the overhang from which :func:`slide_done` may hold (the task's u*)."""
SLIDE_DONE_BEND = 0.05
"""rad: :func:`slide_done` holds once the pressing finger's joint is bent less than this
(pressed, it bends 0.2-0.3 rad; unloaded, within 0.03)."""


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """(..., 4) quaternions xyzw (normalised here) to (..., 3, 3) rotation matrices."""
    q = q / np.maximum(np.linalg.norm(q, axis=-1, keepdims=True), 1e-12)
    x, y, z, w = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def _yaw(rot: np.ndarray) -> np.ndarray:
    """Heading of a rotation's x axis in the world xy plane (rad)."""
    return np.arctan2(rot[..., 1, 0], rot[..., 0, 0])


def task_features(obs: Mapping[str, np.ndarray]) -> np.ndarray:
    """(N, :data:`TASK_FEATURE_SIZE`) features (see the module docstring) of a batch of
    observations (each entry (N, size))."""
    tip = np.asarray(obs["fingertip_pose"], np.float64)
    plate = np.asarray(obs["object_pose"], np.float64)
    tip_rot, plate_rot = quat_to_matrix(tip[:, 3:]), quat_to_matrix(plate[:, 3:])
    plate_in_tip = np.einsum("nji,nj->ni", tip_rot, plate[:, :3] - tip[:, :3])
    dyaw = _yaw(plate_rot) - _yaw(tip_rot)

    table = np.asarray(obs["table_outline"], np.float64).reshape(len(tip), -1, 2)
    a, b = table, np.roll(table, -1, axis=1)  # (N, E, 2) edge ends; the outline is CCW
    edge = b - a
    length = np.maximum(np.linalg.norm(edge, axis=-1), 1e-9)
    normal = np.stack([edge[..., 1], -edge[..., 0]], -1) / length[..., None]  # outward
    centre = plate[:, None, :2]
    along = np.clip(np.einsum("nek,nek->ne", centre - a, edge) / length**2, 0.0, 1.0)
    dist = np.linalg.norm(a + along[..., None] * edge - centre, axis=-1)
    nearest = np.argmin(dist, axis=1)
    rows = np.arange(len(tip))
    n_near, a_near = normal[rows, nearest], a[rows, nearest]
    depth = np.einsum("nk,nk->n", centre[:, 0] - a_near, n_near)  # > 0: centroid outside
    edge_distance = np.where(depth > 0, -dist[rows, nearest], dist[rows, nearest])

    outline = np.asarray(obs["object_outline"], np.float64).reshape(len(tip), -1, 2)
    world = np.einsum("nij,npj->npi", plate_rot[:, :2, :2], outline) + centre
    reach = np.einsum("npk,nk->np", world - a_near[:, None], n_near).max(axis=1)
    return np.column_stack(
        [
            plate_in_tip,
            np.cos(dyaw),
            np.sin(dyaw),
            edge_distance,
            n_near,
            np.maximum(reach, 0.0),
        ]
    ).astype(np.float32)


def slide_done(obs: Mapping[str, np.ndarray]) -> np.ndarray:
    """(N,) bool: the observations show a finished slide. The plate overhangs the nearest
    edge by at least :data:`SLIDE_DONE_OVERHANG` (the task's u*, as the ``overhang`` feature
    reads it) and the pressing finger has unbent to within :data:`SLIDE_DONE_BEND` (the
    fingertip has let go). ``TopSlide-v0``'s expert demonstrations end about there, and in a
    ``TopSlideGrasp-v0`` demonstration it first holds a few steps into the lift-off: the
    point where a grasping skill takes over from a sliding one
    (:class:`~agents.learned.policy.DiffusionPolicy` with ``first``)."""
    bend = np.abs(np.asarray(obs["finger_qpos"], np.float64)[:, 0])
    return (task_features(obs)[:, -1] >= SLIDE_DONE_OVERHANG) & (bend < SLIDE_DONE_BEND)


def flatten(obs: Mapping[str, np.ndarray], keys: Sequence[str] = STATE_KEYS) -> np.ndarray:
    """(N, D) float32: the entries ``keys`` of a batch of observations, side by side."""
    n = len(np.asarray(obs[keys[0]]))
    return np.concatenate([np.asarray(obs[k], np.float32).reshape(n, -1) for k in keys], axis=1)


def fingertip_axes(obs: Mapping[str, np.ndarray]) -> np.ndarray:
    """(N, 6) float32: the fingertip frame's x and z axes in the world frame.

    The observation's quaternion changes sign where its w crosses zero, so a hand turning
    from pressing to a side grasp shows a jump of up to 2 in an input that moved smoothly
    (96 times in the transfers of 200 grasp demonstrations); these columns of its rotation
    matrix move smoothly with it."""
    rot = quat_to_matrix(np.asarray(obs["fingertip_pose"], np.float64)[:, 3:])
    return np.concatenate([rot[:, :, 0], rot[:, :, 2]], axis=1).astype(np.float32)


def policy_input(
    obs: Mapping[str, np.ndarray], with_features: bool = True, tip_axes: bool = False
) -> np.ndarray:
    """(N, D) float32: what a learned policy sees of a batch of observations (the state
    entries, then :func:`task_features` unless ``with_features`` is False, then
    :func:`fingertip_axes` if ``tip_axes``)."""
    parts = [flatten(obs)]
    if with_features:
        parts.append(task_features(obs))
    if tip_axes:
        parts.append(fingertip_axes(obs))
    return np.concatenate(parts, axis=1)
