"""The scene an observation describes: which object (and scale) and which table.

The environment observes the object outline (in the object's frame) and the table outline (in
the world) as fixed-size arc-length samples, flattened ``x0, y0, x1, ...`` (the methods here
also take them as (n, 2) points). An agent recognises known shapes from them exactly:
the samples of a shape scaled by ``s`` are ``s`` times its unit samples, so a least-squares
scale and a residual identify the shape. Unknown outlines fall back to the polygon through the
samples (an approximation: corners are cut, holes are left out).
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable

import numpy as np

from slide_gym.envs.observation import OBJECT_OUTLINE_POINTS, TABLE_OUTLINE_POINTS
from slide_gym.geometry import OBJECTS, TABLES, ObjectShape, TableShape

MATCH_TOLERANCE = 1e-4
"""Largest outline sample mismatch (m) for a known shape to count as observed."""


class SceneLibrary:
    """Known objects and tables (any given, then the catalog), recognised from observations.

    Given shapes come first, so one that shares a catalog outline (a catalog letter with
    another thickness, say) wins over it; tables must also match the observed height.
    """

    def __init__(
        self,
        objects: Iterable[ObjectShape] = (),
        tables: Iterable[TableShape] = (),
    ):
        self.objects = [*objects, *OBJECTS.values()]
        self.tables = [*tables, *TABLES.values()]
        self._object_outlines = np.stack(
            [o.descriptor(OBJECT_OUTLINE_POINTS) for o in self.objects]
        )
        self._table_outlines = np.stack([t.descriptor(TABLE_OUTLINE_POINTS) for t in self.tables])

    def object_from(self, outline: np.ndarray) -> ObjectShape:
        """The known object (rescaled) whose outline samples match, else the sampled polygon."""
        obs = np.asarray(outline, dtype=float).reshape(OBJECT_OUTLINE_POINTS, 2)
        ref = self._object_outlines
        scales = np.einsum("kij,ij->k", ref, obs) / np.einsum("kij,kij->k", ref, ref)
        residual = np.abs(ref * scales[:, None, None] - obs).max(axis=(1, 2))
        k = int(np.argmin(residual))
        if residual[k] <= MATCH_TOLERANCE and scales[k] > 0:
            shape = self.objects[k]
            return shape if abs(scales[k] - 1.0) < 1e-6 else shape.scaled(float(scales[k]))
        warnings.warn(
            "object outline matches no known shape: planning on the polygon through its "
            f"{len(obs)} samples (pass the shape to the agent for an exact plan)",
            stacklevel=3,
        )
        return ObjectShape.from_vertices("observed", obs)

    def table_from(self, outline: np.ndarray, height: float) -> TableShape:
        """The known table whose outline samples match, else the sampled polygon."""
        obs = np.asarray(outline, dtype=float).reshape(TABLE_OUTLINE_POINTS, 2)
        residual = np.abs(self._table_outlines - obs).max(axis=(1, 2))
        residual[[abs(t.height - float(height)) > 1e-6 for t in self.tables]] = np.inf
        k = int(np.argmin(residual))
        if residual[k] <= MATCH_TOLERANCE:
            return self.tables[k]
        warnings.warn(
            "table outline matches no known table: planning on the polygon through its samples",
            stacklevel=3,
        )
        return TableShape.from_vertices("observed", obs, height=float(height))
