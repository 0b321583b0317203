"""The ``"pointcloud"`` observation's points: depth images fused into one cloud of fixed size.

:func:`fuse` turns each camera's depth and segmentation (:func:`~slide_gym.envs.cameras.capture`)
into world-frame points with their RGB and a label (:data:`SEGMENT_NAMES`), leaving out the
pixels where nothing is in view. :func:`sample_indices` picks a fixed number of them: one
point per 1 cm voxel and label first (which costs nothing in the sample and cuts its time
about fourfold), then farthest-point sampling from a seeded start, so a seed gives the same
cloud on any machine.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from slide_gym.envs.cameras import CameraModel, capture

SEGMENT_NAMES = ("plate", "table", "robot")
"""Point labels: a point's label is the index of its body's name here."""
SEGMENT_BODIES = ("object", "table", "robot")
"""The simulation's body names (:attr:`slide_gym.sim.Simulation.bodies`) in label order."""
NUM_POINTS = 1024
"""Points of the ``"pointcloud"`` observation unless ``num_points`` is given."""
MAX_POINTS = 65536
VOXEL_SIZE = 0.01
"""Edge of the voxels that thin the fused cloud before sampling (m)."""


def check_num_points(value: Any) -> int:
    """``value`` as a whole number of points in 1..MAX_POINTS, else a ValueError."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"num_points must be a whole number, got {value!r}")
    if not 1 <= value <= MAX_POINTS:
        raise ValueError(f"num_points must be 1..{MAX_POINTS}, got {value}")
    return int(value)


def fuse(
    client: Any, models: Iterable[CameraModel], bodies: Mapping[str, int]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every pixel of every camera that sees a body of :data:`SEGMENT_BODIES`: world points
    ``(m, 3)`` float32, RGB ``(m, 3)`` uint8 and labels ``(m,)`` uint8, camera by camera."""
    xyz, rgb, labels = [], [], []
    for model in models:
        colour, depth, seg = capture(client, model, segmentation=True)
        assert seg is not None
        # Body id + 1 -> label (-1: nothing in view, or a body the cloud leaves out).
        lookup = np.full(max(int(seg.max()), *bodies.values()) + 2, -1, dtype=np.int16)
        for value, name in enumerate(SEGMENT_BODIES):
            lookup[bodies[name] + 1] = value
        label = lookup[seg + 1]
        keep = label >= 0
        xyz.append(model.unproject(depth, keep).astype(np.float32))
        rgb.append(colour[keep])
        labels.append(label[keep].astype(np.uint8))
    return np.concatenate(xyz), np.concatenate(rgb), np.concatenate(labels)


def farthest_point_indices(points: np.ndarray, n: int, start: int) -> np.ndarray:
    """``n`` indices into ``points`` ``(m, 3)`` (``n <= m``) by farthest-point sampling from
    ``start``: each next point is the one farthest from all chosen so far (the first such
    on ties). Element-wise float32 operations only, so the result is the same on any CPU."""
    x, y, z = (np.ascontiguousarray(points[:, k], dtype=np.float32) for k in range(3))
    m = len(x)
    chosen = np.empty(n, dtype=np.int64)
    chosen[0] = start
    nearest = np.full(m, np.inf, dtype=np.float32)  # squared distance to the chosen set
    d, t = np.empty(m, dtype=np.float32), np.empty(m, dtype=np.float32)
    for i in range(1, n):
        j = chosen[i - 1]
        np.subtract(x, x[j], out=d)
        np.square(d, out=d)
        for axis in (y, z):
            np.subtract(axis, axis[j], out=t)
            np.square(t, out=t)
            d += t
        np.minimum(nearest, d, out=nearest)
        chosen[i] = nearest.argmax()
    return chosen


def voxel_representatives(points: np.ndarray, labels: np.ndarray, size: float) -> np.ndarray:
    """Indices, in order, of the first point in each occupied voxel of edge ``size`` (m) and
    label (points of two bodies never merge)."""
    cells = np.floor(points / size).astype(np.int64)
    cells -= cells.min(axis=0)
    shape = (len(SEGMENT_NAMES), *(cells.max(axis=0) + 1))
    key = np.ravel_multi_index((labels, *cells.T), shape)
    _, first = np.unique(key, return_index=True)
    return np.sort(first)


def sample_indices(
    points: np.ndarray, labels: np.ndarray, n: int, rng: np.random.Generator
) -> np.ndarray:
    """``n`` indices into ``points`` ``(m, 3)``: farthest-point sampling, from a start drawn
    from ``rng``, of one point per :data:`VOXEL_SIZE` voxel and label (of every point if the
    voxels are fewer than ``n``); with fewer than ``n`` points, all of them and then
    ``n - m`` drawn again from ``rng`` (repeats)."""
    m = len(points)
    if m == 0:
        raise RuntimeError("no camera sees the plate, the table or the robot: no points")
    if m < n:
        return np.concatenate([np.arange(m), rng.integers(0, m, n - m)])
    candidates = voxel_representatives(points, labels, VOXEL_SIZE)
    if len(candidates) < n:
        candidates = np.arange(m)
    start = int(rng.integers(len(candidates)))
    return candidates[farthest_point_indices(points[candidates], n, start)]
