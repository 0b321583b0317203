"""Planar polygon tools: validation, SE(2) transforms, convex pieces, descriptors, overhang.

Conventions (public contract):

* World frame: origin at the robot base mounting point, z up, x from the robot toward the
  tables. All lengths are metres, angles radians.
* Polygons are :class:`shapely.Polygon` with the exterior ring counter-clockwise and holes
  clockwise (:func:`make_polygon` normalises either input orientation).
* A pose ``(x, y, yaw)`` maps a local point ``p`` to ``R(yaw) @ p + (x, y)``.
* Overhang (the paper's definition): ``P_out = object - table``; the table edge is the segment
  of the table's exterior ring closest to ``P_out``'s centroid, and ``u`` is how deep ``P_out``
  reaches past that edge's *line*: the largest signed distance of a vertex of ``P_out`` beyond
  the line, along the edge's outward normal (0 when ``P_out`` is empty). Measuring to the line
  and not to the segment matters on tables with short edges (a many-sided round table) and
  near corners, where the distance to a segment's end point overstates the depth.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

ArrayLike2 = Sequence[Sequence[float]] | np.ndarray
_EMPTY_AREA = 1e-12  # m^2; differences smaller than this are numerical slivers


def _ring_array(vertices: ArrayLike2, what: str) -> np.ndarray:
    """Parse one ring as an (N, 2) finite float array without the repeated closing vertex."""
    try:
        pts = np.asarray(vertices, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(
            f"{what}: vertices must be a list of [x, y] number pairs ({exc})"
        ) from None
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(
            f"{what}: vertices must have shape (N, 2) as [[x, y], ...], got shape {pts.shape}"
        )
    if not np.isfinite(pts).all():
        raise ValueError(f"{what}: vertices must be finite numbers (found NaN or inf)")
    if len(pts) > 1 and np.array_equal(pts[0], pts[-1]):
        pts = pts[:-1]
    if len(np.unique(pts, axis=0)) < 3:
        raise ValueError(f"{what}: a polygon needs at least 3 distinct vertices, got {len(pts)}")
    return pts


def _ring_polygon(pts: np.ndarray, what: str) -> shapely.Polygon:
    """A simple, non-degenerate polygon from one ring, or a ValueError saying why not."""
    poly = shapely.Polygon(pts)
    span = float(np.ptp(pts, axis=0).max())
    min_area = max(1e-14, 1e-6 * span**2)
    if poly.convex_hull.area < min_area:
        raise ValueError(f"{what}: zero or near-zero area (vertices are collinear or coincident)")
    if not poly.is_valid:
        raise ValueError(
            f"{what}: the outline must be a simple polygon without self-intersection "
            f"({shapely.is_valid_reason(poly)}); list vertices in order around the boundary"
        )
    if poly.area < min_area:
        raise ValueError(f"{what}: zero or near-zero area ({poly.area:.3g} m^2)")
    return poly


def make_polygon(
    vertices: ArrayLike2, holes: Iterable[ArrayLike2] = (), what: str = "object"
) -> shapely.Polygon:
    """Validate an outline (and holes) and return a polygon with CCW exterior, CW holes.

    Either orientation is accepted; concave outlines and holes strictly inside it are allowed.
    Raises ValueError naming ``what`` and the problem.
    """
    shell = _ring_polygon(_ring_array(vertices, what), what)
    hole_polys = []
    for i, hole in enumerate(holes):
        label = f"{what} hole {i}"
        hp = _ring_polygon(_ring_array(hole, label), label)
        if not shell.contains(hp):
            raise ValueError(f"{label}: holes must lie strictly inside the outline")
        for j, other in enumerate(hole_polys):
            if hp.intersects(other):
                raise ValueError(f"{label}: overlaps or touches hole {j}; holes must be disjoint")
        hole_polys.append(hp)
    poly = shapely.Polygon(
        shell.exterior.coords, [np.asarray(h.exterior.coords) for h in hole_polys]
    )
    if not poly.is_valid:
        raise ValueError(f"{what}: invalid polygon ({shapely.is_valid_reason(poly)})")
    return shapely.orient_polygons(poly)


def _rotation(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s], [s, c]])


def quat_yaw(quat: np.ndarray) -> float:
    """Yaw (rad) of an xyzw quaternion: the heading of a body lying flat."""
    x, y, z, w = (float(v) for v in quat)
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def wrap_angle(a: float) -> float:
    """``a`` wrapped to [-pi, pi)."""
    return (a + math.pi) % (2 * math.pi) - math.pi


def transform_points(points: np.ndarray, x: float, y: float, yaw: float) -> np.ndarray:
    """Apply the SE(2) pose (x, y, yaw) to an (N, 2) array of points."""
    pts = np.asarray(points, dtype=float)
    return pts @ _rotation(yaw).T + np.array([x, y])


def transform_polygon(poly: BaseGeometry, x: float, y: float, yaw: float) -> BaseGeometry:
    """Apply the SE(2) pose (x, y, yaw) to a shapely geometry (orientation is preserved)."""
    return shapely.transform(poly, lambda pts: transform_points(pts, x, y, yaw))


def _is_convex(pts: np.ndarray, tol: float = 1e-9) -> bool:
    """True if the CCW cycle ``pts`` has no right turn (sine of turn angle below -tol)."""
    e = np.roll(pts, -1, axis=0) - pts
    e_prev = np.roll(e, 1, axis=0)
    cross = e_prev[:, 0] * e[:, 1] - e_prev[:, 1] * e[:, 0]
    norms = np.linalg.norm(e_prev, axis=1) * np.linalg.norm(e, axis=1)
    return bool(np.all(cross >= -tol * norms))


def _drop_collinear(pts: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Remove vertices where the boundary goes straight on."""
    e = np.roll(pts, -1, axis=0) - pts
    e_prev = np.roll(e, 1, axis=0)
    cross = e_prev[:, 0] * e[:, 1] - e_prev[:, 1] * e[:, 0]
    norms = np.linalg.norm(e_prev, axis=1) * np.linalg.norm(e, axis=1)
    keep = np.abs(cross) > tol * norms
    return pts[keep] if keep.sum() >= 3 else pts


