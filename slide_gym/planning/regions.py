"""Sampleable start and goal regions C_s (Eq. 3) and C_g (Eq. 4).

A draw picks a contact point (from the plate's top-surface point cloud P_o for C_s, uniformly
from the band P_g along the table outline for C_g), a yaw alpha in [0, 2 pi), the pitch beta0
and a contact height inside the depth band, then solves IK for the fingertip pose
r(alpha, beta0) at that point and keeps the result only if it is on the relaxed manifold and
collision-free in ``"sliding"`` mode. A failed draw returns None; the search just skips it.
The planner's default goal region draws the plate's goal pose first instead
(:mod:`slide_gym.planning.plate_goals`); this module's :class:`GoalRegion` is the paper's.
"""

from __future__ import annotations

import math
import time

import numpy as np
import shapely

from slide_gym.planning.collision import CollisionChecker
from slide_gym.planning.constraints import SlideConstraints, contact_rotation
from slide_gym.planning.grasp_reach import reachable_stretches
from slide_gym.planning.ik import IKParams, IKTarget, solve_ik
from slide_gym.planning.result import PlannerStats
from slide_gym.robot.model import ARM_LOWER, ARM_UPPER, READY_ARM_Q

TWO_PI = 2.0 * math.pi


def nominal_seed(point: np.ndarray, alpha: float) -> np.ndarray:
    """A start guess for IK: READY_ARM_Q turned toward ``point``, wrist roll set for ``alpha``.

    At READY_ARM_Q (j1 = 0) the hand points down with X_F along world +y; turning j1 by
    theta and j7 by (alpha - theta - pi/2) brings X_F to yaw alpha.
    """
    q = np.array(READY_ARM_Q, dtype=float)
    theta = math.atan2(point[1], point[0])
    q[0] = theta
    j7 = q[6] + math.remainder(alpha - theta - math.pi / 2, TWO_PI)
    if j7 > ARM_UPPER[6]:
        j7 -= TWO_PI
    elif j7 < ARM_LOWER[6]:
        j7 += TWO_PI
    q[6] = j7
    return np.clip(q, ARM_LOWER, ARM_UPPER)


class ContactRegion:
    """Base of the two regions: pose sampling around a contact point, IK and checks."""

    def __init__(
        self,
        constraints: SlideConstraints,
        checker: CollisionChecker,
        ik_params: IKParams | None = None,
    ):
        self.constraints = constraints
        self.checker = checker
        self.ik_params = ik_params or IKParams()
        self.draws = 0
        self.accepted = 0
        self.deadline = math.inf  # draws give up (None) once perf_counter() passes it
        self.last: np.ndarray | None = None  # the latest accepted configuration

    def sample_point(self, rng: np.random.Generator) -> np.ndarray:
        """A contact point (x, y) in world."""
        raise NotImplementedError

    def sample(self, rng: np.random.Generator) -> np.ndarray | None:
        """One configuration of the region, or None when this draw failed."""
        self.draws += 1
        xy = self.sample_point(rng)
        return self.solve_contact(xy, float(rng.uniform(0.0, TWO_PI)), rng)

    def solve_contact(
        self,
        xy: np.ndarray,
        alpha: float,
        rng: np.random.Generator,
        seed: np.ndarray | None = None,
    ) -> np.ndarray | None:
        """A configuration with the contact at ``xy`` (a height drawn in the depth band), yaw
        ``alpha`` and pitch beta0, on the relaxed manifold and collision-free, or None. IK
        starts from ``seed`` (7,), if given, then from :func:`nominal_seed`."""
        band = self.constraints.band
        z = float(rng.uniform(band.z_lo, band.z_hi))
        point = np.array([xy[0], xy[1], z])
        target = IKTarget(point, contact_rotation(alpha, band.beta0))
        seeds = nominal_seed(point, alpha)[None]
        if seed is not None:
            seeds = np.vstack([seed, seeds])
        q = solve_ik(self.constraints.chain, target, rng, seeds, self.ik_params, self.deadline)
        if q is None or not self.constraints.satisfied(q):
            return None
        if self.checker.collides(q, "sliding"):
            return None
        self.accepted += 1
        self.last = q
        return q


