"""Planar geometry of slide-gym: plate objects, tables, convex pieces and overhang.

World frame: origin at the robot base mounting point, z up, x from the robot toward the
tables. Object frame: origin at the plate polygon's centroid, z = 0 at its bottom face
(loaded vertices are recentred on the centroid). See :mod:`slide_gym.geometry.shapes` for
the JSON formats and :mod:`slide_gym.geometry.polygons` for the overhang definition.
"""

from slide_gym.geometry.catalog import (
    OBJECT_NAMES,
    OBJECTS,
    TABLE_NAMES,
    TABLES,
    catalog_summary,
    get_object,
    get_table,
)
from slide_gym.geometry.polygons import (
    Overhang,
    convex_pieces,
    diameter,
    is_graspable,
    make_polygon,
    outline_descriptor,
    overhang,
    point_cloud,
    quat_yaw,
    transform_points,
    transform_polygon,
    wrap_angle,
)
from slide_gym.geometry.shape_json import (
    OBJECT_KEYS,
    TABLE_KEYS,
    load_object_json,
    load_table_json,
)
from slide_gym.geometry.shapes import (
    DEFAULT_DENSITY,
    DEFAULT_SLAB_THICKNESS,
    DEFAULT_THICKNESS,
    MAX_SIZE,
    MAX_THICKNESS,
    MIN_SIZE,
    MIN_THICKNESS,
    TABLE_HEIGHT_RANGE,
    ObjectShape,
    TableShape,
)

__all__ = [
    "DEFAULT_DENSITY",
    "DEFAULT_SLAB_THICKNESS",
    "DEFAULT_THICKNESS",
    "MAX_SIZE",
    "MAX_THICKNESS",
    "MIN_SIZE",
    "MIN_THICKNESS",
    "OBJECT_KEYS",
    "TABLE_HEIGHT_RANGE",
    "TABLE_KEYS",
    "OBJECTS",
    "OBJECT_NAMES",
    "TABLES",
    "TABLE_NAMES",
    "ObjectShape",
    "Overhang",
    "TableShape",
    "catalog_summary",
    "convex_pieces",
    "diameter",
    "get_object",
    "get_table",
    "is_graspable",
    "load_object_json",
    "load_table_json",
    "make_polygon",
    "outline_descriptor",
    "overhang",
    "point_cloud",
    "quat_yaw",
    "transform_points",
    "wrap_angle",
    "transform_polygon",
]