def _merge_cycles(p: list[int], q: list[int], a: int, b: int) -> list[int]:
    """Join CCW cycles p (holding edge a->b) and q (holding b->a) along that edge."""
    i = p.index(b)
    p_rot = p[i:] + p[:i]  # starts at b, ends at a
    j = q.index(a)
    q_rot = q[j:] + q[:j]  # starts at a, ends at b
    return p_rot + q_rot[1:-1]


@lru_cache(maxsize=256)
def _convex_pieces_cached(wkb: bytes) -> tuple[np.ndarray, ...]:
    poly = shapely.from_wkb(wkb)
    tris = shapely.get_parts(shapely.constrained_delaunay_triangles(poly))
    index: dict[tuple[float, float], int] = {}
    coords: list[tuple[float, float]] = []
    pieces: dict[int, list[int]] = {}
    for k, tri in enumerate(tris):
        cyc = []
        for xy in shapely.get_coordinates(tri)[:3]:
            key = (float(xy[0]), float(xy[1]))
            if key not in index:
                index[key] = len(coords)
                coords.append(key)
            cyc.append(index[key])
        (ax, ay), (bx, by), (cx, cy) = (coords[i] for i in cyc)
        if (bx - ax) * (cy - ay) - (by - ay) * (cx - ax) < 0:
            cyc.reverse()
        pieces[k] = cyc
    pts = np.array(coords)
    owner = {(c[i], c[(i + 1) % 3]): k for k, c in pieces.items() for i in range(3)}
    # Hertel-Mehlhorn: remove inner diagonals, longest first, while the union stays convex.
    diagonals = sorted(
        {(a, b) for (a, b) in owner if (b, a) in owner and a < b},
        key=lambda e: -float(np.linalg.norm(pts[e[0]] - pts[e[1]])),
    )
    for a, b in diagonals:
        kp, kq = owner.get((a, b)), owner.get((b, a))
        if kp is None or kq is None or kp == kq:
            continue
        merged = _merge_cycles(pieces[kp], pieces[kq], a, b)
        if not _is_convex(pts[merged]):
            continue
        for i, v in enumerate(pieces[kq]):
            owner[(v, pieces[kq][(i + 1) % len(pieces[kq])])] = kp
        del owner[(a, b)], owner[(b, a)], pieces[kq]
        pieces[kp] = merged
    out = []
    for cyc in pieces.values():
        piece = _drop_collinear(pts[cyc])
        if shapely.area(shapely.Polygon(piece)) > _EMPTY_AREA * 1e-3:
            piece.setflags(write=False)
            out.append(piece)
    return tuple(out)


def convex_pieces(poly: shapely.Polygon) -> list[np.ndarray]:
    """Split a polygon (concave, with holes) into convex pieces whose union is the polygon.

    Constrained Delaunay triangulation followed by greedy Hertel-Mehlhorn merging, so a
    convex polygon gives one piece. Each piece is a read-only (k, 2) CCW array without the
    repeated closing vertex. Results are cached per polygon.
    """
    return list(_convex_pieces_cached(shapely.to_wkb(poly)))


