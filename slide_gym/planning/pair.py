"""IsPairValid (IV-C.1): where a start/goal pair slides the plate, and can it then be grasped.

For a connected pair (phi_s, phi_g) the plate's final pose follows from Eq. 2 in SE(2). The
pair is valid when the placed plate overhangs a table edge by ``u >= u_star`` with its
centroid still on the table, a side grasp perpendicular to that edge at the overhang's centre
has an IK solution that is collision-free (plate included), and the hand can get there from
phi_g: lift the fingertip off the plate, then rise above the table outside the edge, descend
and approach (or, for grasps at the edge of the workspace where no stand-off pose exists, go
straight to the grasp). Each leg is a checked joint-space straight line; if none works, a
short unconstrained CBiRRT (the search core) joins the lifted configuration and the grasp,
capped by a number of iterations (``GraspParams.transfer_iterations``).

Nothing here decides by the clock: every loop is bounded by a count, and the validator's
``deadline`` (the planner's give-up time) only makes a check that it interrupted answer "time
budget ran out" instead of a verdict.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import shapely

from slide_gym.geometry import ObjectShape, TableShape, overhang, transform_polygon, wrap_angle
from slide_gym.planning.collision import CollisionChecker
from slide_gym.planning.constraints import planar_pose
from slide_gym.planning.ik import IKParams, IKTarget, solve_ik, solve_ik_along
from slide_gym.planning.result import OutOfTime, SearchParams
from slide_gym.planning.se2 import slid_object_pose
from slide_gym.planning.search import ForestConnectPlanner, SearchFunctions
from slide_gym.planning.smoothing import shortcut_straight
from slide_gym.robot.kinematics import (
    SHOULDER,
    WRIST_REACH,
    WRIST_TO_GRASP,
    FastChain,
    grasp_chain,
)
from slide_gym.robot.model import ARM_LOWER, ARM_UPPER, PINCH_DEPTH, PINCH_EDGE_CLEARANCE


@dataclass(frozen=True)
class GraspParams:
    """Side grasp geometry and the transfer from phi_g to it (m, rad).

    ``transfer_iterations`` caps the fallback transfer planner (an unconstrained CBiRRT from
    the lifted configuration to the grasp, tried when no straight route is free) at that many
    search iterations per grasp candidate. It replaced a 0.25 s wall-clock cap, which made
    the verdict depend on the machine's speed. Measured on the 2-core development machine:
    over ``slide-gym bench plan --trials 3`` (45 queries, 26 fallbacks) and 72 expert
    episodes (77 fallbacks) every fallback succeeded, in 1-59 iterations (median 5, 99th
    percentile 53); at the measured 160-340 iterations/s the old 0.25 s held about 40-85.
    100 keeps all of them with a margin and still stops a hopeless search early.
    """

    depth: float = PINCH_DEPTH  # the fingertips reach this far in from the overhang's outer end
    least_hold: float = 0.5 * PINCH_DEPTH  # no grasp with less plate than this within reach
    edge_clearance: float = PINCH_EDGE_CLEARANCE  # least gap between fingertips and table edge
    lift: float = 0.08  # fingertip lift off the plate after sliding; the grasp must rise this
    retreat: float = 0.04  # pre-grasp stand-off outside the edge, along the approach
    rise: float = 0.08  # the pre-grasp is approached from this high above the grasp
    clear_height: float = 0.2  # height over the table top the hand rises to before turning
    resolution: float = 0.02  # largest joint change between collision checks on a leg
    transfer_iterations: int = 100  # search iterations of the fallback planner per candidate

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            if name == "transfer_iterations":
                if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                    raise ValueError(f"GraspParams.{name} must be an integer >= 1: {value!r}")
            elif not (math.isfinite(value) and value > 0):
                raise ValueError(f"GraspParams.{name} must be a finite positive number: {value}")


def grasp_poses(
    outside: shapely.Geometry, edge: np.ndarray, z_mid: float, p: GraspParams
) -> list[tuple[np.ndarray, np.ndarray]] | None:
    """Grasp-frame targets (position, rotation) for an overhang, palm y up and down.

    The grasp frame's z (approach) is horizontal, perpendicular to ``edge`` and points into
    the table; its origin (midway between the fingertips) sits on the edge normal through the
    overhang's centroid, ``depth`` in from the overhang's outer end (less where the table's
    edge is nearer, by ``edge_clearance``) and at the plate's mid-height ``z_mid``. None when
    less than ``least_hold`` of plate lies within the fingertips' reach on that normal.
    """
    a, b = np.asarray(edge, dtype=float)
    e = (b - a) / np.linalg.norm(b - a)
    n = np.array([e[1], -e[0]])
    c = np.array(outside.centroid.coords[0])
    if np.dot(c - a, n) < 0.0:
        n = -n  # outward normal: toward the overhanging part
    foot = a + np.dot(c - a, e) * e
    ray = shapely.LineString([foot - 0.5 * n, foot + 0.5 * n])
    hits = shapely.get_coordinates(outside.intersection(ray))
    if len(hits) == 0:
        return None
    s_max = float(np.max((hits - a) @ n))
    s_tip = max(s_max - p.depth, p.edge_clearance)
    if s_max - s_tip < p.least_hold:
        return None
    pos = np.array([*(foot + s_tip * n), z_mid])
    return [(pos, rot) for rot in side_grasp_rotations(n)]


def side_grasp_rotations(n: np.ndarray) -> list[np.ndarray]:
    """Grasp-frame rotations for a side grasp over an edge with outward normal ``n`` (2,):
    the approach (z) horizontal along ``-n``, into the table, palm y up and down."""
    z_axis = np.array([-n[0], -n[1], 0.0])
    out = []
    for up in (1.0, -1.0):
        y_axis = np.array([0.0, 0.0, up])
        out.append(np.column_stack([np.cross(y_axis, z_axis), y_axis, z_axis]))
    return out


def _edges_near(table: shapely.Polygon, part: shapely.Geometry, gap: float = 1e-3) -> list:
    """Table edges (2, 2) within ``gap`` of ``part``, nearest first."""
    ring = shapely.get_coordinates(table.exterior)
    edges = np.stack([ring[:-1], ring[1:]], axis=1)
    dist = shapely.distance(shapely.linestrings(edges), part)
    return [edges[k] for k in np.argsort(dist) if dist[k] <= gap]


_SEED_ONLY = IKParams(n_restarts=1)
GRASP_IK_ROUNDS = 3
"""IK rounds per grasp candidate: a round's first converged solution may collide."""
NEAR_IK_STEPS = 8
"""Steps of the walk along the arm's IK branch to a re-aimed grasp (``near``)."""


