"""CBiRRT with sampleable regions (Algorithm 1) on forests, and its CBiRRT/CBiRRT2 variants.

The robot-specific parts (sampling, projection onto the constraint manifold, collision and
pair validation) are plain callables in :class:`SearchFunctions`. The three planners differ
only in which roots are fixed and how many roots each forest may sample.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from slide_gym.planning.forest import Forest, check_weights
from slide_gym.planning.result import (
    Planner,
    PlannerStats,
    PlanResult,
    PlanStatus,
    SearchParams,
    timed,
)

Config = np.ndarray
RootSampler = Callable[[np.random.Generator], np.ndarray | None]
PLANNERS: tuple[str, ...] = ("regions", "cbirrt2", "cbirrt", "cbirrt-norestart")
"""The planner names (one list for the whole project): the paper's planner, the two
baselines, and ``cbirrt`` without restarts (its first validated pair for the whole budget),
kept for reference."""
REFERENCE_PLANNERS: tuple[str, ...] = ("ompl",)
"""Planners from outside libraries, not built on this search core: ``"ompl"`` is OMPL's
RRTConnect on our manifold (:mod:`slide_gym.planning.ompl_reference`, the ``ompl`` extra);
:func:`slide_gym.planning.runner.plan_once` and ``slide-gym plan`` accept them."""
PAIR_PLANNERS = ("cbirrt", "cbirrt-norestart")
"""The planners that search between one given start and one given goal configuration."""
_SIDES = ("start", "goal")
# A projection that lands this many steps away from its parent has most likely jumped to
# another part of the manifold; such an edge would not be a valid local motion.
_MAX_JUMP = 2.0


def _accept_pair(q_start: Config, q_goal: Config) -> tuple[bool, Any]:
    return True, None


@dataclass(frozen=True)
class SearchFunctions:
    """Problem callables. Root samplers return configurations in their region (or None)."""

    sample_config: Callable[[np.random.Generator], Config]
    project: Callable[[Config, Config], Config | None]
    collides: Callable[[Config], bool]
    pair_valid: Callable[[Config, Config], tuple[bool, Any]] = _accept_pair
    sample_start_root: RootSampler | None = None
    sample_goal_root: RootSampler | None = None
    motion_valid: Callable[[Config, Config], bool] | None = None
    distance_weights: Sequence[float] | np.ndarray | None = None
    pair_feasible: Callable[[Config, Config], bool] | None = None
    """A quick necessary condition of ``pair_valid`` on two roots: a tree pair it refuses is
    never connected (the search grows toward the nearest tree it does not refuse)."""


def can_add_root(n_start: int, n_goal: int, n_star: int, rng: np.random.Generator) -> bool:
    """Eq. 5: add a root with probability ``exp(-(n_start + n_goal) / n_star)``."""
    return math.exp(-(n_start + n_goal) / n_star) > rng.random()


def timed_functions(fns: SearchFunctions, stats: PlannerStats) -> SearchFunctions:
    """A copy of ``fns`` whose callables add their run time to ``stats``."""
    return replace(
        fns,
        sample_config=timed(fns.sample_config, stats, "time_sampling_s"),
        project=timed(fns.project, stats, "time_projection_s"),
        collides=timed(fns.collides, stats, "time_collision_s"),
        pair_valid=timed(fns.pair_valid, stats, "time_validation_s"),
        sample_start_root=timed(fns.sample_start_root, stats, "time_sampling_s"),
        sample_goal_root=timed(fns.sample_goal_root, stats, "time_sampling_s"),
        motion_valid=timed(fns.motion_valid, stats, "time_collision_s"),
        pair_feasible=timed(fns.pair_feasible, stats, "time_validation_s"),
    )


def constrained_extend(
    forest: Forest,
    node_idx: int,
    target: Config,
    fns: SearchFunctions,
    step: float,
    *,
    tolerance: float,
    max_steps: int = 500,
    deadline: float = math.inf,
) -> tuple[int, bool]:
    """CBiRRT's ConstrainedExtend from ``node_idx`` toward ``target``.

    Every accepted intermediate state becomes a node. Returns the last node reached and
    whether it lies within ``tolerance`` of ``target``.
    """
    target = np.asarray(target, dtype=float)
    cur_idx = node_idx
    cur = forest.config(node_idx)
    d_cur = forest.distance(cur, target)
    for _ in range(max_steps):
        if d_cur <= tolerance or time.perf_counter() >= deadline:
            break
        q = fns.project(cur + min(1.0, step / d_cur) * (target - cur), cur)
        if q is None:
            break
        q = np.asarray(q, dtype=float)
        d_new = forest.distance(q, target)
        if not d_new < d_cur or forest.distance(q, cur) > _MAX_JUMP * step:
            break
        if fns.collides(q) or (fns.motion_valid is not None and not fns.motion_valid(cur, q)):
            break
        cur_idx = forest.add_node(q, cur_idx)
        cur, d_cur = q, d_new
    return cur_idx, d_cur <= tolerance


def _extract_path(fa: Forest, a_idx: int, fb: Forest, b_idx: int, a_is_start: bool) -> Config:
    """Root of a ... a_idx, b_idx ... root of b, oriented from the start root to the goal root."""
    head = fa.path_to_root(a_idx)[::-1]
    tail = fb.path_to_root(b_idx)
    if np.array_equal(head[-1], tail[0]):
        tail = tail[1:]
    path = np.concatenate([head, tail])
    return path if a_is_start else path[::-1].copy()


def _infer_dim(fns: SearchFunctions, weights: Any, roots: Sequence[Any], rng: Any) -> int:
    if weights is not None:
        return len(weights)
    if len(roots):
        return int(np.asarray(roots[0]).size)
    return int(np.asarray(fns.sample_config(rng)).size)


def forest_connect_search(
    fns: SearchFunctions,
    params: SearchParams,
    rng: np.random.Generator,
    deadline: float,
    stats: PlannerStats,
    start_roots: Sequence[Config] = (),
    goal_roots: Sequence[Config] = (),
    *,
    max_start_roots: int | None = None,
    max_goal_roots: int | None = None,
) -> PlanResult:
    """Algorithm 1 with a start forest and a goal forest, until solved or ``deadline``.

    Fixed roots are added first (colliding ones are dropped); afterwards each forest may sample
    roots (Eq. 5) until it holds ``max_*_roots`` trees. Connected start/goal tree pairs that
    ``pair_valid`` rejected are never connected or validated again.

    Stops with ``ITERATION_LIMIT`` once ``stats.iterations`` reaches
    ``params.max_iterations`` (a ``stats`` shared by several calls shares the cap), and with
    ``TIMEOUT`` once ``deadline`` has passed, checked first: an iteration the deadline cut
    short always ends in ``TIMEOUT`` (a give-up), so every other outcome is the same on any
    machine.
    """
    fns = timed_functions(fns, stats)
    raw_w = params.distance_weights if params.distance_weights is not None else fns.distance_weights
    dim = _infer_dim(fns, raw_w, [*start_roots, *goal_roots], rng)
    weights = check_weights(raw_w, dim)
    forests = (Forest(dim, weights), Forest(dim, weights))
    samplers = (fns.sample_start_root, fns.sample_goal_root)
    caps = (max_start_roots, max_goal_roots)
    n_dropped = [0, 0]
    for k, roots in enumerate((start_roots, goal_roots)):
        for q in roots:
            q = np.asarray(q, dtype=float)
            if q.shape != (dim,):
                raise ValueError(f"{_SIDES[k]} root must have shape ({dim},), got {q.shape}")
            if fns.collides(q):
                n_dropped[k] += 1
            else:
                forests[k].add_root(q)
    # rejected[k][tree] = trees of the other forest whose pair with `tree` failed pair_valid
    # (or pair_feasible); feasible: (start tree, goal tree) pairs pair_feasible let through
    rejected: tuple[dict[int, set[int]], dict[int, set[int]]] = ({}, {})
    feasible: set[tuple[int, int]] = set()
    n_rejected = n_refused = 0  # n_rejected counts the refused pairs too
    last_info: Any = None
    tol, step, steps = params.goal_tolerance, params.step_size, params.max_extend_steps

    def can_grow(k: int) -> bool:
        return samplers[k] is not None and (caps[k] is None or forests[k].n_trees < caps[k])

    def reject(trees: tuple[int, int]) -> None:
        nonlocal n_rejected
        n_rejected += 1
        rejected[0].setdefault(trees[0], set()).add(trees[1])
        rejected[1].setdefault(trees[1], set()).add(trees[0])

    def nearest_allowed(a: int, q: Config, tree_a: int) -> tuple[int, int] | None:
        """The other forest's nearest (tree, node) to ``q`` whose tree may pair with
        ``tree_a`` (not rejected, not refused by ``pair_feasible``)."""
        nonlocal n_refused
        fb = forests[1 - a]
        while (hit := fb.nearest(q, rejected[a].get(tree_a, ()))) is not None:
            trees = (tree_a, hit[0]) if a == 0 else (hit[0], tree_a)
            if fns.pair_feasible is None or trees in feasible:
                return hit
            roots = forests[0].root_config(trees[0]), forests[1].root_config(trees[1])
            if fns.pair_feasible(*roots):
                feasible.add(trees)
                return hit
            n_refused += 1
            stats.pairs_refused += 1
            reject(trees)
        return None

    def finish(status: PlanStatus, reason: str | None, **out: Any) -> PlanResult:
        stats.tree_nodes = forests[0].n_nodes + forests[1].n_nodes
        extra = {"n_start_trees": forests[0].n_trees, "n_goal_trees": forests[1].n_trees}
        extra.update(out.pop("extra", {}))
        return PlanResult(status, reason, stats=stats, extra=extra, **out)

    a = 0
    while True:
        for k in (0, 1):
            if forests[k].n_trees == 0 and not can_grow(k):
                dropped = f" ({n_dropped[k]} given roots collide)" if n_dropped[k] else ""
                return finish(
                    PlanStatus.INFEASIBLE,
                    f"no valid {_SIDES[k]} root and none can be sampled" + dropped,
                )
        if (
            not (can_grow(0) or can_grow(1))
            and n_rejected == forests[0].n_trees * forests[1].n_trees
        ):
            return finish(
                PlanStatus.INFEASIBLE,
                f"all {n_rejected} start/goal root pairs were rejected by pair_valid "
                f"({n_refused} of them by pair_feasible) and no more roots can be added",
                extra={"last_pair_info": last_info},
            )
        if time.perf_counter() >= deadline:
            return finish(
                PlanStatus.TIMEOUT,
                f"time budget exhausted after {stats.iterations} iterations "
                f"({forests[0].n_trees} start / {forests[1].n_trees} goal trees, "
                f"{n_rejected - n_refused} connected pairs rejected, {n_refused} refused)",
                extra={"last_pair_info": last_info},
            )
        if params.max_iterations is not None and stats.iterations >= params.max_iterations:
            return finish(
                PlanStatus.ITERATION_LIMIT,
                f"iteration limit reached: {stats.iterations} iterations "
                f"(max_iterations={params.max_iterations}; {forests[0].n_trees} start / "
                f"{forests[1].n_trees} goal trees, {n_rejected - n_refused} connected pairs "
                f"rejected, {n_refused} refused)",
                extra={"last_pair_info": last_info},
            )
        stats.iterations += 1
        fa, fb = forests[a], forests[1 - a]
        if can_grow(a) and (
            fa.n_trees == 0
            or can_add_root(forests[0].n_trees, forests[1].n_trees, params.n_star, rng)
        ):
            q = samplers[a](rng)
            if q is not None and not fns.collides(np.asarray(q, dtype=float)):
                fa.add_root(q)
                counter = f"roots_added_{_SIDES[a]}"
                setattr(stats, counter, getattr(stats, counter) + 1)
        if fa.n_nodes > 0:
            q_rand = np.asarray(fns.sample_config(rng), dtype=float)
            _, near = fa.nearest(q_rand)
            a_idx, _ = constrained_extend(
                fa, near, q_rand, fns, step, tolerance=tol, max_steps=steps, deadline=deadline
            )
            q_a, tree_a = fa.config(a_idx), fa.tree_of(a_idx)
            hit = nearest_allowed(a, q_a, tree_a)
            if hit is not None:
                b_idx, reached = constrained_extend(
                    fb, hit[1], q_a, fns, step, tolerance=tol, max_steps=steps, deadline=deadline
                )
                if reached and time.perf_counter() < deadline:
                    trees = (tree_a, hit[0]) if a == 0 else (hit[0], tree_a)
                    q_s, q_g = forests[0].root_config(trees[0]), forests[1].root_config(trees[1])
                    ok, last_info = fns.pair_valid(q_s, q_g)
                    stats.pairs_validated += 1
                    if ok:
                        path = _extract_path(fa, a_idx, fb, b_idx, a_is_start=a == 0)
                        return finish(
                            PlanStatus.SOLVED,
                            None,
                            start_config=q_s,
                            goal_config=q_g,
                            path=path,
                            extra={"pair_info": last_info, "trees": trees},
                        )
                    stats.pairs_rejected += 1
                    reject(trees)
        a = 1 - a


class ForestConnectPlanner(Planner):
    """One of ``PLANNERS`` as a configuration of :func:`forest_connect_search`.

    * ``regions``: both forests sample roots (``start``/``goal`` are optional extra roots).
    * ``cbirrt2``: one start root (``start``, else sampled once); goal roots sampled.
    * ``cbirrt``, ``cbirrt-norestart``: one start root and one goal root (given, else sampled
      once); nothing else (restarts are the caller's: a new planner per pair).
    """

    def __init__(
        self,
        kind: str,
        fns: SearchFunctions,
        params: SearchParams,
        rng: np.random.Generator,
        *,
        start: Config | None = None,
        goal: Config | None = None,
    ):
        if kind not in PLANNERS:
            raise ValueError(f"kind must be one of {PLANNERS}, got {kind!r}")
        if not isinstance(rng, np.random.Generator):
            raise TypeError("rng must be a numpy.random.Generator (np.random.default_rng(seed))")
        single = {"regions": (False, False), "cbirrt2": (True, False)}
        single |= {name: (True, True) for name in PAIR_PLANNERS}
        fixed = (start, goal)
        self.caps = tuple(1 if single[kind][k] else None for k in (0, 1))
        self.roots = tuple(() if q is None else (np.asarray(q, dtype=float),) for q in fixed)
        samplers = [fns.sample_start_root, fns.sample_goal_root]
        for k in (0, 1):
            if single[kind][k] and fixed[k] is not None:
                samplers[k] = None  # a fixed single root: never sample on this side
            if samplers[k] is None and (fixed[k] is None or not single[kind][k]):
                raise ValueError(
                    f"the {kind} planner needs fns.sample_{_SIDES[k]}_root"
                    + (f" or a fixed {_SIDES[k]} configuration" if single[kind][k] else "")
                )
        self.name = kind
        self.fns = replace(fns, sample_start_root=samplers[0], sample_goal_root=samplers[1])
        self.params = params
        self.rng = rng

    def _solve(self, deadline: float, stats: PlannerStats) -> PlanResult:
        return forest_connect_search(
            self.fns,
            self.params,
            self.rng,
            deadline,
            stats,
            *self.roots,
            max_start_roots=self.caps[0],
            max_goal_roots=self.caps[1],
        )


class DensifyError(RuntimeError):
    """A path segment could not be subdivided on the constraint manifold."""


def densify(
    path: np.ndarray,
    max_step: float,
    project: Callable[[Config, Config], Config | None],
    metric: Callable[[Config, Config], float],
    max_depth: int = 12,
) -> np.ndarray:
    """Insert projected states so that ``metric`` between neighbours is at most ``max_step``.

    ``project(q, q_near)`` should return None for invalid states (off-manifold, colliding);
    a None raises :class:`DensifyError`, as does a segment still too long after ``max_depth``
    rounds of subdivision. The original configurations are kept.
    """
    path = np.asarray(path, dtype=float)
    if path.ndim != 2 or len(path) == 0:
        raise ValueError(f"path must be a non-empty (m, dim) array, got shape {path.shape}")
    if not (math.isfinite(max_step) and max_step > 0):
        raise ValueError(f"max_step must be a finite positive number, got {max_step}")

    limit = max_step * (1 + 1e-9)  # equal pieces may exceed max_step by rounding only

    def refine(a: Config, b: Config, depth: int) -> list[Config]:
        dist = metric(a, b)
        if dist <= limit:
            return [b]
        if depth == 0:
            raise DensifyError(f"segment still {dist:.4g} > {max_step} after subdivision")
        n = math.ceil(dist / max_step)
        out: list[Config] = []
        prev = a
        for i in range(1, n):
            q = project(a + (i / n) * (b - a), prev)
            if q is None:
                raise DensifyError(f"projection failed between path states (piece {i}/{n})")
            q = np.asarray(q, dtype=float)
            out += refine(prev, q, depth - 1)
            prev = q
        return out + refine(prev, b, depth - 1)

    dense = [path[0]]
    for b in path[1:]:
        dense += refine(dense[-1], b, max_depth)
    return np.array(dense)
