"""Object and table shapes, and their JSON files.

Conventions (public contract):

* Object: a thin flat plate, a planar polygon (concave and with holes allowed) extruded by
  ``thickness`` (default 0.004 m), of uniform ``density`` (default 1200 kg/m^3, plastic).
  Object frame: origin at the polygon's centroid (centre of mass in xy), z = 0 at the plate's
  bottom face, z = thickness at its top face. Given vertices are **recentred** on the
  centroid: :class:`ObjectShape` (and so the JSON loader) shifts the polygon so that its
  centroid is the origin. An object's pose on a table is (x, y, yaw) of this frame in the world.
* Table: a planar polygon (concave allowed) in world xy (world frame: origin at the robot base
  mounting point, z up, x from the robot toward the tables); ``height`` is the world z of its
  top surface, ``slab_thickness`` (default 0.03 m) the thickness of the slab below it.
* JSON, in metres. Object: ``{"name": str, "vertices": [[x, y], ...],
  "holes": [[[x, y], ...], ...], "thickness": m}`` ("holes", "thickness" and "density"
  optional). Table: ``{"name": str, "vertices": [[x, y], ...], "height": m}``
  ("slab_thickness" optional). Vertices may be listed in either orientation. Any other key
  is an error that names the closest valid one (``OBJECT_KEYS``, ``TABLE_KEYS``).
* Bounds (ValueError outside them): object thickness in [``MIN_THICKNESS``,
  ``MAX_THICKNESS``] = [0.3 mm, 5 cm]; object size (:attr:`ObjectShape.size`, the largest
  distance between two outline points, after scaling) in [``MIN_SIZE``, ``MAX_SIZE``] =
  [2 cm, 50 cm]; table height in :data:`TABLE_HEIGHT_RANGE`; vertex coordinates within
  ``MAX_COORDINATE`` metres of the origin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import shapely
import shapely.affinity

from slide_gym.geometry.polygons import (
    convex_pieces,
    diameter,
    make_polygon,
    outline_descriptor,
    point_cloud,
)

DEFAULT_THICKNESS = 0.004  # m
DEFAULT_DENSITY = 1200.0  # kg/m^3 (plastic)
DEFAULT_SLAB_THICKNESS = 0.03  # m
MIN_THICKNESS = 0.0003  # m: a thin card
MAX_THICKNESS = 0.05  # m: a thick book; thicker is no longer a plate to slide
MIN_SIZE = 0.02  # m: a coin; the fingertip pad alone is 3.2 cm wide
MAX_SIZE = 0.5  # m: about the width of the arm's reach band on the tables (0.30-0.85 m)
MAX_COORDINATE = 1000.0
"""Largest |x| or |y| (m) accepted in a vertex list: anything beyond is a unit mistake (and
1e200 would overflow the area computations)."""


def _check_range(value: float, lo: float, hi: float, what: str, span: str) -> float:
    """``value`` as a float if it is a number within [lo, hi] (metres), else a ValueError
    that also spots millimetres given for metres."""
    v = _check_finite(value, what)
    if not lo <= v <= hi:
        hint = ""
        if lo <= v / 1000.0 <= hi:
            hint = f"; lengths are in metres: {v:g} mm is {v / 1000.0:g} m"
        raise ValueError(f"{what} must be within [{lo:g}, {hi:g}] m ({span}), got {value!r}{hint}")
    return v


def check_thickness(value: float, what: str = "thickness") -> float:
    """An object thickness (m) within [MIN_THICKNESS, MAX_THICKNESS], else a ValueError."""
    return _check_range(value, MIN_THICKNESS, MAX_THICKNESS, what, "0.3 mm to 5 cm")


def _check_finite(value: float, what: str) -> float:
    """``value`` as a float if it is a finite number, else a ValueError naming ``what``."""
    if isinstance(value, (str, bytes, bool)):
        raise ValueError(f"{what} must be a number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{what} must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"{what} must be finite, got {value!r}")
    return v


def _check_coordinates(rings: list[Any], what: str) -> None:
    """ValueError if any vertex coordinate is beyond ``MAX_COORDINATE`` (unit mistakes, and
    values near 1e200 that overflow later). Unparsable input is left to ``make_polygon``."""
    for ring in rings:
        try:
            pts = np.asarray(ring, dtype=float)
        except (TypeError, ValueError, OverflowError):
            continue
        finite = pts[np.isfinite(pts)] if pts.size else pts
        if finite.size and float(np.abs(finite).max()) > MAX_COORDINATE:
            raise ValueError(
                f"{what}: vertex coordinates must be metres within +-{MAX_COORDINATE:g} of the "
                f"origin, got {float(np.abs(finite).max()):g}"
            )


def _make_polygon(vertices: Any, holes: Any, what: str) -> shapely.Polygon:
    """:func:`make_polygon` after the coordinate check; numeric overflow becomes ValueError."""
    _check_coordinates([vertices, *holes], what)
    try:
        return make_polygon(vertices, holes, what=what)
    except (OverflowError, FloatingPointError) as exc:
        raise ValueError(f"{what}: vertex coordinates out of range ({exc})") from None


TABLE_HEIGHT_RANGE: tuple[float, float] = (-0.10, 0.05)
"""World z (m) of a table top that the robot can work on (the base is at z = 0, the shoulder
axes 0.346 m above it; the catalog tables are at 0). Measured with ``plan_once`` (square plate
on the square table, 8 seeds per height): every query solves from -0.15 to +0.5 m; at -0.2 m
most time out and at -0.4 m no start configuration exists. The lower bound keeps 0.1 m
from that failing edge. The upper bound comes from the environment's start: at
``READY_ARM_Q`` the open fingers' lowest point is 0.117 m above z = 0, so a table at 0.05 m
under the thickest allowed plate (5 cm) still leaves about 1.7 cm of clearance. The expert
(``run_episode``, square plate) lifted the plate at both ends: 2 of 2 episodes at -0.10 m,
4 of 5 at +0.05 m."""


def _check_positive(value: float, what: str) -> float:
    """Return ``value`` as a float if finite and > 0, else raise ValueError."""
    if isinstance(value, (str, bytes, bool)):
        raise ValueError(f"{what} must be a number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be a number, got {value!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"{what} must be finite and > 0, got {value!r}")
    return v


def _check_polygon(polygon: Any, what: str) -> shapely.Polygon:
    if not isinstance(polygon, shapely.Polygon) or polygon.is_empty:
        raise ValueError(f"{what}: polygon must be a non-empty shapely Polygon")
    if not polygon.is_valid:
        raise ValueError(f"{what}: invalid polygon ({shapely.is_valid_reason(polygon)})")
    _check_coordinates([shapely.get_coordinates(polygon)], what)
    return shapely.orient_polygons(polygon)


def _rings(polygon: shapely.Polygon) -> tuple[list[list[float]], list[list[list[float]]]]:
    """Exterior and holes as JSON lists without the repeated closing vertex."""
    ext = np.asarray(polygon.exterior.coords)[:-1].tolist()
    holes = [np.asarray(r.coords)[:-1].tolist() for r in polygon.interiors]
    return ext, holes


@dataclass(frozen=True)
class ObjectShape:
    """A thin plate: outline polygon in the object frame (recentred on its centroid)."""

    name: str
    polygon: shapely.Polygon
    thickness: float = DEFAULT_THICKNESS
    density: float = DEFAULT_DENSITY

    def __post_init__(self) -> None:
        what = f"object {self.name!r}"
        poly = _check_polygon(self.polygon, what)
        thickness = check_thickness(self.thickness, f"{what} thickness")
        object.__setattr__(self, "thickness", thickness)
        object.__setattr__(self, "density", _check_positive(self.density, f"{what} density"))
        size = diameter(poly)
        if not MIN_SIZE * (1 - 1e-9) <= size <= MAX_SIZE * (1 + 1e-9):
            raise ValueError(
                f"{what} is {_cm(size)} across (its largest extent), "
                f"{'smaller' if size < MIN_SIZE else 'larger'} than allowed: objects must be "
                f"{_cm(MIN_SIZE)} to {_cm(MAX_SIZE)} across (vertices are in metres)"
            )
        c = poly.centroid
        object.__setattr__(self, "polygon", shapely.affinity.translate(poly, -c.x, -c.y))

    @classmethod
    def from_vertices(
        cls,
        name: str,
        vertices: Any,
        holes: Any = (),
        thickness: float = DEFAULT_THICKNESS,
        density: float = DEFAULT_DENSITY,
    ) -> ObjectShape:
        """Validate an outline (and holes), recentre it on its centroid."""
        poly = _make_polygon(vertices, list(holes), what=f"object {name!r}")
        return cls(name, poly, thickness, density)

    @property
    def area(self) -> float:
        """Plate area in m^2."""
        return float(self.polygon.area)

    @property
    def mass(self) -> float:
        """Plate mass in kg."""
        return self.area * self.thickness * self.density

    @property
    def circumradius(self) -> float:
        """Largest distance of an outline vertex from the object-frame origin (m)."""
        ext = np.asarray(self.polygon.exterior.coords)
        return float(np.linalg.norm(ext, axis=1).max())

    def can_overhang(self, u_star: float, centroid_margin: float = 0.0) -> bool:
        """Whether some pose overhangs a straight table edge by ``u_star`` (m) with the
        centroid at least ``centroid_margin`` (m) inside it: the farthest outline point faces
        the edge, so the test is ``circumradius - centroid_margin >= u_star``. Pure geometry
        (no table, no reach); the planner answers ``infeasible`` when it fails."""
        return self.circumradius - float(centroid_margin) >= float(u_star)

    @property
    def size(self) -> float:
        """Largest distance between two points of the outline (m): the plate's largest
        extent, whatever its orientation. Bounded by ``MIN_SIZE`` and ``MAX_SIZE``."""
        return diameter(self.polygon)

    @property
    def max_extent(self) -> float:
        """Largest side of the axis-aligned bounding box (m)."""
        minx, miny, maxx, maxy = self.polygon.bounds
        return float(max(maxx - minx, maxy - miny))

    def scaled(self, s: float) -> ObjectShape:
        """Same plate with its outline scaled by ``s`` about the centroid (thickness kept).

        The scaled size must stay within [``MIN_SIZE``, ``MAX_SIZE``]; the ValueError says
        which scales this object allows."""
        s = _check_positive(s, "scale")
        if s == 1.0:
            return self
        size = self.size
        lo, hi = MIN_SIZE / size, MAX_SIZE / size
        if not lo * (1 - 1e-9) <= s <= hi * (1 + 1e-9):
            raise ValueError(
                f"scale {s:g} makes object {self.name!r} {_cm(s * size)} across, "
                f"{'smaller' if s < lo else 'larger'} than allowed ({_cm(MIN_SIZE)} to "
                f"{_cm(MAX_SIZE)}): scale must be within [{lo:.3g}, {hi:.3g}] for this object"
            )
        poly = shapely.affinity.scale(self.polygon, s, s, origin=(0.0, 0.0))
        return ObjectShape(self.name, poly, self.thickness, self.density)

    def convex_pieces(self) -> list[np.ndarray]:
        """Convex (k, 2) CCW pieces in the object frame whose union is the outline (cached)."""
        return convex_pieces(self.polygon)

    def top_surface_points(self, spacing: float) -> np.ndarray:
        """(N, 3) grid points on the top face (z = thickness) in the object frame."""
        xy = point_cloud(self.polygon, spacing)
        return np.column_stack([xy, np.full(len(xy), self.thickness)])

    def descriptor(self, n: int = 32) -> np.ndarray:
        """(n, 2) outline points evenly spaced by arc length, in the object frame."""
        return outline_descriptor(self.polygon, n)

    def to_json(self) -> dict[str, Any]:
        """The JSON object described in the module docstring (recentred vertices)."""
        ext, holes = _rings(self.polygon)
        return {
            "name": self.name,
            "vertices": ext,
            "holes": holes,
            "thickness": self.thickness,
            "density": self.density,
        }


@dataclass(frozen=True)
class TableShape:
    """A table top: polygon in world xy, top surface at world z = ``height``."""

    name: str
    polygon: shapely.Polygon
    height: float = 0.0
    slab_thickness: float = DEFAULT_SLAB_THICKNESS

    def __post_init__(self) -> None:
        what = f"table {self.name!r}"
        object.__setattr__(self, "polygon", _check_polygon(self.polygon, what))
        try:
            if isinstance(self.height, (str, bytes, bool)):
                raise TypeError
            height = float(self.height)
        except (TypeError, ValueError):
            raise ValueError(f"{what} height must be a number, got {self.height!r}") from None
        if not math.isfinite(height):
            raise ValueError(f"{what} height must be finite, got {self.height!r}")
        lo, hi = TABLE_HEIGHT_RANGE
        if not lo - 1e-6 <= height <= hi + 1e-6:  # a float32 observation of a bound passes
            raise ValueError(
                f"{what} height {height:g} m is out of the arm's reach: a table top must be at "
                f"world z {lo:g} to {hi:g} m (the robot base is at z = 0, its shoulder 0.346 m "
                f"above it)"
            )
        object.__setattr__(self, "height", height)
        slab = _check_positive(self.slab_thickness, f"{what} slab_thickness")
        object.__setattr__(self, "slab_thickness", slab)

    @classmethod
    def from_vertices(
        cls,
        name: str,
        vertices: Any,
        height: float = 0.0,
        slab_thickness: float = DEFAULT_SLAB_THICKNESS,
    ) -> TableShape:
        """Validate a world-xy outline."""
        poly = _make_polygon(vertices, [], what=f"table {name!r}")
        return cls(name, poly, height, slab_thickness)

    @property
    def area(self) -> float:
        """Top area in m^2."""
        return float(self.polygon.area)

    def convex_pieces(self) -> list[np.ndarray]:
        """Convex (k, 2) CCW pieces in world xy whose union is the top (cached)."""
        return convex_pieces(self.polygon)

    def descriptor(self, n: int = 64) -> np.ndarray:
        """(n, 2) world-xy outline points evenly spaced by arc length."""
        return outline_descriptor(self.polygon, n)

    def to_json(self) -> dict[str, Any]:
        """The JSON object described in the module docstring."""
        ext, _ = _rings(self.polygon)
        return {
            "name": self.name,
            "vertices": ext,
            "height": self.height,
            "slab_thickness": self.slab_thickness,
        }


def _cm(metres: float) -> str:
    """A length for messages: centimetres with 3 significant digits."""
    return f"{metres * 100:.3g} cm"
