"""Goal roots that know the plate's size: C_g drawn through the plate's goal pose.

The paper's C_g (Eq. 4) puts the fingertip anywhere in the band P_g with any yaw; where the
plate then lands follows from the start root it is paired with (Eq. 2). A plate much larger
than u* overhangs enough in most of those landings, but one whose far points reach little
more than u* past its centroid overhangs u* only when such a point faces the edge, so pair
validation rejects most goals drawn that way.

:class:`PlateGoalPoses` draws the plate's goal pose instead: a point of P_g gives the table
edge and the edge point, a plate direction whose extent reaches u* past the centroid (with
the centroid margin) faces that edge, and the overhang is drawn in [u* + a little,
u* + :data:`EXTRA_OVERHANG`] with the centroid still inside. :class:`PlateGoalRegion` turns it
into a fingertip pose by the inverse of Eq. 2 for the latest start root (Gamma_g = kappa_g *
inv(kappa_s) * Gamma_s) and solves IK from that root, so the goal tree starts near the start
tree it was made for. It hands the sampler that root's contact in the plate's frame, and
only directions and overhangs that leave the contact ``contact_margin`` inside the edge are
drawn: on a plate a few centimetres across, a contact on the plate's outer half lies past
the edge (off the area where the fingertip may press) for many directions; in one episode
of a half-scale circle on the long table, 374 of 402 goal roots failed that way and the
plan gave up. Pair validation is unchanged: it still checks every connected pair.
"""

from __future__ import annotations

import math

import numpy as np
import shapely

from slide_gym.geometry import overhang, transform_points, transform_polygon, wrap_angle
from slide_gym.planning.constraints import planar_pose
from slide_gym.planning.regions import AreaPoints, GoalRegion, StartRegion
from slide_gym.planning.se2 import se2_compose, se2_inverse

EXTRA_OVERHANG = 0.02
"""m: the drawn overhang lies in [u* + delta, u* + EXTRA_OVERHANG] (less where the plate is
too small for it), delta = min(2 mm, a third of the plate's slack)."""
N_DIRECTIONS = 720
"""Plate directions (a 0.5 degree grid) tried to face the edge."""
TURN_SCALE = 0.5
"""rad: a direction that needs the plate to turn by t is drawn with weight exp(-t /
TURN_SCALE). Small turns keep the slide short in joint space (a large plate, which may face
the edge any way, then mostly slides without turning); large ones stay possible."""

OTHER_EDGE_SIN = math.sin(math.radians(20.0))
"""A drawn pose is dropped when the edge the plate overhangs most (where pair validation will
grasp) turns more than 20 degrees from the aimed one: near a corner that is another edge,
which may have no reachable grasp; a polygonal round table's neighbouring edges stay in."""


