"""OMPL as an outside reference planner (``"ompl"``, the optional ``ompl`` extra).

OMPL 2.0's constrained planning on our manifold: ``ob.ProjectedStateSpace`` over the 7 arm
joints (bounds: the joint limits our planner uses) with an ``ob.Constraint`` whose
``function``/``jacobian`` are :class:`~slide_gym.planning.constraints.SlideConstraints`'
residuals and whose ``project`` is our own Newton projection (the contact band is an
inequality, which OMPL's equality projection would pin to its centre), a state validity
checker (on the relaxed manifold and collision-free in ``"sliding"`` mode), and
``og.RRTConnect``. The start is one configuration drawn from C_s (as ``cbirrt2`` draws it);
the goal is an ``ob.GoalSampleableRegion`` whose samples are drawn from C_g and kept only
if pair validation accepts (start, goal), so a found path leaves the plate graspable.

The path is shortcut and densified with the same helpers as :class:`TopSlidePlanner`, and
the result has the same ``extra`` fields. OMPL's own metric is the unweighted joint
distance, with its default delta, lambda and RRTConnect range.
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable, Sequence
from types import SimpleNamespace
from typing import Any

import numpy as np

from slide_gym.planning.problem import TopSlideProblem
from slide_gym.planning.result import OutOfTime, PlannerStats, PlanResult, PlanStatus
from slide_gym.planning.search import DensifyError
from slide_gym.planning.top_slide import TopSlidePlanner
from slide_gym.robot.model import ARM_LOWER, ARM_UPPER

MISSING_OMPL = "planner 'ompl' needs the optional OMPL bindings: pip install 'slide-gym[ompl]'"
_DIM = 7
_NO_GOAL = (np.asarray(ARM_UPPER, dtype=float) + 1.0).tolist()  # out of bounds: OMPL skips it


@functools.cache
def ompl_types() -> SimpleNamespace:
    """OMPL's modules and our subclasses of its types; ValueError if OMPL is missing."""
    try:
        from ompl import base as ob
        from ompl import geometric as og
        from ompl import util as ou
    except ImportError as err:
        raise ValueError(MISSING_OMPL) from err

    class SlideConstraint(ob.Constraint):
        """Our residuals (roll, pitch band, depth band), their Jacobian and our projection."""

        def __init__(self, planner: OmplReferencePlanner):
            super().__init__(_DIM, 3, planner.constraints.tolerance)
            self.planner = planner

        def function(self, x: np.ndarray, out: np.ndarray) -> None:
            cons = self.planner.constraints
            out[:] = cons.residuals(cons.chain.forward(np.array(x)))

        def jacobian(self, x: np.ndarray, out: np.ndarray) -> None:
            cons = self.planner.constraints
            out[:] = cons.residual_jacobian(*cons.chain.jacobian(np.array(x)))

        def project(self, x: np.ndarray) -> bool:
            q = self.planner._ompl_project(np.array(x))
            if q is None:
                return False
            x[:] = q
            return True

    class ValidatedGoals(ob.GoalSampleableRegion):
        """Goal states drawn from C_g, each kept only if pair validation accepts it."""

        def __init__(self, si: Any, sample: Callable[[], list[float]], goals: list):
            super().__init__(si)
            self.sample, self.goals = sample, goals

        def sampleGoal(self, state: Any) -> None:  # noqa: N802 (OMPL's names)
            state.copy(self.sample())

        def maxSampleCount(self) -> int:  # noqa: N802
            return 2**31 - 1

        def distanceGoal(self, state: Any) -> float:  # noqa: N802
            q = _config(state)
            return min((float(np.linalg.norm(q - g)) for g in self.goals), default=math.inf)

    return SimpleNamespace(
        ob=ob, og=og, ou=ou, SlideConstraint=SlideConstraint, ValidatedGoals=ValidatedGoals
    )


def _config(state: Any) -> np.ndarray:
    return np.array([state[i] for i in range(_DIM)])


