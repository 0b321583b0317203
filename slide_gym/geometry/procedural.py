"""Random thin plates that nobody tuned for: ``object="procedural"``.

:func:`procedural_object` draws one plate from an integer seed, so the same seed always gives
the same plate, on any machine. Three families, one third each:

* ``convex``: the hull of random points on an ellipse (triangles to dodecagons, discs);
* ``star``: a star-shaped outline of 16-48 vertices whose radius wobbles with a few
  harmonics (gear-like, blob-like, concave);
* ``blocks``: the union of two to four bars (letters such as L, T, E, H and zig-zags).

About a third of the plates get one or two holes (6- to 24-gons) that keep a wall of at least
8 mm around them. The size across (:func:`diameter`) is drawn log-uniformly from
:data:`SIZE_RANGE`, the width is at least :data:`MIN_WIDTH` (a fingertip must fit on the
plate) and the thickness is drawn log-uniformly from :data:`THICKNESS_RANGE`.

Admissible plates. ``object="procedural"`` (:func:`slide_gym.task.fit_procedural_object`)
only hands out plates the task admits: a plate must be able to overhang a straight table edge
by the hand's u* (2 cm) with its centroid at least 5 mm inside the edge, so its circumradius
(farthest outline point from the centroid) must be at least 2.5 cm
(:func:`slide_gym.task.plate_admissible`). Draw 0 of a seed that falls short (9 % of seeds,
all 4-5 cm across) is replaced by draw 1, 2, ... of the same seed (:func:`procedural_object`
with ``redraw``, rarely more than one), so seed ``s`` is always the same admissible plate,
still named ``procedural-<s>``; :func:`slide_gym.task.draw_procedural_plate` says how many
draws it took. Admitted plates are 4-30 cm across as before, but those under 5 cm only when
they are elongated enough (a disc needs 5 cm). With a ``scale`` the test applies to the
scaled plate, so smaller scales redraw more often. :func:`procedural_object` itself draws any
plate; user plates (catalog, JSON, shapes) are never redrawn.
"""

from __future__ import annotations

import math

import numpy as np
import shapely
import shapely.affinity
from shapely.ops import polylabel

from slide_gym.geometry.polygons import diameter
from slide_gym.geometry.shapes import ObjectShape

SIZE_RANGE = (0.04, 0.30)
"""Size across of a plate (m), drawn log-uniformly."""
THICKNESS_RANGE = (0.0005, 0.006)
"""Plate thickness (m), drawn log-uniformly."""
MIN_WIDTH = 0.025
"""Smallest width (m) of a plate (short side of its minimum rotated rectangle): a fingertip
pad must fit on it."""
MIN_INRADIUS = 0.01
"""Radius (m) of the largest disc inside a plate, at least: room for a pressed fingertip."""
HOLE_WALL = 0.008
"""Least material (m) between a hole and the outline or another hole."""
KINDS = ("convex", "star", "blocks")
_STREAM = 0x51DE  # keeps these draws apart from any other use of the same seed


def _log_uniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def _convex(rng: np.random.Generator, aspect: float) -> shapely.Polygon:
    if rng.random() < 0.2:  # a disc or an ellipse
        t = np.linspace(0.0, 2 * math.pi, 48, endpoint=False)
    else:
        t = np.sort(rng.uniform(0.0, 2 * math.pi, int(rng.integers(3, 13))))
    return shapely.MultiPoint(np.c_[np.cos(t), aspect * np.sin(t)]).convex_hull


def _star(rng: np.random.Generator, aspect: float) -> shapely.Polygon:
    aspect = max(aspect, 0.4)  # thinner stars are bundles of needles
    n = int(rng.integers(16, 49))
    t = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
    r = np.ones(n)
    for k in rng.choice(np.arange(2, 9), size=int(rng.integers(1, 4)), replace=False):
        r += rng.uniform(0.05, 0.3) * np.cos(k * t + rng.uniform(0.0, 2 * math.pi))
    r = np.maximum(r, 0.35)
    return shapely.Polygon(np.c_[r * np.cos(t), aspect * r * np.sin(t)])


def _blocks(rng: np.random.Generator, aspect: float) -> shapely.Polygon:
    """Bars of width ``aspect`` (the first spans the unit length) joined end to side."""
    w = max(aspect, 0.15)
    plate = shapely.box(0.0, 0.0, 1.0, w)
    for _ in range(int(rng.integers(1, 4))):
        length = rng.uniform(0.3, 1.0)
        x = rng.choice([0.0, 1.0 - w, rng.uniform(0.0, 1.0 - w)])
        up = rng.random() < 0.5
        bar = shapely.box(x, w if up else -length, x + w, w + length if up else 0.0)
        plate = plate.union(bar)
    return shapely.affinity.rotate(plate, 90.0 * int(rng.integers(4)), origin="centroid")


