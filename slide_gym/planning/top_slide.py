"""The top-slide planner facade (OMPL-like flow).

``TopSlidePlanner`` wires the robot-specific callables (regions, projection, collision, pair
validation) for a :class:`~slide_gym.planning.problem.TopSlideProblem` into the search core and
turns its answer into a :class:`PlanResult` with a densified path and everything needed to
execute it. Executors re-aim the grasp, check routes and plan free-space routes through its
public methods.

With ``start_config`` the ``regions`` search starts from that one configuration (an arm
already pressing the plate, for an executor that takes over mid-slide): the start forest is
that single root, projected onto the manifold first, and goal roots are drawn and pair-validated
against it as usual.

Same seed, same plan, on any machine: every decision is bounded by a count (root draws,
search iterations with ``SlideParams.max_iterations``, shortcut attempts, the fallback
transfer planner's iterations); the time budget only decides when to give up (status
``timeout``), never which plan comes out.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
import shapely

from slide_gym.geometry import transform_polygon
from slide_gym.planning.collision import CollisionChecker
from slide_gym.planning.constraints import ContactBand, SlideConstraints
from slide_gym.planning.pair import PairValidator
from slide_gym.planning.plate_goals import PlateGoalPoses, PlateGoalRegion
from slide_gym.planning.problem import TopSlideProblem
from slide_gym.planning.regions import GoalRegion, StartRegion, draw_root
from slide_gym.planning.result import (
    OutOfTime,
    Planner,
    PlannerStats,
    PlanResult,
    PlanStatus,
    SearchParams,
)
from slide_gym.planning.search import (
    PAIR_PLANNERS,
    PLANNERS,
    DensifyError,
    SearchFunctions,
    densify,
    forest_connect_search,
)
from slide_gym.planning.smoothing import shortcut_path
from slide_gym.robot.kinematics import fingertip_chain
from slide_gym.robot.model import ARM_LOWER, ARM_UPPER

START_TIP_TOLERANCE = 0.005
"""m: a fixed start configuration whose projection onto the manifold moves the fingertip
farther than this is rejected (it was not pressing the plate as the constraints want)."""
START_JOINT_TOLERANCE = 0.1
"""rad: ... or changes a joint by more than this."""
START_TRIES = 5
"""Start roots the regions planner's Init draws, at most, before it gives up on a goal root
(with plate-first goal roots, whose poses depend on the start root's contact)."""


class TopSlidePlanner(Planner):
    """Plans a top-sliding motion that leaves the plate graspable (Algorithm 1 and baselines).

    * ``"regions"``: start and goal forests both sample roots from C_s / C_g (the paper's).
      C_g is drawn through the plate's goal pose (``SlideParams.goal_sampling = "plate"``,
      :mod:`~slide_gym.planning.plate_goals`) or, with ``"band"``, as the paper's Eq. 4.
    * ``"cbirrt2"``: one start configuration drawn first; goal roots sampled from C_g.
    * ``"cbirrt"``: draws start/goal pairs until one passes pair validation (inside the budget),
      then only connects that pair under the motion constraints; after
      ``SlideParams.restart_iterations`` search iterations without a path it draws a new
      validated pair and searches again (``extra["restarts"]`` counts them).
    * ``"cbirrt-norestart"``: ``cbirrt`` keeping its first pair for the whole budget.

    ``solve(time_budget)`` returns a :class:`PlanResult` whose ``path`` (fingertip moves
    <= ``path_resolution`` between neighbours) runs from ``start_config`` to ``goal_config``;
    ``extra`` holds ``object_start_pose``, ``object_goal_pose`` (x, y, yaw from Eq. 2),
    ``overhang_m``, ``edge`` (the table edge it overhangs), ``grasp_config``,
    ``transfer_path`` (phi_g ... grasp), ``contact_height_range`` and ``parameters`` (every
    value used), plus counters. The planner owns a PyBullet client: ``close()`` it, or use it
    as a context manager.

    Args:
        problem: the scene and parameters.
        planner: one of ``PLANNERS``.
        seed: seed (anything ``numpy.random.default_rng`` takes) or a Generator.
        start_config: (7,) fixed start (``"regions"`` only): the arm pressing the plate at
            its start pose. It is projected onto the manifold (``project``); a projection
            that fails, moves it more than :data:`START_TIP_TOLERANCE` /
            :data:`START_JOINT_TOLERANCE`, collides or leaves the contact off the plate makes
            ``solve`` answer ``INFEASIBLE`` with the reason. The result's ``start_config`` is
            the projected configuration.
        start_tolerance: (m, rad) the most the projection may move the fixed start's
            fingertip and any joint (default those two constants).
    """

    def __init__(
        self,
        problem: TopSlideProblem,
        planner: str = "regions",
        seed: int | Sequence[int] | np.random.Generator | None = None,
        start_config: Any = None,
        start_tolerance: tuple[float, float] = (START_TIP_TOLERANCE, START_JOINT_TOLERANCE),
    ):
        if planner not in PLANNERS:
            raise ValueError(f"planner must be one of {', '.join(PLANNERS)}, got {planner!r}")
        if start_config is not None:
            if planner != "regions":
                raise ValueError(f"start_config needs the regions planner, not {planner!r}")
            start_config = np.asarray(start_config, dtype=float)
            if start_config.shape != (7,) or not np.isfinite(start_config).all():
                raise ValueError(
                    f"start_config must be 7 finite joint angles, got {start_config.tolist()}"
                )
        tip_tol, joint_tol = (float(v) for v in start_tolerance)
        if not (np.isfinite([tip_tol, joint_tol]).all() and tip_tol > 0 and joint_tol > 0):
            raise ValueError(
                f"start_tolerance must be (metres, radians), both positive, got {start_tolerance}"
            )
        self.start_tolerance = (tip_tol, joint_tol)
        self.problem = problem
        self.name = planner
        self.seed = seed if not isinstance(seed, np.random.Generator) else None
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        p = problem.params
        self.chain = fingertip_chain()
        band = ContactBand(p.beta0, p.dbeta, *problem.height_range, problem.z_surface)
        self.constraints = SlideConstraints(self.chain, band, problem.contact_area, p.tolerance)
        self.checker = CollisionChecker(problem.table, problem.object)
        args = (self.constraints, self.checker, p.ik)
        self.start_region = StartRegion(problem.start_points, *args)
        if p.goal_sampling == "plate":
            poses = PlateGoalPoses(
                problem.object.polygon,
                problem.table.polygon,
                problem.goal_band,
                p.u_star,
                p.centroid_margin,
                p.tip_edge_margin,
                problem.grasp_stretches,
            )
            start, turn = problem.start_pose, p.max_rotation
            self.goal_region = PlateGoalRegion(poses, self.start_region, start, turn, *args)
        else:
            self.goal_region = GoalRegion(problem.goal_band, *args)
        self.validator = PairValidator(
            problem.object,
            problem.table,
            problem.start_pose,
            p.u_star,
            self.chain,
            self.checker,
            self.rng,
            p.grasp,
            p.ik,
            p.centroid_margin,
            p.max_rotation,
        )
        self.search_params = SearchParams(
            step_size=p.step,
            n_star=p.n_star,
            distance_weights=p.distance_weights,
            max_iterations=p.max_iterations,
        )
        self._pair_cache: dict[bytes, tuple[bool, Any]] = {}
        self.max_root_draws = 300
        self.start_config: np.ndarray | None = None
        self._bad_start: str | None = None
        if start_config is not None:
            self._fix_start(start_config)

    def _fix_start(self, q: np.ndarray) -> None:
        """Project and check a fixed start configuration (see the class docstring)."""
        q_p = self.project(q)
        if q_p is None:
            self._bad_start = "the start configuration cannot be projected onto the manifold"
            return
        tip, joint = self.tip_distance(q, q_p), float(np.abs(q_p - q).max())
        tip_tol, joint_tol = self.start_tolerance
        if tip > tip_tol or joint > joint_tol:
            self._bad_start = (
                f"projecting the start configuration moves the fingertip {tip:.4f} m and a "
                f"joint {joint:.3f} rad (at most {tip_tol} m and {joint_tol} rad)"
            )
        elif self.collides(q_p):
            self._bad_start = "the (projected) start configuration collides"
        else:
            xy = self.chain.forward(q_p)[:2, 3]
            plate = transform_polygon(self.problem.object.polygon, *self.problem.start_pose)
            if not shapely.contains_xy(plate, xy[0], xy[1]):
                self._bad_start = "the start configuration's contact is not on the plate"
            else:
                self.start_config = q_p
                self.start_region.last = q_p  # plate-first goal roots aim from it

    # ------------------------------------------------------------ callables
    def pair_valid(self, q_s: np.ndarray, q_g: np.ndarray) -> tuple[bool, Any]:
        """IsPairValid, remembered per pair (the cbirrt baseline validates its pair twice)."""
        key = np.concatenate([q_s, q_g]).tobytes()
        if key not in self._pair_cache:
            self._pair_cache[key] = self.validator(q_s, q_g)
        return self._pair_cache[key]

    def project(self, q: np.ndarray, q_near: np.ndarray | None = None) -> np.ndarray | None:
        """Projection onto the relaxed manifold (None if it fails or breaks a checked rule), as
        ``SlideParams.projection`` says."""
        mode = self.problem.params.projection
        if mode == "ompl":
            return self.constraints.project_ompl(q, q_near)
        return self.constraints.project(q, q_near, depth=mode != "orientation")

    def chord_valid(self, a: np.ndarray, b: np.ndarray) -> bool:
        """The ``"nodes"`` projection's edge check: the straight chord between two tree nodes
        satisfies the constraints at points at most ``path_resolution`` of fingertip travel
        apart (at least at its midpoint)."""
        pieces = math.ceil(self.tip_distance(a, b) / self.problem.params.path_resolution)
        return self.constraints.chord_ok(a, b, max(pieces, 2))

    def collides(self, q: np.ndarray) -> bool:
        """Collision in ``"sliding"`` mode (finger A may sink into the table top)."""
        return self.checker.collides(q, "sliding")

    def functions(self, start: bool = True, goal: bool = True) -> SearchFunctions:
        """The search core's callables; ``start``/``goal`` False fix that side's roots."""
        return SearchFunctions(
            sample_config=lambda rng: rng.uniform(ARM_LOWER, ARM_UPPER),
            project=self.project,
            collides=self.collides,
            pair_valid=self.pair_valid,
            pair_feasible=self.validator.feasible,
            sample_start_root=self.start_region.sample if start else None,
            sample_goal_root=self.goal_region.sample if goal else None,
            motion_valid=self.chord_valid if self.problem.params.projection == "nodes" else None,
            distance_weights=self.problem.params.distance_weights,
        )

    def tip_distance(self, a: np.ndarray, b: np.ndarray) -> float:
        """Fingertip displacement (m) between two configurations."""
        tips = self.chain.forward(np.stack([a, b]))
        return float(np.linalg.norm(tips[0, :3, 3] - tips[1, :3, 3]))

    # ------------------------------------------------------- for executors
    def reaim_grasp(
        self,
        object_pose: Any,
        q_from: np.ndarray,
        u_star: float,
        max_iterations: int | None = None,
        time_budget: float = math.inf,
        grasp_seed: Any = None,
        postures: Any = None,
    ) -> tuple[bool, dict[str, Any]]:
        """Re-aim the side grasp at a measured plate pose (x, y, yaw) after a real slide.

        ``q_from`` is the arm with the fingertip already lifted off the plate. Runs the
        placement half of pair validation (overhang >= ``u_star``, centroid on the table, a
        collision-free, liftable grasp and a transfer from ``q_from``), whose work is bounded
        by counts: two grasp candidates, IK iterations, and at most ``max_iterations``
        iterations of the fallback transfer planner per candidate (None:
        ``GraspParams.transfer_iterations``). ``time_budget`` (seconds, inf: none) is only a
        give-up: a check it interrupts answers ``info["timeout"] = True``. ``grasp_seed`` (7,):
        an extra IK seed for the grasp, such as the plan's ``extra["grasp_config"]``.
        ``postures`` (r, 7): take the grasp nearest any of these arm postures (see
        :func:`~slide_gym.robot.kinematics.mirrored_postures`) rather than the one nearest
        ``q_from``'s IK branch. Returns
        ``(ok, info)``; ``info["transfer_path"]`` runs from ``q_from`` to the grasp,
        ``info["reason"]`` says why not.
        """
        if not time_budget > 0.0:  # NaN fails too; inf means no limit
            raise ValueError(f"time_budget must be > 0 seconds, got {time_budget!r}")
        saved = self.validator.deadline
        self.validator.deadline = time.perf_counter() + time_budget
        try:
            return self.validator.check_placement(
                np.asarray(object_pose, dtype=float),
                np.asarray(q_from, dtype=float),
                u_star,
                lifted=True,
                centroid_margin=0.0,
                transfer_iterations=max_iterations,
                grasp_seeds=None if grasp_seed is None else np.atleast_2d(grasp_seed),
                near=True,
                postures=None if postures is None else np.atleast_2d(postures),
            )
        finally:
            self.validator.deadline = saved

    def route_free(
        self,
        route: Sequence[np.ndarray],
        object_pose: Any = None,
        resolution: float = 0.02,
        mode: str = "full",
    ) -> bool:
        """Is the joint-space polyline ``route`` free of collisions for the whole robot (finger
        A included), with the plate at ``object_pose`` (x, y, yaw; None: no plate)? ``mode``
        ``"sliding"`` ignores finger A against the table and the plate (for legs that start
        pressed on it)."""
        self.checker.place_object(None if object_pose is None else np.asarray(object_pose))
        try:
            return all(
                self.checker.segment_free(a, b, mode, resolution)
                for a, b in zip(route[:-1], route[1:], strict=True)
            )
        finally:
            self.checker.place_object(None)

    def plan_route(
        self,
        q_from: np.ndarray,
        q_to: np.ndarray,
        object_pose: Any = None,
        max_iterations: int | None = None,
        time_budget: float = math.inf,
    ) -> tuple[np.ndarray | None, str | None]:
        """A collision-free joint route ``q_from`` ... ``q_to`` ("full" mode, the plate at
        ``object_pose`` or none) from the same search core as the fallback transfer planner:
        an unconstrained CBiRRT of at most ``max_iterations`` iterations (None:
        ``GraspParams.transfer_iterations``), then 30 shortcuts. ``time_budget`` (seconds)
        is only a give-up. Returns ``(route, None)`` or ``(None, reason)``.
        """
        if not time_budget > 0.0:
            raise ValueError(f"time_budget must be > 0 seconds, got {time_budget!r}")
        cap = max_iterations or self.problem.params.grasp.transfer_iterations
        q_from, q_to = (np.asarray(q, dtype=float) for q in (q_from, q_to))
        saved = self.validator.deadline
        self.validator.deadline = time.perf_counter() + time_budget
        self.checker.place_object(None if object_pose is None else np.asarray(object_pose))
        try:
            if any(self.checker.collides(q, "full") for q in (q_from, q_to)):
                return None, "an end of the route is in collision"
            route = self.validator.plan_route(q_from, q_to, cap)
            timed_out = time.perf_counter() >= self.validator.deadline
        finally:
            self.checker.place_object(None)
            self.validator.deadline = saved
        if timed_out:
            return None, "time budget ran out while planning the route"
        if route is None:
            return None, f"no collision-free route within {cap} search iterations"
        return route, None

    # ---------------------------------------------------------------- solve
    def _draw(self, region: Any, deadline: float, stats: PlannerStats) -> np.ndarray | str:
        return draw_root(region, self.rng, self.max_root_draws, deadline, stats)

    def _initial_roots(self, deadline: float, stats: PlannerStats) -> tuple[list, list, str | None]:
        """Roots drawn before the search (Init of Algorithm 1, or the baselines' fixed roots)."""
        regions = (("start", self.start_region), ("goal", self.goal_region))
        if self.name in PAIR_PLANNERS:
            cap = self.search_params.max_iterations
            for _ in range(cap) if cap is not None else itertools.count():
                drawn = [self._draw(r, deadline, stats) for _, r in regions]
                for (side, _), q in zip(regions, drawn, strict=True):
                    if isinstance(q, str):
                        return [], [], f"{q}:{side}"
                t0 = time.perf_counter()
                ok, _ = self.pair_valid(drawn[0], drawn[1])
                stats.time_validation_s += time.perf_counter() - t0
                if ok:
                    return [drawn[0]], [drawn[1]], None
                if time.perf_counter() >= deadline:
                    return [], [], "timeout:pair"
            return [], [], "limit:pair"
        roots: list[list] = [[], []]
        tries = self._start_tries()
        for attempt in range(tries):
            if self.start_config is not None:
                roots[0].append(self.start_config)
            else:
                q = self._draw(self.start_region, deadline, stats)
                if isinstance(q, str):
                    return [], [], f"{q}:start"
                roots[0].append(q)
            if self.name == "cbirrt2":
                break
            q = self._draw(self.goal_region, deadline, stats)
            if isinstance(q, str) and q == "exhausted" and attempt < tries - 1:
                continue  # no goal pose keeps this root's contact on the table: another root
            if isinstance(q, str):
                return [], [], f"{q}:goal"
            roots[1].append(q)
            break
        return roots[0], roots[1], None

    def _start_tries(self) -> int:
        """Start roots Init may draw before it gives up on a goal root: plate-first goal roots
        depend on the start root's contact (a contact near the plate's rim may leave no goal
        pose that keeps it on the table), so the regions planner draws up to
        ``START_TRIES`` of them; one otherwise."""
        plate_goals = isinstance(self.goal_region, PlateGoalRegion)
        sampled = self.name == "regions" and self.start_config is None
        return START_TRIES if plate_goals and sampled else 1

    def _solve(self, deadline: float, stats: PlannerStats) -> PlanResult:
        t_start = time.perf_counter()
        budget = deadline - t_start
        hard = deadline + 0.04 * budget
        search_deadline = deadline - min(0.05 * budget, 0.25)
        self.validator.deadline = search_deadline
        self.start_region.deadline = self.goal_region.deadline = search_deadline
        bad = self._infeasible()
        if bad is not None:
            return bad
        starts, goals, why = self._initial_roots(search_deadline, stats)
        if why is not None:
            return self._no_roots(why)
        sample_starts = self.name == "regions" and self.start_config is None
        fns = self.functions(start=sample_starts, goal=self.name not in PAIR_PLANNERS)
        failures = restarts = 0
        while True:
            params = self._period_params(stats)
            res = forest_connect_search(
                fns, params, self.rng, search_deadline, stats, starts, goals
            )
            if params is not self.search_params and res.status is PlanStatus.ITERATION_LIMIT:
                restarts += 1  # this pair did not connect in its period: draw another
                starts, goals, why = self._initial_roots(search_deadline, stats)
                if why is not None:
                    return self._no_roots(why, restarts)
                continue
            if not res.solved:
                extra = {"densify_failures": failures, "restarts": restarts}
                res.extra = {**self._extra(), **res.extra, **extra}
                return res
            try:
                dense = self.finish_path(res.path, search_deadline, hard)
            except OutOfTime:
                reason = "found a path but shortcutting and densifying it did not fit in the budget"
                return PlanResult(PlanStatus.TIMEOUT, reason, extra=self._extra())
            except DensifyError:
                if time.perf_counter() >= search_deadline:
                    reason = "found a path but densifying it did not fit in the time budget"
                    return PlanResult(PlanStatus.TIMEOUT, reason, extra=self._extra())
                failures += 1
                continue
            return self._solved(res, dense, failures, restarts)

    def _infeasible(self) -> PlanResult | None:
        """An ``INFEASIBLE`` result for scenes no planner can solve, else None."""
        if self._bad_start is not None:
            return PlanResult(PlanStatus.INFEASIBLE, self._bad_start, extra=self._extra())
        if self.problem.goal_band.is_empty:
            reason = "no stretch of the table edge allows a side grasp within the arm's reach"
            return PlanResult(PlanStatus.INFEASIBLE, reason, extra=self._extra())
        reach, p = self.problem.object.circumradius, self.problem.params
        if not self.problem.object.can_overhang(p.u_star, p.centroid_margin):
            reason = (
                f"the plate cannot overhang u* = {p.u_star:.3g} m with its centroid "
                f"{p.centroid_margin:.3g} m inside the edge: no point of it lies farther than "
                f"{reach:.3g} m from its centroid"
            )
            return PlanResult(PlanStatus.INFEASIBLE, reason, extra=self._extra())
        return None

    def _period_params(self, stats: PlannerStats) -> SearchParams:
        """The search settings of the next search: for ``cbirrt``, capped at
        ``restart_iterations`` more iterations (unless the overall cap comes first)."""
        if self.name != "cbirrt":
            return self.search_params
        cap = stats.iterations + self.problem.params.restart_iterations
        overall = self.search_params.max_iterations
        if overall is not None and cap >= overall:
            return self.search_params
        return dataclasses.replace(self.search_params, max_iterations=cap)

    def _no_roots(self, why: str, restarts: int = 0) -> PlanResult:
        """The result when :meth:`_initial_roots` could not draw its roots (``why``)."""
        what, side = why.split(":")
        extra = {**self._extra(), "restarts": restarts}
        if what == "limit":
            reason = (
                f"iteration limit reached: no valid start/goal pair in "
                f"{self.search_params.max_iterations} draws (max_iterations)"
            )
            return PlanResult(PlanStatus.ITERATION_LIMIT, reason, extra=extra)
        if what == "exhausted":
            tries = self._start_tries()
            each = f" for each of {tries} start roots" if side == "goal" and tries > 1 else ""
            reason = (
                f"no {side} configuration: {self.max_root_draws} draws from C_{side[0]}{each} "
                "all failed (IK, manifold checks or collisions)"
            )
            return PlanResult(PlanStatus.INFEASIBLE, reason, extra=extra)
        reason = f"time budget exhausted while drawing the {side}"
        return PlanResult(PlanStatus.TIMEOUT, reason, extra=extra)

    def finish_path(self, raw: np.ndarray, deadline: float, hard: float) -> np.ndarray:
        """A found slide shortcut (until ``deadline``) and densified by projection (until
        ``hard``); raises :class:`OutOfTime` or :class:`DensifyError` as those do."""
        p = self.problem.params
        fns = self.functions(start=False, goal=False)
        path = shortcut_path(raw, fns, self.search_params, self.rng, p.shortcut_attempts, deadline)
        return densify(path, p.path_resolution, self._dense_project(hard), self.tip_distance)

    def _dense_project(self, hard: float):
        def project(q: np.ndarray, q_near: np.ndarray) -> np.ndarray | None:
            if time.perf_counter() >= hard:
                raise OutOfTime("densifying the path ran out of time")
            q = self.constraints.project(q, q_near)
            return None if q is None or self.collides(q) else q

        return project

    def _solved(
        self, res: PlanResult, dense: np.ndarray, failures: int, restarts: int
    ) -> PlanResult:
        info = res.extra.pop("pair_info")
        extra = {
            **self._extra(),
            **res.extra,
            "object_goal_pose": np.asarray(info["object_goal_pose"]).tolist(),
            "overhang_m": float(info["overhang_m"]),
            "edge": np.asarray(info["edge"]).tolist(),
            "grasp_config": np.asarray(info["grasp_config"]).tolist(),
            "transfer_path": np.asarray(info["transfer_path"]).tolist(),
            "raw_path_length": len(res.path),
            "densify_failures": failures,
            "restarts": restarts,
        }
        return PlanResult(
            PlanStatus.SOLVED, None, res.start_config, res.goal_config, dense, extra=extra
        )

    def _extra(self) -> dict[str, Any]:
        prob = self.problem
        params = prob.params.as_dict()
        params["contact_height_range"] = list(prob.height_range)
        params["max_root_draws"] = self.max_root_draws
        return {
            "planner": self.name,
            "seed": self.seed,
            "fixed_start": self.start_config is not None or self._bad_start is not None,
            **prob.describe(),
            "parameters": params,
            "validator_counts": dict(self.validator.counts),
            "region_draws": {
                "start": [self.start_region.draws, self.start_region.accepted],
                "goal": [self.goal_region.draws, self.goal_region.accepted],
            },
        }

    def close(self) -> None:
        """Release the private collision world (safe to call twice)."""
        self.checker.close()

    def __enter__(self) -> TopSlidePlanner:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
