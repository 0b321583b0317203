"""The top-sliding planning problem (OMPL's problem definition): the plate, the table, the
start pose and what follows from them (P_o in the world, the goal band P_g, the contact
height band)."""

from __future__ import annotations

from typing import Any

import numpy as np
import shapely

from slide_gym.geometry import ObjectShape, TableShape, get_object, get_table, transform_points
from slide_gym.planning.grasp_reach import nearest_stretches, reachable_stretches
from slide_gym.planning.params import SlideParams
from slide_gym.planning.regions import goal_band
from slide_gym.task import check_scene, validate_start_pose


def _supported_pose(obj: ObjectShape, table: TableShape, pose: Any) -> np.ndarray:
    """A start pose whose centroid is over the table (the plate may overhang)."""
    arr = np.asarray(pose, dtype=float).reshape(-1)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"object_pose must be 3 finite numbers (x, y, yaw), got {pose!r}")
    if not shapely.contains_xy(table.polygon, arr[0], arr[1]):
        raise ValueError(f"object_pose {arr.tolist()} puts the object's centroid off the table")
    return arr


class TopSlideProblem:
    """A plate on a table at a start pose; raises ValueError for scenes that cannot work.

    Args:
        obj: an :class:`ObjectShape` or a catalog name / JSON path.
        table: a :class:`TableShape` or a catalog name / JSON path.
        object_start_pose: (x, y, yaw) of the plate, fully on the table and in reach.
        params: planner parameters.
        allow_overhang: accept a start pose that already overhangs an edge (a replan after a
            short slide); the centroid must still be over the table, and presses stay over it.
    """

    def __init__(
        self,
        obj: ObjectShape | str,
        table: TableShape | str,
        object_start_pose: Any,
        params: SlideParams | None = None,
        allow_overhang: bool = False,
    ):
        self.object = get_object(obj)
        self.table = get_table(table)
        self.params = params or SlideParams()
        check_scene(self.object, self.table)
        if allow_overhang:
            self.start_pose = _supported_pose(self.object, self.table, object_start_pose)
        else:
            self.start_pose = validate_start_pose(self.object, self.table, object_start_pose)
        self.z_surface = self.table.height + self.object.thickness
        self.height_range = self.params.contact_height_range(self.z_surface)
        top = self.object.top_surface_points(self.params.cloud_spacing)
        if self.params.press_edge_margin > 0.0:  # a rounded tip pressed near an edge slips off
            inset = shapely.distance(self.object.polygon.boundary, shapely.points(top[:, :2]))
            top = top[inset >= min(self.params.press_edge_margin, inset.max())]
        if self.params.press_radius is not None:  # P_o near the centroid: less spin while sliding
            d = np.linalg.norm(top[:, :2], axis=1)  # the shape's frame is centred on its centroid
            top = top[d <= d.min() + self.params.press_radius]
        xy = transform_points(top[:, :2], *self.start_pose)
        if allow_overhang:  # press only where the table is underneath
            inner = self.table.polygon.buffer(-self.params.cloud_spacing)
            xy = xy[shapely.contains_xy(inner, xy[:, 0], xy[:, 1])]
            if len(xy) == 0:
                raise ValueError("no part of the object's top lies over the table to press on")
        self.start_points = np.column_stack([xy, np.full(len(xy), self.z_surface)])
        margin = self.params.tip_edge_margin
        self.contact_area = self.table.polygon.buffer(-margin) if margin > 0 else self.table.polygon
        """Where the fingertip contact may be: the table, ``tip_edge_margin`` in from its edge."""
        if self.contact_area.is_empty:
            raise ValueError(f"tip_edge_margin {margin} m leaves no table to press on")
        grasp_z = self.table.height + 0.5 * self.object.thickness
        offset = self.params.grasp.edge_clearance
        self.grasp_stretches = (
            reachable_stretches(self.table.polygon, grasp_z, offset)
            if self.params.goal_band_reachable
            else None
        )
        """The outline's stretches ``(p, q, outward normal)`` with a reachable side grasp
        (:mod:`~slide_gym.planning.grasp_reach`), only the nearest ones with ``goal_edge``
        ``"nearest"``; None: every edge, unchecked."""
        if self.grasp_stretches is not None and self.params.goal_edge == "nearest":
            self.grasp_stretches = nearest_stretches(self.grasp_stretches, self.start_pose[:2])
        self.goal_band = goal_band(
            self.table.polygon,
            self.params.goal_band_width,
            grasp_z if self.params.goal_band_reachable else None,
            offset,
            stretches=self.grasp_stretches,
        )
        if margin > 0:
            self.goal_band = self.goal_band.intersection(self.contact_area)

    def describe(self) -> dict[str, Any]:
        """Scene summary for results and logs."""
        return {
            "object": self.object.name,
            "table": self.table.name,
            "object_start_pose": self.start_pose.tolist(),
            "z_surface": self.z_surface,
            "contact_height_range": list(self.height_range),
            "n_start_points": len(self.start_points),
        }
