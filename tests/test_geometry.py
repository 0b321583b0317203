"""Tests of slide_gym.geometry: catalog, convex pieces, point clouds, overhang, JSON, errors."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import shapely

from slide_gym.geometry import (
    OBJECT_NAMES,
    OBJECTS,
    TABLE_NAMES,
    TABLES,
    ObjectShape,
    TableShape,
    catalog_summary,
    convex_pieces,
    get_object,
    get_table,
    is_graspable,
    load_object_json,
    load_table_json,
    make_polygon,
    outline_descriptor,
    overhang,
    point_cloud,
    transform_points,
    transform_polygon,
)

ALL_SHAPES = [OBJECTS[n] for n in OBJECT_NAMES] + [TABLES[n] for n in TABLE_NAMES]
CONCAVE = ["crescent", "irregular", "Y", "A", "L", "E"]


def _is_ccw_convex(pts: np.ndarray) -> bool:
    e = np.roll(pts, -1, axis=0) - pts
    ep = np.roll(e, 1, axis=0)
    return bool(np.all(ep[:, 0] * e[:, 1] - ep[:, 1] * e[:, 0] > -1e-12))


def test_catalog_names_and_sizes() -> None:
    assert set(OBJECT_NAMES) == {"square", "circle", "triangle", "crescent", "irregular"} | {
        "Y", "A", "L", "E",
    }  # fmt: skip
    assert set(TABLE_NAMES) == {"square", "round", "long", "triangle"}
    for obj in OBJECTS.values():
        assert obj.polygon.is_valid and obj.polygon.exterior.is_ccw
        assert 0.08 <= obj.max_extent <= 0.12, obj.name
        c = obj.polygon.centroid
        assert abs(c.x) < 1e-12 and abs(c.y) < 1e-12, obj.name
        assert obj.thickness == 0.004 and obj.mass == pytest.approx(obj.area * 0.004 * 1200)
    assert len(OBJECTS["A"].polygon.interiors) == 1
    assert OBJECTS["square"].area == pytest.approx(0.01)
    assert OBJECTS["circle"].circumradius == pytest.approx(0.05)


def test_tables_placement() -> None:
    origin = shapely.Point(0.0, 0.0)
    for table in TABLES.values():
        minx, miny, maxx, maxy = table.polygon.bounds
        assert table.polygon.is_valid and table.height == 0.0
        assert table.polygon.distance(origin) >= 0.3, table.name
        assert max(abs(miny), abs(maxy)) <= 0.45 + 1e-12
        assert minx > 0.3 and maxx < 0.9
    assert TABLES["square"].area == pytest.approx(0.25)
    assert len(TABLES["round"].polygon.exterior.coords) == 101
    assert TABLES["long"].polygon.bounds == pytest.approx((0.45, -0.45, 0.70, 0.45))


@pytest.mark.parametrize("shape", ALL_SHAPES, ids=lambda s: f"{type(s).__name__}-{s.name}")
def test_convex_pieces_cover_exactly(shape: ObjectShape | TableShape) -> None:
    pieces = shape.convex_pieces()
    assert pieces and all(p.ndim == 2 and p.shape[1] == 2 and len(p) >= 3 for p in pieces)
    assert all(_is_ccw_convex(p) for p in pieces)
    union = shapely.union_all([shapely.Polygon(p) for p in pieces])
    assert union.symmetric_difference(shape.polygon).area < 1e-9
    assert sum(shapely.Polygon(p).area for p in pieces) == pytest.approx(shape.area, rel=1e-9)
    if shape.polygon.equals(shape.polygon.convex_hull):
        assert len(pieces) == 1


@pytest.mark.parametrize("name", CONCAVE)
def test_concave_pieces_are_not_the_hull(name: str) -> None:
    obj = OBJECTS[name]
    union = shapely.union_all([shapely.Polygon(p) for p in obj.convex_pieces()])
    assert union.area < 0.9 * obj.polygon.convex_hull.area
    assert 2 <= len(obj.convex_pieces()) <= 12


def test_convex_pieces_cached_and_letter_counts() -> None:
    a = convex_pieces(OBJECTS["E"].polygon)
    b = convex_pieces(OBJECTS["E"].polygon)
    assert a[0] is b[0] and not a[0].flags.writeable
    assert len(OBJECTS["L"].convex_pieces()) == 2
    assert len(OBJECTS["E"].convex_pieces()) <= 5


def test_point_cloud_inside_and_spaced() -> None:
    obj = OBJECTS["A"]
    pts = obj.top_surface_points(0.005)
    assert pts.shape[1] == 3 and len(pts) > 50 and np.allclose(pts[:, 2], obj.thickness)
    assert shapely.contains_xy(obj.polygon, pts[:, 0], pts[:, 1]).all()
    hole = shapely.Polygon(obj.polygon.interiors[0])
    assert not shapely.contains_xy(hole, pts[:, 0], pts[:, 1]).any()
    steps = np.diff(np.unique(pts[:, 0]))
    assert np.allclose(np.round(steps / 0.005), steps / 0.005) and steps.min() >= 0.005 - 1e-12
    coarse = point_cloud(OBJECTS["L"].polygon, 1.0)
    assert coarse.shape == (1, 2)
    assert shapely.contains_xy(OBJECTS["L"].polygon, coarse[:, 0], coarse[:, 1]).all()


def test_outline_descriptor() -> None:
    d = outline_descriptor(OBJECTS["square"].polygon, 8)
    assert d.shape == (8, 2)
    assert d[0] == pytest.approx([0.05, 0.0])
    assert d[1] == pytest.approx([0.05, 0.05])
    assert d[2] == pytest.approx([0.0, 0.05])
    gaps = np.linalg.norm(np.diff(np.vstack([d, d[:1]]), axis=0), axis=1)
    assert gaps == pytest.approx(np.full(8, 0.05))
    rotated = ObjectShape("r", transform_polygon(OBJECTS["E"].polygon, 0, 0, 0.3))
    assert rotated.descriptor().shape == (32, 2)
    assert TABLES["round"].descriptor().shape == (64, 2)


def test_overhang_hand_worked() -> None:
    table = TABLES["square"].polygon  # x in [0.35, 0.85], y in [-0.25, 0.25]
    square = OBJECTS["square"].polygon
    out = overhang(transform_polygon(square, 0.6, 0.23, 0.0), table)  # 3 cm past +y edge
    assert out.u == pytest.approx(0.03) and out.centroid_inside
    assert sorted(out.edge[:, 1]) == pytest.approx([0.25, 0.25])
    assert out.outside.area == pytest.approx(0.003)
    assert is_graspable(transform_polygon(square, 0.6, 0.23, 0.0), table, 0.025)
    assert not is_graspable(transform_polygon(square, 0.6, 0.23, 0.0), table, 0.035)
    # Rotated 45 deg with the centre 2 cm inside the +x edge: a corner sticks out by r - 0.02.
    rot = transform_polygon(square, 0.83, 0.0, math.pi / 4)
    out = overhang(rot, table)
    assert out.u == pytest.approx(0.05 * math.sqrt(2) - 0.02)
    assert sorted(out.edge[:, 0]) == pytest.approx([0.85, 0.85])
    inside = overhang(transform_polygon(square, 0.6, 0.0, 0.4), table)
    assert inside.u == 0.0 and inside.edge is None and inside.centroid_inside
    beyond = overhang(transform_polygon(square, 0.6, 0.27, 0.0), table)
    assert beyond.u == pytest.approx(0.07) and not beyond.centroid_inside
    assert not is_graspable(transform_polygon(square, 0.6, 0.27, 0.0), table, 0.03)


def test_overhang_is_the_depth_past_the_edge_line_on_the_round_table() -> None:
    table = TABLES["round"].polygon  # a 100-gon: edges of about 1.8 cm
    ring = shapely.get_coordinates(table.exterior)
    square = OBJECTS["square"].polygon  # 10 cm, wider than five edges
    for k in (0, 17, 42):
        a, b = ring[k], ring[k + 1]
        mid, along = (a + b) / 2, (b - a) / np.linalg.norm(b - a)
        normal = np.array([along[1], -along[0]])  # outward (the ring is counter-clockwise)
        # The square's outer side parallel to edge k, 2.5 cm past its line.
        centre = mid + (0.025 - 0.05) * normal
        out = overhang(transform_polygon(square, *centre, math.atan2(*normal[::-1])), table)
        np.testing.assert_allclose(out.edge, [a, b])
        # The distance to the short segment itself (its end points) would be about 5 cm.
        assert out.u == pytest.approx(0.025)
        # A convex table's edge line never cuts into it: no depth past the line exceeds the
        # depth past the table.
        corners = shapely.points(shapely.get_coordinates(out.outside))
        assert out.u <= shapely.distance(corners, table).max() + 1e-12


def test_overhang_near_a_corner_is_the_depth_past_one_edge() -> None:
    table = TABLES["square"].polygon  # x in [0.35, 0.85], y in [-0.25, 0.25]
    square = OBJECTS["square"].polygon  # 10 cm, sticking out 2 cm past +x and 1 cm past +y
    out = overhang(transform_polygon(square, 0.82, 0.21, 0.0), table)
    assert out.u == pytest.approx(0.02)
    assert sorted(out.edge[:, 0]) == pytest.approx([0.85, 0.85])


def test_se2_round_trip() -> None:
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(20, 2))
    x, y, yaw = 0.3, -0.2, 1.1
    moved = transform_points(pts, x, y, yaw)
    assert np.linalg.norm(moved[0] - (x, y)) == pytest.approx(np.linalg.norm(pts[0]))
    back = transform_points(transform_points(moved, -x, -y, 0.0), 0.0, 0.0, -yaw)
    assert back == pytest.approx(pts)
    poly = OBJECTS["A"].polygon
    there = transform_polygon(poly, x, y, yaw)
    assert there.area == pytest.approx(poly.area) and there.exterior.is_ccw
    again = transform_polygon(transform_polygon(there, -x, -y, 0.0), 0.0, 0.0, -yaw)
    assert again.symmetric_difference(poly).area < 1e-12


def test_json_round_trip(tmp_path) -> None:
    obj = get_object("A", scale=1.2)
    path = tmp_path / "a.json"
    path.write_text(json.dumps(obj.to_json()))
    loaded = get_object(str(path))
    assert loaded.name == "A" and loaded.thickness == obj.thickness
    assert loaded.polygon.symmetric_difference(obj.polygon).area < 1e-12
    table_path = tmp_path / "t.json"
    table_path.write_text(json.dumps(TABLES["triangle"].to_json()))
    assert get_table(table_path).polygon.equals(TABLES["triangle"].polygon)
    # Loader recentres and accepts clockwise vertices.
    raw = tmp_path / "raw.json"
    raw.write_text(json.dumps({"name": "b", "vertices": [[1, 1], [1, 1.1], [1.1, 1.1], [1.1, 1]]}))
    box = load_object_json(raw)
    assert box.polygon.bounds == pytest.approx((-0.05, -0.05, 0.05, 0.05))
    assert box.polygon.exterior.is_ccw and box.thickness == 0.004


def test_scaling_and_lookup() -> None:
    big = get_object("circle", 2.0)
    assert big.circumradius == pytest.approx(0.1) and big.thickness == 0.004
    assert get_object(big) is big and get_table(TABLES["long"]) is TABLES["long"]
    assert get_object(OBJECTS["L"], 0.5).area == pytest.approx(OBJECTS["L"].area / 4)
    rows = catalog_summary()
    assert len(rows) == len(OBJECT_NAMES) + len(TABLE_NAMES)
    a_row = next(r for r in rows if r["kind"] == "object" and r["name"] == "A")
    assert a_row["holes"] == 1 and a_row["convex_pieces"] == len(OBJECTS["A"].convex_pieces())


BAD_POLYGONS = [
    ([(0, 0), (1, 0)], "at least 3"),
    ([(0, 0), (1, 1), (1, 0), (0, 1)], "self-intersection"),
    ([(0, 0), (1, 0), (2, 0)], "zero"),
    ([(0, 0), (1, 0), (float("nan"), 1)], "finite"),
    ([(0, 0, 0), (1, 0, 0), (1, 1, 0)], "shape"),
    ([("a", 0), (1, 0), (1, 1)], "number"),
]


@pytest.mark.parametrize(("vertices", "word"), BAD_POLYGONS)
def test_bad_polygons(vertices, word: str) -> None:
    with pytest.raises(ValueError, match=word):
        make_polygon(vertices)


def test_bad_holes() -> None:
    outline = [(0, 0), (1, 0), (1, 1), (0, 1)]
    with pytest.raises(ValueError, match="inside"):
        make_polygon(outline, [[(0.5, 0.5), (1.5, 0.5), (1.5, 0.6)]])
    with pytest.raises(ValueError, match="overlap"):
        tri = [(0.2, 0.2), (0.6, 0.2), (0.4, 0.6)]
        make_polygon(outline, [tri, [(x + 0.1, y) for x, y in tri]])


def test_bad_values_and_specs(tmp_path) -> None:
    with pytest.raises(ValueError, match="valid names: square"):
        get_object("hexagon")
    with pytest.raises(ValueError, match=r"\.json"):
        get_table("kitchen")
    with pytest.raises(ValueError, match="thickness"):
        ObjectShape("x", shapely.box(0, 0, 0.1, 0.1), thickness=0.0)
    with pytest.raises(ValueError, match="density"):
        ObjectShape("x", shapely.box(0, 0, 0.1, 0.1), density=-1.0)
    with pytest.raises(ValueError, match="height"):
        TableShape("t", shapely.box(0, 0, 1, 1), height=float("nan"))
    for scale in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="scale"):
            get_object("square", scale)
    missing = tmp_path / "m.json"
    missing.write_text(json.dumps({"name": "m", "vertices": [[0, 0], [1, 0], [0, 1]]}))
    with pytest.raises(ValueError, match=r"m\.json.*missing key.*height"):
        load_table_json(missing)
    broken = tmp_path / "broken.json"
    broken.write_text("{not json")
    with pytest.raises(ValueError, match="not valid JSON"):
        load_object_json(broken)
    bad_type = tmp_path / "bad.json"
    bad_type.write_text(
        json.dumps({"name": "b", "vertices": [[0, 0], [1, 0], [0, 1]], "thickness": "thin"})
    )
    with pytest.raises(ValueError, match=r"bad\.json.*thickness"):
        load_object_json(bad_type)
    with pytest.raises(ValueError, match="not found"):
        get_object(tmp_path / "nope.json")
