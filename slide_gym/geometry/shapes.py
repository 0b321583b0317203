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
  ("slab_thickness" optional). Vertices may be listed in either orientation.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import shapely
import shapely.affinity

from slide_gym.geometry.polygons import (
    convex_pieces,
    make_polygon,
    outline_descriptor,
    point_cloud,
)

DEFAULT_THICKNESS = 0.004  # m
DEFAULT_DENSITY = 1200.0  # kg/m^3 (plastic)
DEFAULT_SLAB_THICKNESS = 0.03  # m


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
        poly = _check_polygon(self.polygon, f"object {self.name!r}")
        c = poly.centroid
        poly = shapely.affinity.translate(poly, -c.x, -c.y)
        object.__setattr__(self, "polygon", poly)
        what = f"object {self.name!r}"
        object.__setattr__(self, "thickness", _check_positive(self.thickness, f"{what} thickness"))
        object.__setattr__(self, "density", _check_positive(self.density, f"{what} density"))

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
        poly = make_polygon(vertices, holes, what=f"object {name!r}")
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

    @property
    def max_extent(self) -> float:
        """Largest side of the axis-aligned bounding box (m)."""
        minx, miny, maxx, maxy = self.polygon.bounds
        return float(max(maxx - minx, maxy - miny))

    def scaled(self, s: float) -> ObjectShape:
        """Same plate with its outline scaled by ``s`` about the centroid (thickness kept)."""
        s = _check_positive(s, "scale")
        if s == 1.0:
            return self
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
        return cls(name, make_polygon(vertices, what=f"table {name!r}"), height, slab_thickness)

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


def _read_json(path: str | Path, required: tuple[str, ...]) -> tuple[Path, dict[str, Any]]:
    """Read a JSON object with the required keys; ValueError naming the file otherwise."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise ValueError(f"{path}: file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot read file ({exc})") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a JSON object {{...}}, got {type(data).__name__}")
    missing = [k for k in required if k not in data]
    if missing:
        raise ValueError(f"{path}: missing key(s) {missing}; required keys are {list(required)}")
    if not isinstance(data["name"], str):
        raise ValueError(f"{path}: 'name' must be a string, got {data['name']!r}")
    if not isinstance(data["vertices"], list):
        raise ValueError(f"{path}: 'vertices' must be a list of [x, y] pairs")
    return path, data


def _wrap(path: Path, build: Any) -> Any:
    """Run ``build()`` and prefix any ValueError with the file name."""
    try:
        return build()
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def load_object_json(path: str | Path) -> ObjectShape:
    """Load an object from JSON (see module docstring); vertices are recentred."""
    path, data = _read_json(path, ("name", "vertices"))
    holes = data.get("holes", [])
    if not isinstance(holes, list):
        raise ValueError(f"{path}: 'holes' must be a list of vertex lists")
    return _wrap(
        path,
        lambda: ObjectShape.from_vertices(
            data["name"],
            data["vertices"],
            holes,
            data.get("thickness", DEFAULT_THICKNESS),
            data.get("density", DEFAULT_DENSITY),
        ),
    )


def load_table_json(path: str | Path) -> TableShape:
    """Load a table from JSON (see module docstring)."""
    path, data = _read_json(path, ("name", "vertices", "height"))
    return _wrap(
        path,
        lambda: TableShape.from_vertices(
            data["name"],
            data["vertices"],
            data["height"],
            data.get("slab_thickness", DEFAULT_SLAB_THICKNESS),
        ),
    )