class OmplReferencePlanner(TopSlidePlanner):
    """OMPL's RRTConnect on our manifold, regions and pair validation (``"ompl"``).

    Random states: OMPL's ``ProjectedStateSampler`` draws a uniform joint vector and keeps it
    even when the projection fails; on our manifold most such draws fail (97 % of 500 on a
    fig11 problem: the contact must land over the table), and RRTConnect never reaches an
    off-manifold target, so its trees barely grow. RRTConnect checks its termination
    condition and then draws its random state, so the first projection after each check is
    the sampler's: when it fails, up to ``sampler_attempts`` fresh uniform draws (from the
    planner's Generator) are projected instead, the rejection sampling of OMPL's
    ``ProjectedValidStateSampler`` (``sampler_attempts=0``: OMPL's sampler as it is).

    Determinism: each solve seeds OMPL's RNG (``ou.RNG.setSeed``) from the planner's numpy
    Generator, once, before it builds OMPL's objects. That seed is process-global (every
    OMPL object created afterwards draws from it), so plans repeat only while no other
    OMPL planning runs in the process meanwhile. OMPL's log output is off during a solve.

    ``SlideParams.max_iterations`` does not apply (RRTConnect has no iteration cap);
    ``stats.iterations`` counts OMPL's termination-condition checks, about one per
    RRTConnect iteration. ``range_``: RRTConnect's range (None: OMPL's default).
    """

    def __init__(
        self,
        problem: TopSlideProblem,
        seed: int | Sequence[int] | np.random.Generator | None = None,
        range_: float | None = None,
        sampler_attempts: int = 100,
    ):
        ompl_types()  # fail before building the collision world
        super().__init__(problem, "cbirrt2", seed)
        self.name = "ompl"
        self.range = range_
        self.sampler_attempts = int(sampler_attempts)
        self._stats = PlannerStats()
        self._deadline = math.inf
        self._fresh = False  # the next projection is the sampler's

    # ------------------------------------------------------ OMPL's callables
    def _ompl_project(self, x: np.ndarray) -> np.ndarray | None:
        """Our projection of ``x``; for the sampler's call, rejection sampling on failure."""
        t0 = time.perf_counter()
        if t0 >= self._deadline:
            return None  # ends a manifold traversal that OMPL would not interrupt
        q = self.project(x)
        if q is None and self._fresh:
            for _ in range(self.sampler_attempts):
                q = self.project(self.rng.uniform(ARM_LOWER, ARM_UPPER))
                if q is not None:
                    break
        self._fresh = False
        self._stats.time_projection_s += time.perf_counter() - t0
        return q

    def _valid(self, state: Any) -> bool:
        """On the relaxed manifold (checks included) and collision-free."""
        t0 = time.perf_counter()
        q = _config(state)
        ok = t0 < self._deadline and bool(np.isfinite(q).all() and self.constraints.satisfied(q))
        ok = ok and not self.collides(q)
        self._stats.time_collision_s += time.perf_counter() - t0
        return ok

    def _stop(self) -> bool:
        self._stats.iterations += 1
        self._fresh = True
        return time.perf_counter() >= self._deadline

    def _sample_goal(self, q_s: np.ndarray, goals: list[np.ndarray]) -> list[float]:
        """One draw from C_g, kept if pair validation accepts it with ``q_s``."""
        stats = self._stats
        q = self._draw(self.goal_region, self._deadline, stats)
        if isinstance(q, str):
            return _NO_GOAL
        t0 = time.perf_counter()
        ok, _ = self.pair_valid(q_s, q)
        stats.time_validation_s += time.perf_counter() - t0
        stats.pairs_validated += 1
        if not ok:
            stats.pairs_rejected += 1
            return _NO_GOAL
        goals.append(q)
        stats.roots_added_goal += 1
        return q.tolist()

    # ---------------------------------------------------------------- solve
    def _solve(self, deadline: float, stats: PlannerStats) -> PlanResult:
        budget = deadline - time.perf_counter()
        hard = deadline + 0.04 * budget
        search_deadline = deadline - min(0.05 * budget, 0.25)
        self._stats, self._deadline, self._fresh = stats, search_deadline, False
        self.validator.deadline = search_deadline
        self.start_region.deadline = self.goal_region.deadline = search_deadline
        bad = self._infeasible()
        if bad is not None:
            return bad
        ompl_seed = int(self.rng.integers(1, 2**31))
        q_s = self._draw(self.start_region, search_deadline, stats)
        if isinstance(q_s, str):
            return self._no_roots(f"{q_s}:start")
        stats.roots_added_start = 1
        t = ompl_types()
        level = t.ou.getLogLevel()
        t.ou.setLogLevel(t.ou.LOG_NONE)
        try:
            t.ou.RNG.setSeed(ompl_seed)
            return self._search(t, q_s, hard)
        finally:
            t.ou.setLogLevel(level)

    def _search(self, t: SimpleNamespace, q_s: np.ndarray, hard: float) -> PlanResult:
        """Build OMPL's problem, solve it, post-process the path; the SimpleSetup dies here."""
        stats, deadline = self._stats, self._deadline
        space = t.ob.RealVectorStateSpace(_DIM)
        bounds = t.ob.RealVectorBounds(_DIM)
        for i in range(_DIM):
            bounds.setLow(i, float(ARM_LOWER[i]))
            bounds.setHigh(i, float(ARM_UPPER[i]))
        space.setBounds(bounds)
        css = t.ob.ProjectedStateSpace(space, t.SlideConstraint(self))
        csi = t.ob.ConstrainedSpaceInformation(css)
        ss = t.og.SimpleSetup(csi)
        ss.setStateValidityChecker(self._valid)
        start = css.allocState()
        start.copy(q_s.tolist())
        ss.setStartState(start)
        goals: list[np.ndarray] = []
        ss.setGoal(t.ValidatedGoals(csi, lambda: self._sample_goal(q_s, goals), goals))
        rrt = t.og.RRTConnect(csi)
        if self.range is not None:
            rrt.setRange(float(self.range))
        ss.setPlanner(rrt)
        exact = t.ob.PlannerStatus.PlannerStatusType.EXACT_SOLUTION
        failures = 0
        try:
            ss.setup()
            while True:
                status = ss.solve(t.ob.PlannerTerminationCondition(self._stop))
                data = t.ob.PlannerData(csi)
                rrt.getPlannerData(data)
                stats.tree_nodes = data.numVertices()
                extra = {
                    **self._extra(),
                    "ompl_status": status.asString(),
                    "n_goals": len(goals),
                    "densify_failures": failures,
                    "restarts": 0,
                }
                if status.getStatus() != exact:
                    if time.perf_counter() < deadline:
                        reason = f"OMPL's RRTConnect stopped: {status.asString()}"
                        return PlanResult(PlanStatus.INFEASIBLE, reason, extra=extra)
                    reason = (
                        f"time budget exhausted after {stats.iterations} OMPL iterations "
                        f"({len(goals)} validated goals, {stats.pairs_rejected} rejected)"
                    )
                    return PlanResult(PlanStatus.TIMEOUT, reason, extra=extra)
                raw = np.array([_config(s) for s in ss.getSolutionPath().getStates()])
                try:
                    dense = self.finish_path(raw, deadline, hard)
                except OutOfTime:
                    reason = (
                        "found a path but shortcutting and densifying it did not fit in the budget"
                    )
                    return PlanResult(PlanStatus.TIMEOUT, reason, extra=extra)
                except DensifyError:
                    if time.perf_counter() >= deadline:
                        reason = "found a path but densifying it did not fit in the time budget"
                        return PlanResult(PlanStatus.TIMEOUT, reason, extra=extra)
                    failures += 1
                    ss.getProblemDefinition().clearSolutionPaths()
                    continue  # RRTConnect keeps its trees and looks for another connection
                ok, info = self.pair_valid(q_s, raw[-1])  # remembered from the goal's draw
                if not ok:
                    raise RuntimeError("OMPL's path ends at a goal that pair validation rejected")
                extra["pair_info"] = info
                res = PlanResult(PlanStatus.SOLVED, None, q_s, raw[-1], raw, extra=extra)
                return self._solved(res, dense, failures, 0)
        finally:
            del ss  # before OMPL's other objects (nanobind reports leaks otherwise)