class StartRegion(ContactRegion):
    """C_s: contacts at the points of P_o (the plate top at its start pose, world frame)."""

    def __init__(self, points: np.ndarray, *args, **kwargs):
        super().__init__(*args, **kwargs)
        pts = np.asarray(points, dtype=float)
        if pts.ndim != 2 or pts.shape[1] < 2 or len(pts) == 0:
            raise ValueError(f"P_o must be a non-empty (N, 2|3) array, got shape {pts.shape}")
        self.points = pts[:, :2].copy()

    def sample_point(self, rng: np.random.Generator) -> np.ndarray:
        return self.points[int(rng.integers(len(self.points)))]


def goal_band(
    table: shapely.Polygon,
    width: float,
    grasp_height: float | None = None,
    grasp_offset: float = 0.015,
    stretches: list[tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None,
) -> shapely.Geometry:
    """P_g as an area: the table minus its inward offset by ``width``.

    With ``grasp_height`` (the plate's mid-height) the band keeps only the stretches of the
    outline where a side grasp ``grasp_offset`` outside the edge, perpendicular to it, has an
    IK solution (:func:`~slide_gym.planning.grasp_reach.reachable_stretches`, a necessary
    condition: pair validation checks the rest): a plate slid elsewhere could never be picked
    up. ``stretches`` (``(p, q, outward normal)`` each) replaces that search with these
    stretches. Returns an empty geometry if nothing is left.
    """
    inner = table.buffer(-width)
    band = table.difference(inner) if not inner.is_empty else table
    if band.area <= 0.0:
        raise ValueError(f"goal band of width {width} m is empty for this table")
    if stretches is None:
        if grasp_height is None:
            return band
        stretches = reachable_stretches(table, grasp_height, grasp_offset)
    pieces = [
        shapely.Polygon([p, q, q - 2 * width * n, p - 2 * width * n]) for p, q, n in stretches
    ]
    return band.intersection(shapely.union_all(pieces)) if pieces else shapely.Polygon()


class AreaPoints:
    """Uniform random points of an area (triangulated once); none for an empty area."""

    def __init__(self, area: shapely.Geometry):
        self.area = area
        tris = shapely.get_parts(shapely.constrained_delaunay_triangles(area))
        tris = [t for t in tris if t.area > 0.0]
        coords = [shapely.get_coordinates(t)[:3] for t in tris]
        self.triangles = np.array(coords).reshape(-1, 3, 2)  # (T, 3, 2); none if area empty
        areas = np.array([t.area for t in tris])
        self.cum_area = np.cumsum(areas) / areas.sum() if tris else areas

    def __len__(self) -> int:
        return len(self.triangles)

    def sample_point(self, rng: np.random.Generator) -> np.ndarray:
        k = int(np.searchsorted(self.cum_area, rng.random(), side="right"))
        k = min(k, len(self.triangles) - 1)
        r1, r2 = rng.random(2)
        if r1 + r2 > 1.0:
            r1, r2 = 1.0 - r1, 1.0 - r2
        a, b, c = self.triangles[k]
        return a + r1 * (b - a) + r2 * (c - a)


class GoalRegion(ContactRegion):
    """C_g: contacts uniformly in the band P_g along the table outline (at the plate's top)."""

    def __init__(self, band: shapely.Geometry, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.band = band
        self.points = AreaPoints(band)

    def sample(self, rng: np.random.Generator) -> np.ndarray | None:
        """As :meth:`ContactRegion.sample`; always None for an empty band."""
        if len(self.points) == 0:
            self.draws += 1
            return None
        return super().sample(rng)

    def sample_point(self, rng: np.random.Generator) -> np.ndarray:
        return self.points.sample_point(rng)


def draw_root(
    region: StartRegion | GoalRegion,
    rng: np.random.Generator,
    max_draws: int,
    deadline: float,
    stats: PlannerStats,
) -> np.ndarray | str:
    """A root configuration from ``region``, or why none came: ``"timeout"`` (``deadline``
    passed) or ``"exhausted"`` (``max_draws`` draws all failed). Sampling time goes to
    ``stats``."""
    for _ in range(max_draws):
        if time.perf_counter() >= deadline:
            return "timeout"
        t0 = time.perf_counter()
        q = region.sample(rng)
        stats.time_sampling_s += time.perf_counter() - t0
        if q is not None:
            return q
    return "exhausted"
