"""Built-in objects and tables, and look-up by name, JSON path or instance.

Objects (plates ~8-12 cm across, 4 mm thick, plastic, recentred on their centroid):
``square`` (10 cm side), ``circle`` (10 cm diameter, 64-gon), ``triangle`` (equilateral,
11 cm side), ``crescent`` (10 cm 48-gon minus an offset 24-gon disc), ``irregular`` (fixed concave
9-gon), block letters ``Y``, ``A`` (with a triangular hole), ``L``, ``E`` (stroke ~2.5 cm).

Tables (world frame: origin at the robot base, x toward the tables; top at z = 0.0):
``square`` 0.5 x 0.5 m centred at (0.6, 0); ``round`` radius 0.28 m centred at (0.6, 0)
(100-gon); ``long`` x in [0.45, 0.70], y in [-0.45, 0.45]; ``triangle`` with corners
(0.35, -0.32), (0.35, 0.32), (0.85, 0.0). No table comes within 0.3 m of the origin.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import shapely

from slide_gym.geometry.shape_json import closest, load_object_json, load_table_json
from slide_gym.geometry.shapes import ObjectShape, TableShape


def _ngon(radius: float, n: int, cx: float = 0.0, cy: float = 0.0) -> np.ndarray:
    """Regular n-gon vertices (CCW) on a circle."""
    t = 2.0 * np.pi * np.arange(n) / n
    return np.column_stack([cx + radius * np.cos(t), cy + radius * np.sin(t)])


def _crescent() -> ObjectShape:
    outer = shapely.Polygon(_ngon(0.05, 48))
    inner = shapely.Polygon(_ngon(0.042, 24, cx=0.03))  # coarse: fewer convex pieces
    return ObjectShape("crescent", outer.difference(inner))


def _letter_a() -> ObjectShape:
    """Block A: 11 cm tall, 11 cm wide at the base, crossbar and a triangular hole."""
    h, b, t, w = 0.11, 0.055, 0.012, 0.026  # height, half base, half top, horizontal stroke

    def inner_x(y: float) -> float:  # x of the left leg's inner edge at height y
        return -b + (b - t) * y / h + w

    x0, x1 = inner_x(0.0), inner_x(0.03)
    apex = h * (b - w) / (b - t)
    outline = [
        (-b, 0.0), (x0, 0.0), (x1, 0.03), (-x1, 0.03), (-x0, 0.0), (b, 0.0), (t, h), (-t, h),
    ]  # fmt: skip
    xh = inner_x(0.05)
    hole = [(xh, 0.05), (-xh, 0.05), (0.0, apex)]
    return ObjectShape.from_vertices("A", outline, [hole])


def _build_objects() -> dict[str, ObjectShape]:
    side = 0.11
    tri = [(0.0, 0.0), (side, 0.0), (side / 2, side * math.sqrt(3) / 2)]
    irregular = [
        (0.05, -0.01), (0.035, 0.04), (0.005, 0.02), (-0.02, 0.045), (-0.05, 0.015),
        (-0.035, -0.015), (-0.045, -0.045), (0.0, -0.03), (0.025, -0.05),
    ]  # fmt: skip
    letter_y = [
        (-0.0125, -0.05), (0.0125, -0.05), (0.0125, -0.005), (0.05, 0.05), (0.02, 0.05),
        (0.0, 0.02), (-0.02, 0.05), (-0.05, 0.05), (-0.0125, -0.005),
    ]  # fmt: skip
    letter_l = [(0, 0), (0.07, 0), (0.07, 0.025), (0.025, 0.025), (0.025, 0.10), (0, 0.10)]
    letter_e = [
        (0, 0), (0.07, 0), (0.07, 0.025), (0.025, 0.025), (0.025, 0.0425), (0.06, 0.0425),
        (0.06, 0.0675), (0.025, 0.0675), (0.025, 0.085), (0.07, 0.085), (0.07, 0.11), (0, 0.11),
    ]  # fmt: skip
    shapes = [
        ObjectShape("square", shapely.box(-0.05, -0.05, 0.05, 0.05)),
        ObjectShape.from_vertices("circle", _ngon(0.05, 64)),
        ObjectShape.from_vertices("triangle", tri),
        _crescent(),
        ObjectShape.from_vertices("irregular", irregular),
        ObjectShape.from_vertices("Y", letter_y),
        _letter_a(),
        ObjectShape.from_vertices("L", letter_l),
        ObjectShape.from_vertices("E", letter_e),
    ]
    return {s.name: s for s in shapes}


def _build_tables() -> dict[str, TableShape]:
    tables = [
        TableShape("square", shapely.box(0.35, -0.25, 0.85, 0.25)),
        TableShape.from_vertices("round", _ngon(0.28, 100, cx=0.6)),
        TableShape("long", shapely.box(0.45, -0.45, 0.70, 0.45)),
        TableShape.from_vertices("triangle", [(0.35, -0.32), (0.35, 0.32), (0.85, 0.0)]),
    ]
    return {t.name: t for t in tables}


OBJECTS: dict[str, ObjectShape] = _build_objects()
TABLES: dict[str, TableShape] = _build_tables()
OBJECT_NAMES: tuple[str, ...] = tuple(OBJECTS)
TABLE_NAMES: tuple[str, ...] = tuple(TABLES)


def _check_scale(scale: float) -> float:
    if isinstance(scale, bool) or not isinstance(scale, (int, float, np.number)):
        raise ValueError(f"scale must be a number, got {scale!r}")
    if not (math.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be finite and > 0, got {scale!r}")
    return float(scale)


def unknown_name(kind: str, spec: str, names: Sequence[str]) -> ValueError:
    """The error for an unknown ``kind`` name: the closest of ``names`` and all of them."""
    near = closest(spec, tuple(names))
    hint = f"did you mean {near!r}? " if near is not None else ""
    return ValueError(
        f"unknown {kind} {spec!r}; {hint}valid names: {', '.join(names)} "
        "(or a path to a .json file)"
    )


def _is_path(spec: str | Path) -> bool:
    return isinstance(spec, Path) or str(spec).lower().endswith(".json")


def get_object(spec: str | Path | ObjectShape, scale: float = 1.0) -> ObjectShape:
    """An object from a catalog name, a ``.json`` path or an instance, scaled by ``scale``."""
    scale = _check_scale(scale)
    if isinstance(spec, ObjectShape):
        shape = spec
    elif isinstance(spec, str) and spec in OBJECTS:
        shape = OBJECTS[spec]
    elif isinstance(spec, (str, Path)) and _is_path(spec):
        shape = load_object_json(spec)
    elif isinstance(spec, str):
        raise unknown_name("object", spec, OBJECT_NAMES)
    else:
        raise ValueError(f"object spec must be a name, a .json path or an ObjectShape: {spec!r}")
    return shape.scaled(scale)


def get_table(spec: str | Path | TableShape) -> TableShape:
    """A table from a catalog name, a ``.json`` path or an instance."""
    if isinstance(spec, TableShape):
        return spec
    if isinstance(spec, str) and spec in TABLES:
        return TABLES[spec]
    if isinstance(spec, (str, Path)) and _is_path(spec):
        return load_table_json(spec)
    if isinstance(spec, str):
        raise unknown_name("table", spec, TABLE_NAMES)
    raise ValueError(f"table spec must be a name, a .json path or a TableShape: {spec!r}")


def catalog_summary() -> list[dict[str, Any]]:
    """One dict per built-in shape: kind, name, vertex and hole counts, thickness or height,
    area (m^2) and number of convex pieces."""
    rows: list[dict[str, Any]] = []
    for obj in OBJECTS.values():
        rows.append({
            "kind": "object",
            "name": obj.name,
            "vertices": len(obj.polygon.exterior.coords) - 1,
            "holes": len(obj.polygon.interiors),
            "thickness": obj.thickness,
            "area": obj.area,
            "convex_pieces": len(obj.convex_pieces()),
        })  # fmt: skip
    for table in TABLES.values():
        rows.append({
            "kind": "table",
            "name": table.name,
            "vertices": len(table.polygon.exterior.coords) - 1,
            "holes": len(table.polygon.interiors),
            "height": table.height,
            "area": table.area,
            "convex_pieces": len(table.convex_pieces()),
        })  # fmt: skip
    return rows