class PlateGoalPoses:
    """Plate goal poses (x, y, yaw) that overhang an edge of P_g by at least u* with the
    centroid ``centroid_margin`` inside the table (checked with the validator's
    :func:`~slide_gym.geometry.overhang`).

    Args:
        plate: the plate's outline in its own frame (centroid at the origin).
        table: the table outline.
        band: P_g as an area (edge stretches a side grasp can reach).
        u_star: the least overhang (m).
        centroid_margin: how far inside the edge the centroid must lie (m).
        contact_margin: how far inside the edge a ``contact`` passed to :meth:`sample` must
            lie (m; the planner's ``tip_edge_margin``).
        stretches: the outline's stretches ``(p, q, outward normal)`` a side grasp can reach
            (``TopSlideProblem.grasp_stretches``); the plate is aimed at the nearest
            point of one of them. None: at the nearest point of the whole outline.
    """

    def __init__(
        self,
        plate: shapely.Polygon,
        table: shapely.Polygon,
        band: shapely.Geometry,
        u_star: float,
        centroid_margin: float = 0.0,
        contact_margin: float = 0.0,
        stretches: list[tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None,
    ):
        self.plate, self.table = plate, table
        self.u_star, self.margin = float(u_star), float(centroid_margin)
        self.contact_margin = float(contact_margin)
        self.band = AreaPoints(band)
        hull = shapely.get_coordinates(plate.convex_hull.exterior)[:-1]
        self.phis = np.linspace(0.0, 2.0 * math.pi, N_DIRECTIONS, endpoint=False)
        self.dirs = np.column_stack([np.cos(self.phis), np.sin(self.phis)])
        self.extent = (hull @ self.dirs.T).max(axis=0)  # how far the plate reaches along each
        slack = self.extent - self.u_star - self.margin
        self.delta = np.minimum(0.002, slack / 3.0)  # the least overhang is u* + delta
        if stretches is None:
            ring = shapely.get_coordinates(shapely.orient_polygons(table).exterior)
            ends = np.stack([ring[:-1], ring[1:]], axis=1)
        else:
            ends = np.array([(p, q) for p, q, _ in stretches]).reshape(-1, 2, 2)
        self.edge_a, self.edge_d = ends[:, 0], ends[:, 1] - ends[:, 0]
        self.edge_len2 = np.maximum((self.edge_d**2).sum(axis=1), 1e-18)

    def edge_point(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The nearest point of the outline (or of its reachable stretches) to ``xy`` and that
        edge's outward normal."""
        t = np.clip(((xy - self.edge_a) * self.edge_d).sum(axis=1) / self.edge_len2, 0.0, 1.0)
        feet = self.edge_a + t[:, None] * self.edge_d
        k = int(np.argmin(((feet - xy) ** 2).sum(axis=1)))
        e = self.edge_d[k] / math.sqrt(self.edge_len2[k])
        return feet[k], np.array([e[1], -e[0]])  # outward for a counter-clockwise ring

    def sample(
        self,
        rng: np.random.Generator,
        start_yaw: float = 0.0,
        max_rotation: float = math.inf,
        contact: np.ndarray | None = None,
    ) -> np.ndarray | None:
        """A goal pose turned at most ``max_rotation`` from ``start_yaw`` (small turns
        preferred, :data:`TURN_SCALE`) that leaves ``contact`` (a point in the plate's frame,
        if given) ``contact_margin`` inside the edge, or None when this draw found none (no
        admissible direction at the drawn edge point, or a corner spoils the overhang or the
        centroid)."""
        if len(self.band) == 0:
            return None
        foot, n = self.edge_point(self.band.sample_point(rng))
        yaws = math.atan2(n[1], n[0]) - self.phis  # the plate yaw that points phi along n
        turn = np.abs((yaws - start_yaw + math.pi) % (2.0 * math.pi) - math.pi)
        # the largest overhang along each direction that keeps the contact in
        reach = self.dirs @ contact if contact is not None else 0.0
        room = self.extent - reach - self.contact_margin
        ok = (self.extent > self.u_star + self.margin) & (turn <= max_rotation)
        if contact is not None:
            ok &= room >= self.u_star + self.delta
        if not ok.any():
            return None
        weight = np.exp(-turn[ok] / TURN_SCALE)
        k = int(rng.choice(np.flatnonzero(ok), p=weight / weight.sum()))
        delta = float(self.delta[k])
        u_hi = min(self.u_star + EXTRA_OVERHANG, self.extent[k] - self.margin - delta)
        if contact is not None:
            u_hi = min(u_hi, float(room[k]))
        u = float(rng.uniform(self.u_star + delta, u_hi))
        centre = foot - (self.extent[k] - u) * n
        pose = np.array([centre[0], centre[1], wrap_angle(float(yaws[k]))])
        placed = transform_polygon(self.plate, *pose)
        ov = overhang(placed, self.table)
        margin_ok = self.margin <= 0.0 or self.table.exterior.distance(placed.centroid) >= (
            self.margin
        )
        if ov.u < self.u_star or not ov.centroid_inside or not margin_ok:
            return None
        if ov.edge is not None:  # near a corner the plate may stick out farthest over another
            e = np.diff(np.asarray(ov.edge, dtype=float), axis=0)[0]
            if abs(float(np.dot(e, n))) > OTHER_EDGE_SIN * float(np.linalg.norm(e)):
                return None
        if contact is not None:  # near a corner the other edge may come closer
            point = shapely.Point(transform_points(np.asarray(contact)[None], *pose)[0])
            inside = self.table.contains(point)
            if not inside or self.table.exterior.distance(point) < self.contact_margin:
                return None
        return pose


class PlateGoalRegion(GoalRegion):
    """C_g through the plate's goal pose: a fingertip pose from the inverse of Eq. 2 for the
    start region's latest root (:attr:`StartRegion.last`); while there is none, a draw of the
    paper's band region (:class:`GoalRegion`)."""

    def __init__(
        self,
        poses: PlateGoalPoses,
        start: StartRegion,
        object_start: np.ndarray,
        max_rotation: float,
        *args,
        **kwargs,
    ):
        super().__init__(poses.band.area, *args, **kwargs)
        self.poses, self.start = poses, start
        self.object_start = np.asarray(object_start, dtype=float)
        self.max_rotation = float(max_rotation)

    def sample(self, rng: np.random.Generator) -> np.ndarray | None:
        q_s = self.start.last
        if q_s is None:
            return super().sample(rng)
        self.draws += 1
        gamma_s = planar_pose(self.constraints.chain.forward(q_s))
        contact = se2_compose(se2_inverse(self.object_start), gamma_s)  # in the plate's frame
        kappa_g = self.poses.sample(
            rng, float(self.object_start[2]), self.max_rotation, contact=contact[:2]
        )
        if kappa_g is None:
            return None
        gamma_g = se2_compose(kappa_g, contact)
        return self.solve_contact(gamma_g[:2], float(gamma_g[2]), rng, seed=q_s)