class PairValidator:
    """Callable ``(q_s, q_g) -> (ok, info)`` for the search; ``info`` explains the verdict."""

    def __init__(
        self,
        obj: ObjectShape,
        table: TableShape,
        object_start: np.ndarray,
        u_star: float,
        tip_chain: FastChain,
        checker: CollisionChecker,
        rng: np.random.Generator,
        grasp: GraspParams | None = None,
        ik_params: IKParams | None = None,
        centroid_margin: float = 0.0,
        max_rotation: float = math.inf,
    ):
        self.obj, self.table = obj, table
        self.centroid_margin = float(centroid_margin)
        self.max_rotation = float(max_rotation)
        self.object_start = np.asarray(object_start, dtype=float)
        self.u_star = float(u_star)
        self.tip_chain = tip_chain
        self.hand = grasp_chain()
        self.checker = checker
        self.rng = rng
        self.grasp = grasp or GraspParams()
        self.ik_params = ik_params or IKParams()
        self.deadline = math.inf  # the planner's give-up time (time.perf_counter)
        self.counts = dict.fromkeys(
            (
                "rotation",
                "overhang",
                "reach",
                "grasp_ik",
                "transfer",
                "timeout",
                "fallback",
                "fallback_solved",
                "fallback_iterations",
                "valid",
            ),
            0,
        )

    def object_goal(self, q_s: np.ndarray, q_g: np.ndarray) -> np.ndarray:
        """Eq. 2: the plate pose (x, y, yaw) after sliding from phi_s to phi_g."""
        gammas = planar_pose(self.tip_chain.forward(np.stack([q_s, q_g])))
        return slid_object_pose(gammas[0], gammas[1], self.object_start)

    def __call__(self, q_s: np.ndarray, q_g: np.ndarray) -> tuple[bool, dict[str, Any]]:
        goal = self.object_goal(q_s, q_g)
        turn = abs(wrap_angle(goal[2] - self.object_start[2]))
        if turn > self.max_rotation:
            self.counts["rotation"] += 1
            reason = f"the plate would turn {turn:.2f} rad > {self.max_rotation:.2f}"
            return False, {"object_goal_pose": goal, "overhang_m": 0.0, "reason": reason}
        return self.check_placement(goal, q_g)

    def check_placement(
        self,
        goal: np.ndarray,
        q_g: np.ndarray,
        u_star: float | None = None,
        lifted: bool = False,
        centroid_margin: float | None = None,
        transfer_iterations: int | None = None,
        grasp_seeds: np.ndarray | None = None,
        near: bool = False,
        postures: np.ndarray | None = None,
    ) -> tuple[bool, dict[str, Any]]:
        """Is the plate graspable at ``goal`` (x, y, yaw), and reachable from ``q_g``?

        The second half of the pair check; an executor also calls it with the plate's measured
        pose after a real slide, to re-aim the grasp (``u_star`` overrides the validator's;
        ``lifted`` says the fingertip is already off the plate at ``q_g``, so no lift leg;
        ``centroid_margin`` overrides how far inside the table edge the centroid must lie;
        ``transfer_iterations`` the fallback planner's iteration cap; ``grasp_seeds`` (k, 7)
        extra IK seeds for the grasp, e.g. the grasp planned for a nearby pose; ``near``: prefer
        the grasp on the IK branch of ``q_g``, or the one nearest it, so that the transfer to
        it is short; ``postures`` (r, 7): prefer instead the grasp nearest any of these arm
        postures, so that grasps of nearby plate poses lie on one IK branch whatever the arm
        did before).

        Every step is bounded by a count (two grasp candidates, IK iterations, straight legs,
        the fallback's iterations). If :attr:`deadline` passes during the check, the answer is
        ``(False, {"reason": "time budget ran out during validation", "timeout": True})``
        whatever the partial work found, so the verdict never depends on the clock.
        """
        u_star = self.u_star if u_star is None else float(u_star)
        margin = self.centroid_margin if centroid_margin is None else float(centroid_margin)
        goal = np.asarray(goal, dtype=float)
        info, poses, counter = self._grasp_targets(goal, u_star, margin)
        if poses is None:
            self.counts[counter] += 1
            return False, info
        if time.perf_counter() >= self.deadline:
            return self._timed_out(info)
        cap = self.grasp.transfer_iterations if transfer_iterations is None else transfer_iterations
        self.checker.place_object(goal)
        reason, counter = "no collision-free IK solution for the grasp", "grasp_ik"
        found: dict[str, Any] | None = None
        try:
            seeds = np.vstack([q_g[None], *([] if grasp_seeds is None else [grasp_seeds])])
            for pos, rot in poses:
                q_grasp = self._grasp_ik(pos, rot, seeds, near, postures)
                if q_grasp is None:
                    continue
                if not self._liftable(q_grasp, pos, rot):
                    reason, counter = "the grasp configuration cannot lift the plate", "grasp_ik"
                    continue
                path = self._transfer(q_g, q_grasp, pos, rot, lifted, cap)
                if path is not None:
                    found = {**info, "grasp_config": q_grasp, "transfer_path": path}
                    break
                reason, counter = "no collision-free motion to the grasp", "transfer"
        finally:
            self.checker.place_object(None)
        if time.perf_counter() >= self.deadline:  # some step may have stopped at the deadline
            return self._timed_out(info)
        if found is not None:
            self.counts["valid"] += 1
            return True, found
        self.counts[counter] += 1
        return False, {**info, "reason": reason}

    def feasible(self, q_s: np.ndarray, q_g: np.ndarray) -> bool:
        """The quick half of a validation, no IK and no collision checks: the plate's turn, its
        overhang and centroid, plate on the grasp line and the grasp within the arm's reach.
        False: calling the validator would reject the pair; True decides nothing."""
        goal = self.object_goal(q_s, q_g)
        if abs(wrap_angle(goal[2] - self.object_start[2])) > self.max_rotation:
            return False
        return self._grasp_targets(goal, self.u_star, self.centroid_margin)[1] is not None

    def _grasp_targets(
        self, goal: np.ndarray, u_star: float, margin: float
    ) -> tuple[dict[str, Any], list | None, str]:
        """``(info, grasp poses, "")`` for the plate at ``goal``, or ``(info with a reason,
        None, the counter to raise)`` when the placement alone rules the grasp out."""
        placed = transform_polygon(self.obj.polygon, *goal)
        ov = overhang(placed, self.table.polygon)
        info: dict[str, Any] = {"object_goal_pose": goal, "overhang_m": ov.u}
        centroid_ok = ov.centroid_inside and (
            margin <= 0.0 or self.table.polygon.exterior.distance(placed.centroid) >= margin
        )
        if ov.u < u_star or not centroid_ok or ov.edge is None:
            why = "centroid off the table" if not centroid_ok else "overhang below u_star"
            return {**info, "reason": why}, None, "overhang"
        info["edge"] = ov.edge
        z_mid = self.table.height + 0.5 * self.obj.thickness
        poses = grasp_poses(ov.outside, ov.edge, z_mid, self.grasp)
        if poses is None:  # near a corner: try the other edges the overhang sticks out over
            for edge in _edges_near(self.table.polygon, ov.outside):
                poses = grasp_poses(ov.outside, edge, z_mid, self.grasp)
                if poses is not None:
                    info["edge"] = edge
                    break
        if poses is None:
            return {**info, "reason": "too little plate on the grasp line"}, None, "overhang"
        wrist = poses[0][0] - WRIST_TO_GRASP * poses[0][1][:, 2]
        if np.linalg.norm(wrist - SHOULDER) > WRIST_REACH:
            return {**info, "reason": "grasp pose out of the arm's reach"}, None, "reach"
        return info, poses, ""

    def _timed_out(self, info: dict[str, Any]) -> tuple[bool, dict[str, Any]]:
        self.counts["timeout"] += 1
        return False, {**info, "reason": "time budget ran out during validation", "timeout": True}

    # -------------------------------------------------------------- helpers
    def _ik(
        self,
        pos: np.ndarray,
        rot: np.ndarray,
        seed: np.ndarray,
        chain: FastChain | None = None,
        params: IKParams | None = None,
    ):
        """IK for the hand (or ``chain``) from ``seed`` (7,) or seeds (k, 7)."""
        chain = chain or self.hand
        target = IKTarget(pos, rot)
        params = params or self.ik_params
        return solve_ik(chain, target, self.rng, np.atleast_2d(seed), params, self.deadline)

    def _ik_close(self, pos: np.ndarray, rot: np.ndarray, seed: np.ndarray):
        """IK for the hand a few centimetres from ``seed``'s pose, on its branch if the seed
        alone converges: a random restart on another branch would make the straight
        joint-space leg between them sweep the hand far off the short Cartesian move."""
        q = self._ik(pos, rot, seed, params=_SEED_ONLY)
        return q if q is not None else self._ik(pos, rot, seed)

    def _grasp_ik(
        self,
        pos: np.ndarray,
        rot: np.ndarray,
        seeds: np.ndarray,
        near: bool = False,
        postures: np.ndarray | None = None,
    ):
        """A collision-free grasp configuration at (``pos``, ``rot``), or None.

        ``near``: first follow the arm's own IK branch from ``seeds[0]``
        (:func:`~slide_gym.planning.ik.solve_ik_along`), and if that fails take the
        converged restart nearest ``seeds[0]``. The lowest-index restart to converge wins a
        batch otherwise, often a random one on another branch, and a joint-space transfer
        between branches sweeps the hand through a wide arc (up to a metre above the table).
        ``postures`` (r, 7) replace both: the first round also starts from them, and its
        converged restart nearest any of them wins.

        The first round solves from ``seeds`` plus random restarts, ``GRASP_IK_ROUNDS`` times
        the usual number in one batch (a batch of 24 costs ~1.3 batches of 8, and most grasps
        that converge at all do so from some restart of it). If its solution puts the arm
        through the table, further rounds with fresh restarts look for another one.
        """
        if postures is not None:
            postures = np.atleast_2d(np.asarray(postures, dtype=float))
            seeds, near = np.vstack([postures, seeds]), False
        elif near:
            target = IKTarget(pos, rot)
            q = solve_ik_along(
                self.hand, target, seeds[0], NEAR_IK_STEPS, self.rng, self.ik_params, self.deadline
            )
            if q is not None and not self.checker.collides(q, "full"):
                return q
        wide = replace(self.ik_params, n_restarts=self.ik_params.n_restarts * GRASP_IK_ROUNDS)
        for round_ in range(GRASP_IK_ROUNDS):
            if round_ == 0:
                target = IKTarget(pos, rot)
                nearest = near or postures is not None
                q = solve_ik(
                    self.hand, target, self.rng, seeds, wide, self.deadline, nearest, postures
                )
                if q is None:
                    return None  # no restart of the wide batch converged
            else:
                q = self._ik(pos, rot, seeds[:1])
            if q is not None and not self.checker.collides(q, "full"):
                return q
        return None

    def _liftable(self, q_grasp: np.ndarray, pos: np.ndarray, rot: np.ndarray) -> bool:
        """The hand can rise ``grasp.lift`` straight up from ``q_grasp`` on the same IK branch
        (a grasp at a joint limit cannot lift the plate)."""
        n = max(1, math.ceil(self.grasp.lift / 0.02))
        q = q_grasp
        for k in range(1, n + 1):
            target = IKTarget(pos + [0.0, 0.0, self.grasp.lift * k / n], rot)
            nxt = solve_ik(self.hand, target, self.rng, q[None], _SEED_ONLY, self.deadline)
            if nxt is None or np.abs(nxt - q).max() > 0.5:
                return False
            q = nxt
        return True

    def _transfer(
        self, q_g, q_grasp, pos, rot, from_lifted=False, max_iterations=None
    ) -> np.ndarray | None:
        """phi_g -> lifted -> high pre-grasp -> pre-grasp -> grasp (or without the high
        pre-grasp, or lifted -> grasp, or a fallback plan of at most ``max_iterations``
        iterations); ``from_lifted``: q_g is already off the plate, lifted = q_g. The
        pre-grasp stands ``retreat`` back from the grasp, or a half or a quarter of it where
        the arm cannot reach that far. None also once the deadline has passed."""
        p = self.grasp
        if from_lifted:
            lifted = q_g
        else:
            tip = self.tip_chain.forward(q_g)
            lifted = self._ik(tip[:3, 3] + [0.0, 0.0, p.lift], tip[:3, :3], q_g, self.tip_chain)
            if lifted is None:
                return None
            if not self.checker.segment_free(q_g, lifted, "sliding", p.resolution):
                return None
        if time.perf_counter() >= self.deadline:
            return None
        if self.checker.collides(lifted, "full"):
            return None
        pre = back = None
        for retreat in (p.retreat, p.retreat / 2, p.retreat / 4):  # shorter near reach's edge
            back = pos - retreat * rot[:, 2]
            pre = self._ik_close(back, rot, q_grasp)
            if pre is not None:
                break
        routes = []
        if pre is not None:
            high = self._ik_close(back + [0.0, 0.0, p.rise], rot, pre)
            if high is not None:  # the hand first rises clear of the table, then turns around
                routes.append([lifted, high, pre, q_grasp])
                tip = self.tip_chain.forward(lifted)
                clear_z = max(tip[2, 3], self.table.height + p.clear_height)
                up = self._ik(np.r_[tip[:2, 3], clear_z], tip[:3, :3], lifted, self.tip_chain)
                if up is not None:
                    routes.append([lifted, up, high, pre, q_grasp])
            routes.append([lifted, pre, q_grasp])
        routes.append([lifted, q_grasp])  # grasps at the edge of the workspace: no stand-off
        for route in routes:
            if time.perf_counter() >= self.deadline:
                return None
            legs = zip(route[:-1], route[1:], strict=True)
            if all(self.checker.segment_free(a, b, "full", p.resolution) for a, b in legs):
                return np.array(route if from_lifted else [q_g, *route])
        path = self.plan_route(lifted, q_grasp, max_iterations or p.transfer_iterations)
        if path is None:
            return None
        return path if from_lifted else np.vstack([q_g[None], path])

    def plan_route(
        self, q_from: np.ndarray, q_to: np.ndarray, max_iterations: int
    ) -> np.ndarray | None:
        """A collision-free joint path ``q_from`` ... ``q_to`` ("full" mode, with whatever
        plate the checker holds) from an unconstrained CBiRRT of at most ``max_iterations``
        iterations, then shortcut greedily by straight segments; None if the cap (or the
        deadline) stops it first.

        Its random stream is seeded by exactly one draw from the validator's, so however many
        samples the search takes, the planner's main stream stays the same.
        """
        rng = np.random.default_rng(self.rng.integers(2**63))
        if time.perf_counter() >= self.deadline:
            return None
        self.counts["fallback"] += 1
        res = self.grasp.resolution
        fns = SearchFunctions(
            sample_config=lambda rng: rng.uniform(ARM_LOWER, ARM_UPPER),
            project=lambda q, near: q,
            collides=lambda q: self.checker.collides(q, "full"),
            motion_valid=lambda a, b: self.checker.segment_free(a, b, "full", res),
        )
        params = SearchParams(step_size=0.15, n_star=1, max_iterations=max_iterations)
        planner = ForestConnectPlanner("cbirrt", fns, params, rng, start=q_from, goal=q_to)
        result = planner.solve_until(self.deadline)
        self.counts["fallback_iterations"] += result.stats.iterations
        if not result.solved:
            return None
        try:
            path = shortcut_straight(result.path, fns.motion_valid, self.deadline)
        except OutOfTime:
            return None
        self.counts["fallback_solved"] += 1
        return path