def _start_point(ring: shapely.LinearRing, origin: shapely.Point) -> shapely.Point:
    """Canonical start: outermost crossing of the ray origin -> +x with the ring."""
    minx, miny, maxx, maxy = ring.bounds
    reach = 2.0 * (maxx - minx + maxy - miny) + 1.0
    ray = shapely.LineString([(origin.x, origin.y), (origin.x + reach, origin.y)])
    hit = shapely.get_coordinates(ring.intersection(ray))
    if len(hit):
        return shapely.Point(hit[np.argmax(hit[:, 0])])
    return shapely.Point(shapely.get_coordinates(shapely.shortest_line(ring, ray))[0])


def outline_descriptor(poly: shapely.Polygon, n: int) -> np.ndarray:
    """(n, 2) points evenly spaced by arc length along the exterior ring, CCW.

    The first point is where the ray from the centroid along +x last crosses the ring (the
    ring point nearest that ray if it misses). Coordinates are in the polygon's own frame.
    """
    if n < 1:
        raise ValueError(f"descriptor size n must be >= 1, got {n}")
    ring = shapely.orient_polygons(poly).exterior
    start = ring.project(_start_point(ring, poly.centroid))
    dist = (start + ring.length * np.arange(n) / n) % ring.length
    return shapely.get_coordinates(shapely.line_interpolate_point(ring, dist))


def point_cloud(poly: shapely.Polygon, spacing: float) -> np.ndarray:
    """(N, 2) points of a square grid of the given spacing, centred on the bounding box,
    lying inside the polygon (not in holes). Falls back to the representative point."""
    if not (np.isfinite(spacing) and spacing > 0):
        raise ValueError(f"point-cloud spacing must be finite and > 0, got {spacing}")
    minx, miny, maxx, maxy = poly.bounds
    axes = []
    for lo, hi in ((minx, maxx), (miny, maxy)):
        count = int(np.floor((hi - lo) / spacing)) + 1
        axes.append(0.5 * (lo + hi) + (np.arange(count) - 0.5 * (count - 1)) * spacing)
    gx, gy = (g.ravel() for g in np.meshgrid(*axes))
    inside = shapely.contains_xy(poly, gx, gy)
    if not inside.any():
        return shapely.get_coordinates(poly.representative_point())
    return np.column_stack([gx[inside], gy[inside]])


@dataclass(frozen=True, eq=False)
class Overhang:
    """How far an object sticks out over a table edge."""

    u: float  # metres beyond the edge (0 if fully on the table)
    edge: np.ndarray | None  # (2, 2) table edge segment, or None when u == 0
    outside: BaseGeometry  # object part outside the table
    centroid_inside: bool  # object's centroid over the table

    def graspable(self, u_star: float) -> bool:
        """Enough overhang for a side grasp, and the centroid still over the table."""
        return self.u >= u_star and self.centroid_inside


def _ring_segments(ring: shapely.LinearRing) -> np.ndarray:
    """(M, 2, 2) consecutive segments of a ring."""
    c = shapely.get_coordinates(ring)
    return np.stack([c[:-1], c[1:]], axis=1)


def overhang(object_world: shapely.Polygon, table: shapely.Polygon) -> Overhang:
    """Overhang of an object (in world xy) over a table polygon; see the module docstring."""
    c = object_world.centroid
    centroid_inside = bool(shapely.contains_xy(table, c.x, c.y))
    outside = object_world.difference(table)
    if outside.is_empty or outside.area < _EMPTY_AREA:
        return Overhang(0.0, None, outside, centroid_inside)
    segments = _ring_segments(table.exterior)
    k = int(np.argmin(shapely.distance(outside.centroid, shapely.linestrings(segments))))
    (ax, ay), (bx, by) = segments[k]
    length = math.hypot(bx - ax, by - ay)
    normal = np.array([by - ay, ax - bx]) / length  # outward: the exterior ring is CCW
    depth = (shapely.get_coordinates(outside) - (ax, ay)) @ normal
    return Overhang(max(0.0, float(depth.max())), segments[k].copy(), outside, centroid_inside)


def is_graspable(object_world: shapely.Polygon, table: shapely.Polygon, u_star: float) -> bool:
    """True if the overhang is at least ``u_star`` and the object's centroid is on the table."""
    return overhang(object_world, table).graspable(u_star)


def diameter(poly: BaseGeometry) -> float:
    """Largest distance (m) between two points of ``poly``: its size across (the convex hull's
    diameter)."""
    minx, miny, maxx, maxy = poly.bounds
    box = max(maxx - minx, maxy - miny)
    if not math.isfinite(box) or box > 100.0:
        return box  # far too large for anything here; avoid squaring huge numbers
    hull = np.asarray(poly.convex_hull.exterior.coords)[:-1]
    best = 0.0
    for start in range(0, len(hull), 256):
        d = hull[start : start + 256, None, :] - hull[None, :, :]
        best = max(best, float(np.sqrt((d**2).sum(axis=2)).max()))
    return best