def _with_holes(rng: np.random.Generator, plate: shapely.Polygon) -> shapely.Polygon:
    holes: list[shapely.Polygon] = []
    for _ in range(int(rng.integers(1, 3))):
        room = plate.buffer(-HOLE_WALL)
        for other in holes:
            room = room.difference(other.buffer(HOLE_WALL))
        if room.is_empty:
            break
        if room.geom_type != "Polygon":
            room = max(room.geoms, key=lambda g: g.area)
        # About the largest circle that fits: centred on the pole of inaccessibility.
        centre = polylabel(room, 1e-4)
        radius = centre.distance(room.boundary)
        if radius < 0.003:
            break
        r = radius * rng.uniform(0.4, 0.9)
        k = int(rng.choice([6, 12, 24]))
        t = np.linspace(0.0, 2 * math.pi, k, endpoint=False) + rng.uniform(0.0, math.pi)
        hole = shapely.Polygon(np.c_[centre.x + r * np.cos(t), centre.y + r * np.sin(t)])
        holed = shapely.Polygon(plate.exterior, [h.exterior.coords for h in (*holes, hole)])
        if polylabel(holed, 1e-4).distance(holed.boundary) < MIN_INRADIUS:
            break  # the hole would leave no room to press
        holes.append(hole)
    return shapely.Polygon(plate.exterior, [h.exterior.coords for h in holes])


def _box_sides(poly: shapely.Polygon) -> tuple[float, float]:
    """Long and short side of the minimum rotated rectangle."""
    box = np.asarray(poly.minimum_rotated_rectangle.exterior.coords)
    sides = sorted(np.linalg.norm(np.diff(box[:3], axis=0), axis=1))
    return float(sides[1]), float(sides[0])


def _outline(rng: np.random.Generator, size: float) -> shapely.Polygon:
    """One outline of the drawn family, ``size`` across and at least ``MIN_WIDTH`` wide."""
    aspect = rng.uniform(min(1.0, MIN_WIDTH / size), 1.0)
    kind = KINDS[int(rng.integers(len(KINDS)))]
    shape = {"convex": _convex, "star": _star, "blocks": _blocks}[kind](rng, aspect)
    shape = shapely.affinity.scale(shape, size / diameter(shape), size / diameter(shape))
    _, width = _box_sides(shape)
    if width < MIN_WIDTH:  # a thin bar: widen it to the least width a fingertip needs
        angle = math.degrees(_principal_angle(shape))
        shape = shapely.affinity.rotate(shape, -angle, origin="centroid")
        shape = shapely.affinity.scale(shape, 1.0, MIN_WIDTH / width, origin="centroid")
        shape = shapely.affinity.rotate(shape, angle, origin="centroid")
    shape = shapely.affinity.rotate(shape, rng.uniform(0.0, 360.0), origin="centroid")
    return shapely.set_precision(shape, 1e-5)


def _check_count(value: object, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 0:
        raise ValueError(f"a procedural plate's {what} must be an integer >= 0, got {value!r}")
    return int(value)


def procedural_object(seed: int, redraw: int = 0) -> ObjectShape:
    """Draw ``redraw`` of the plate of ``seed`` (non-negative integers), named
    ``procedural-<seed>``. Draw 0 is the seed's first plate; draw ``k`` comes from a generator
    seeded with ``[seed, k]`` (and this module's stream), the redraws that
    :func:`slide_gym.task.fit_procedural_object` makes when a plate is not admissible."""
    seed, redraw = _check_count(seed, "seed"), _check_count(redraw, "redraw")
    rng = np.random.default_rng([seed, _STREAM, redraw] if redraw else [seed, _STREAM])
    size = _log_uniform(rng, *SIZE_RANGE)
    for _ in range(100):  # redraw outlines a fingertip cannot be pressed on
        shape = _outline(rng, size)
        if polylabel(shape, 1e-4).distance(shape.boundary) >= MIN_INRADIUS:
            break
    else:
        shape = shapely.Point(0.0, 0.0).buffer(size / 2.0, 12)
    if rng.random() < 1.0 / 3.0:
        shape = _with_holes(rng, shape)
    thickness = _log_uniform(rng, *THICKNESS_RANGE)
    return ObjectShape(f"procedural-{seed}", shapely.Polygon(shape), thickness)


def _principal_angle(poly: shapely.Polygon) -> float:
    """Direction (rad) of the longest side of the minimum rotated rectangle."""
    box = np.asarray(poly.minimum_rotated_rectangle.exterior.coords)
    sides = np.diff(box[:3], axis=0)
    longest = sides[int(np.argmax(np.linalg.norm(sides, axis=1)))]
    return math.atan2(longest[1], longest[0])
