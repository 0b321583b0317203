"""Where along a table's outline the arm can reach a side grasp at all, found by IK.

The goal band P_g (:func:`slide_gym.planning.regions.goal_band`) keeps the stretches of each
edge where a side grasp is reachable. A reach bound on the wrist centre alone keeps too much:
on the catalog's triangle table it keeps both slanted edges, whose side grasps would point the
hand back toward the robot, and no IK restart reaches any of them. A plate slid there cannot
be picked up, yet each goal root drawn there costs the planner a connection and a failed grasp
IK in pair validation (one half-scale Y on that table: 162 such pairs, 3.9 of its 10 s).

:func:`reachable_stretches` tries the grasp of :func:`slide_gym.planning.pair.grasp_poses`
(approach perpendicular to the edge, palm up or down) at cells :data:`CELL` long along every
edge and keeps the cells where IK converges, widened by one cell on each side so that a cell
the sampled IK missed next to a reachable one stays in. It is a necessary condition (pair
validation still checks collisions, the lift and the transfer), computed once per table
outline and height in a process (0.4-1.1 s for a catalog table on one core) and cached.
"""

from __future__ import annotations

import functools

import numpy as np
import shapely

from slide_gym.planning.ik import IKParams, IKTarget, solve_ik
from slide_gym.planning.pair import side_grasp_rotations
from slide_gym.robot.kinematics import SHOULDER, WRIST_REACH, WRIST_TO_GRASP, grasp_chain

CELL = 0.02
"""m: length of an edge cell whose middle is tested."""
RESTARTS = 24
"""IK restarts per grasp orientation and cell. Against a map with 64 restarts at three
stand-offs, 24 at one stand-off found every reachable cell of the four catalog tables but one
(that one next to a found cell, so the widening keeps it)."""
SEED = 0
"""The IK restarts' generator seed (the map is the same in every process)."""


def reachable_stretches(
    table: shapely.Polygon, grasp_z: float, offset: float
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The stretches of ``table``'s outline with a reachable side grasp.

    Returns ``(p, q, n)`` per stretch: its ends on the outline and the edge's outward normal.
    The grasp frame is tested ``offset`` outside the edge at height ``grasp_z``; cells whose
    wrist centre lies beyond the arm's reach are not tried.
    """
    ring = shapely.get_coordinates(shapely.orient_polygons(table).exterior)
    key = (np.round(ring, 6).tobytes(), round(float(grasp_z), 4), round(float(offset), 4))
    return list(_stretches(*key))


def nearest_stretches(
    stretches: list[tuple[np.ndarray, np.ndarray, np.ndarray]], point: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The stretch of ``stretches`` nearest ``point`` (x, y), with every stretch joined to it
    end to end (a reachable corner is one piece): where ``SlideParams.goal_edge``
    ``"nearest"`` lets a plate go. Empty for no stretches."""
    if not stretches:
        return []
    xy = shapely.points(np.asarray(point, dtype=float)[:2])
    segments = [shapely.LineString([p, q]) for p, q, _ in stretches]
    first = int(np.argmin([shapely.distance(xy, s) for s in segments]))
    kept, frontier = {first}, [first]
    while frontier:
        i = frontier.pop()
        for j, s in enumerate(segments):
            if j not in kept and shapely.distance(segments[i], s) < 1e-6:
                kept.add(j)
                frontier.append(j)
    return [stretches[i] for i in sorted(kept)]


@functools.lru_cache(maxsize=64)
def _stretches(ring_bytes: bytes, grasp_z: float, offset: float) -> tuple:
    ring = np.frombuffer(ring_bytes).reshape(-1, 2)
    chain, rng, params = grasp_chain(), np.random.default_rng(SEED), IKParams(n_restarts=RESTARTS)
    out = []
    for a, b in zip(ring[:-1], ring[1:], strict=True):
        length = float(np.linalg.norm(b - a))
        if length <= 0.0:
            continue
        e = (b - a) / length
        n = np.array([e[1], -e[0]])  # outward for a counter-clockwise exterior
        k = max(1, round(length / CELL))
        ok = np.zeros(k, dtype=bool)
        for i in range(k):
            xy = a + (i + 0.5) / k * length * e + offset * n
            pos = np.array([xy[0], xy[1], grasp_z])
            wrist = pos + WRIST_TO_GRASP * np.array([n[0], n[1], 0.0])
            if np.linalg.norm(wrist - SHOULDER) > WRIST_REACH:
                continue
            ok[i] = any(
                solve_ik(chain, IKTarget(pos, rot), rng, None, params) is not None
                for rot in side_grasp_rotations(n)
            )
        widened = ok | np.r_[ok[1:], False] | np.r_[False, ok[:-1]]
        start = None
        for i, flag in enumerate([*widened, False]):
            if flag and start is None:
                start = i
            elif not flag and start is not None:
                out.append((a + start / k * length * e, a + i / k * length * e, n))
                start = None
    return tuple(out)
