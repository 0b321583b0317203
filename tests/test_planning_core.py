"""Tests of slide_gym.planning on a toy 2-D constrained problem (no robot needed)."""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import time

import numpy as np
import pytest

from slide_gym.planning import (
    DensifyError,
    Forest,
    ForestConnectPlanner,
    PlanStatus,
    SearchFunctions,
    SearchParams,
    can_add_root,
    constrained_extend,
    densify,
)

STEP = 0.05
BAND = (0.2, 0.8)  # the "manifold": |y - 0.5| <= 0.3
WALL_X = (0.45, 0.55)
GAP_Y = (0.6, 0.7)
START_C, START_R = np.array([0.1, 0.5]), 0.05
GOAL_C, GOAL_R = np.array([0.9, 0.5]), 0.08


def on_manifold(q: np.ndarray) -> bool:
    return BAND[0] - 1e-12 <= q[1] <= BAND[1] + 1e-12 and 0.0 <= q[0] <= 1.0


def collides_gap(q: np.ndarray) -> bool:
    in_wall = WALL_X[0] <= q[0] <= WALL_X[1]
    return bool(in_wall and not GAP_Y[0] <= q[1] <= GAP_Y[1])


def collides_closed(q: np.ndarray) -> bool:
    return bool(WALL_X[0] <= q[0] <= WALL_X[1])


def project(q: np.ndarray, q_near: np.ndarray) -> np.ndarray:
    return np.array([np.clip(q[0], 0.0, 1.0), np.clip(q[1], *BAND)])


def disc_sampler(center: np.ndarray, radius: float):
    def sample(rng: np.random.Generator) -> np.ndarray:
        rho, theta = radius * math.sqrt(rng.random()), 2 * math.pi * rng.random()
        return center + rho * np.array([math.cos(theta), math.sin(theta)])

    return sample


def segment_free(collides):
    def motion_valid(a: np.ndarray, b: np.ndarray) -> bool:
        return not any(collides(a + t * (b - a)) for t in np.linspace(0.0, 1.0, 11)[1:-1])

    return motion_valid


def pair_valid(q_start: np.ndarray, q_goal: np.ndarray) -> tuple[bool, dict]:
    return bool(q_goal[0] > 0.9), {"goal_x": float(q_goal[0])}


def toy_fns(collides=collides_gap) -> SearchFunctions:
    return SearchFunctions(
        sample_config=lambda rng: rng.uniform(0.0, 1.0, 2),
        project=project,
        collides=collides,
        motion_valid=segment_free(collides),
        pair_valid=pair_valid,
        sample_start_root=disc_sampler(START_C, START_R),
        sample_goal_root=disc_sampler(GOAL_C, GOAL_R),
    )


PARAMS = SearchParams(step_size=STEP, n_star=20)
BUDGET = 60.0  # s: far more than any toy query needs (they end in well under 1 s)


def solve(kind: str, seed: int, budget: float = BUDGET, fns=None, **roots):
    planner = ForestConnectPlanner(
        kind, fns or toy_fns(), PARAMS, np.random.default_rng(seed), **roots
    )
    return planner.solve(budget)


def test_regions_planner_solves_toy_problem():
    res = solve("regions", seed=0)
    assert res.status is PlanStatus.SOLVED, res.reason
    path = res.path
    assert path.ndim == 2 and path.shape[1] == 2 and len(path) > 10
    assert all(on_manifold(q) and not collides_gap(q) for q in path)
    assert all(segment_free(collides_gap)(a, b) for a, b in zip(path[:-1], path[1:], strict=True))
    steps = np.linalg.norm(np.diff(path, axis=0), axis=1)
    assert steps.max() <= STEP + 1e-12
    np.testing.assert_array_equal(path[0], res.start_config)
    np.testing.assert_array_equal(path[-1], res.goal_config)
    assert np.linalg.norm(res.start_config - START_C) <= START_R
    assert np.linalg.norm(res.goal_config - GOAL_C) <= GOAL_R
    assert pair_valid(res.start_config, res.goal_config)[0]
    assert res.extra["pair_info"]["goal_x"] > 0.9
    s = res.stats
    assert s.roots_added_start == res.extra["n_start_trees"] >= 1
    assert s.roots_added_goal == res.extra["n_goal_trees"] >= 1
    assert s.pairs_validated == s.pairs_rejected + 1
    assert s.time_projection_s > 0 and s.time_collision_s > 0
    assert s.time_total_s >= s.time_projection_s + s.time_collision_s
    doc = json.loads(json.dumps(res.to_json_dict()))
    assert doc["status"] == "solved" and len(doc["path"]) == len(path)


def test_can_add_root_matches_eq5():
    rng = np.random.default_rng(7)
    n, n_star = 20000, 50
    rate = np.mean([can_add_root(30, 20, n_star, rng) for _ in range(n)])
    p = math.exp(-1.0)
    assert abs(rate - p) < 3 * math.sqrt(p * (1 - p) / n)
    assert all(can_add_root(0, 0, n_star, rng) for _ in range(100))


def test_same_seed_is_deterministic_and_seeds_differ():
    a, b, c = (solve("regions", seed) for seed in (3, 3, 4))
    assert a.status is b.status is c.status is PlanStatus.SOLVED
    np.testing.assert_array_equal(a.path, b.path)
    assert a.stats.counts() == b.stats.counts()
    assert a.path.shape != c.path.shape or not np.array_equal(a.path, c.path)


def test_walled_off_goal_times_out_at_its_budget(monkeypatch):
    # A fake clock that advances 0.1 ms per reading: the search sees its deadline pass after
    # a fixed amount of work however loaded the machine is, and the overrun counts readings.
    tick = 1e-4
    readings = itertools.count()
    monkeypatch.setattr(time, "perf_counter", lambda: next(readings) * tick)
    budget = 0.3
    res = solve("regions", seed=1, budget=budget, fns=toy_fns(collides_closed))
    assert res.status is PlanStatus.TIMEOUT and res.path is None
    assert "time budget" in res.reason
    # it searched until the deadline and then stopped within a few clock readings
    assert budget <= res.stats.time_total_s <= 1.05 * budget
    assert res.stats.iterations > 10 and res.stats.pairs_validated == 0


def test_walled_off_goal_stops_at_its_iteration_cap_with_no_deadline():
    params = SearchParams(step_size=STEP, n_star=20, max_iterations=60)
    planner = ForestConnectPlanner(
        "regions", toy_fns(collides_closed), params, np.random.default_rng(1)
    )
    res = planner.solve_until(math.inf)  # only the count can stop it
    assert res.status is PlanStatus.ITERATION_LIMIT and res.path is None
    assert res.stats.iterations == 60 and "iteration limit" in res.reason
    assert res.to_json_dict()["status"] == "iteration_limit"
    again = ForestConnectPlanner(
        "regions", toy_fns(collides_closed), params, np.random.default_rng(1)
    ).solve(BUDGET)
    assert again.stats.counts() == res.stats.counts()
    with pytest.raises(ValueError, match="max_iterations"):
        SearchParams(step_size=STEP, max_iterations=0)


@pytest.mark.parametrize("budget", [0.0, -1.0, math.nan, math.inf, "1", True, None])
def test_bad_budget_raises(budget):
    planner = ForestConnectPlanner("regions", toy_fns(), PARAMS, np.random.default_rng(0))
    with pytest.raises(ValueError, match="time_budget"):
        planner.solve(budget)


def test_cbirrt_and_cbirrt2_report_roots():
    start, goal = np.array([0.1, 0.5]), np.array([0.95, 0.5])
    one = solve("cbirrt", seed=2, start=start, goal=goal)
    assert one.status is PlanStatus.SOLVED, one.reason
    assert one.stats.roots_added_start == one.stats.roots_added_goal == 0
    assert one.extra["n_start_trees"] == one.extra["n_goal_trees"] == 1
    np.testing.assert_array_equal(one.path[0], start)
    np.testing.assert_array_equal(one.path[-1], goal)
    assert one.stats.pairs_validated == 1

    two = solve("cbirrt2", seed=2, start=start)
    assert two.status is PlanStatus.SOLVED, two.reason
    assert two.stats.roots_added_start == 0 and two.extra["n_start_trees"] == 1
    assert two.stats.roots_added_goal == two.extra["n_goal_trees"] >= 1
    np.testing.assert_array_equal(two.path[0], start)
    assert two.goal_config[0] > 0.9


def test_cbirrt_infeasible_cases():
    rejected = solve("cbirrt", seed=0, start=START_C, goal=np.array([0.85, 0.5]))
    assert rejected.status is PlanStatus.INFEASIBLE and "rejected" in rejected.reason
    assert rejected.stats.pairs_validated == rejected.stats.pairs_rejected == 1
    blocked = solve("cbirrt", seed=0, start=np.array([0.5, 0.3]), goal=GOAL_C)
    assert blocked.status is PlanStatus.INFEASIBLE and "start root" in blocked.reason


def test_planner_configuration_errors():
    fns = toy_fns()
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="kind must be one of"):
        ForestConnectPlanner("rrt", fns, PARAMS, rng)
    no_goal = SearchFunctions(fns.sample_config, fns.project, fns.collides)
    with pytest.raises(ValueError, match="sample_goal_root"):
        ForestConnectPlanner("cbirrt2", no_goal, PARAMS, rng, start=START_C)
    ForestConnectPlanner("cbirrt", no_goal, PARAMS, rng, start=START_C, goal=GOAL_C)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"step_size": 0.0}, "step_size"),
        ({"step_size": math.nan}, "step_size"),
        ({"step_size": 0.1, "n_star": 0}, "n_star"),
        ({"step_size": 0.1, "goal_tolerance": 0.2}, "goal_tolerance"),
        ({"step_size": 0.1, "max_extend_steps": 1.5}, "max_extend_steps"),
        ({"step_size": 0.1, "distance_weights": [1.0, -1.0]}, "distance_weights"),
    ],
)
def test_search_params_validation(kwargs, match):
    with pytest.raises(ValueError, match=match):
        SearchParams(**kwargs)
    assert SearchParams(step_size=0.1).goal_tolerance == pytest.approx(0.01)


def test_forest_nearest_matches_brute_force():
    rng = np.random.default_rng(11)
    w = rng.uniform(0.5, 3.0, 7)
    forest = Forest(7, w, capacity=4)
    for _ in range(5):
        forest.add_root(rng.normal(size=7))
    for _ in range(400):
        forest.add_node(rng.normal(size=7), int(rng.integers(forest.n_nodes)))
    assert forest.n_nodes == 405 and forest.n_trees == 5
    nodes = forest.configs
    for q in rng.normal(size=(50, 7)):
        d = [math.sqrt(sum(w[j] * (n[j] - q[j]) ** 2 for j in range(7))) for n in nodes]
        tree, idx = forest.nearest(q)
        assert idx == int(np.argmin(d)) and tree == forest.tree_of(idx)
        tree2, idx2 = forest.nearest(q, exclude_trees=[tree])
        others = [d[i] if forest.tree_of(i) != tree else math.inf for i in range(len(d))]
        assert idx2 == int(np.argmin(others)) and tree2 != tree
    chain = forest.path_to_root(404)
    np.testing.assert_array_equal(chain[-1], forest.config(forest.root_of(404)))
    assert forest.nearest(q, exclude_trees=range(5)) is None


def test_constrained_extend_records_steps_and_stops_at_wall():
    fns = toy_fns(collides_closed)
    forest = Forest(2)
    root = forest.add_root(np.array([0.1, 0.5]))
    last, reached = constrained_extend(forest, root, [0.9, 0.9], fns, STEP, tolerance=1e-3)
    assert not reached and forest.n_nodes > 5
    path = forest.path_to_root(last)
    assert len(path) == forest.n_nodes and path[0][0] < WALL_X[0]
    assert all(on_manifold(q) for q in path)  # target y = 0.9 is off the band
    assert np.linalg.norm(np.diff(path, axis=0), axis=1).max() <= STEP + 1e-12
    free = Forest(2)
    last, reached = constrained_extend(
        free, free.add_root(np.array([0.6, 0.5])), [0.95, 0.5], fns, STEP, tolerance=1e-3
    )
    assert reached and free.n_nodes == 1 + math.ceil(0.35 / STEP - 1e-9)


def test_densify_bounds_metric_and_keeps_waypoints():
    path = np.array([[0.0, 0.5], [0.3, 0.5], [0.3, 0.8]])

    def metric(a, b):
        return float(np.linalg.norm(a - b))

    dense = densify(path, 0.01, project, metric)
    gaps = [metric(a, b) for a, b in zip(dense[:-1], dense[1:], strict=True)]
    assert max(gaps) <= 0.01 + 1e-12
    assert all(on_manifold(q) for q in dense)
    for q in path:
        assert np.any(np.all(np.isclose(dense, q), axis=1))
    assert 1 + 30 + 30 <= len(dense) <= 1 + 31 + 31  # near-minimal: no bisection blow-up
    with pytest.raises(DensifyError):
        densify(path, 0.01, lambda q, near: None, metric)


def test_pairs_the_quick_check_refuses_are_never_connected():
    """With pair_feasible = pair_valid's own condition, every connected pair is valid: the
    refused goal trees (x <= 0.9) are not grown toward, and the answer stays a valid pair."""
    checked: list[tuple[np.ndarray, np.ndarray]] = []

    def feasible(q_start: np.ndarray, q_goal: np.ndarray) -> bool:
        checked.append((q_start, q_goal))
        return pair_valid(q_start, q_goal)[0]

    fns = dataclasses.replace(toy_fns(), pair_feasible=feasible)
    refused = rejected = 0
    for seed in range(6):
        res = solve("regions", seed=seed, fns=fns)
        assert res.status is PlanStatus.SOLVED, res.reason
        assert res.goal_config[0] > 0.9
        assert res.stats.pairs_rejected == 0  # nothing connected was invalid
        refused += res.stats.pairs_refused
        plain = solve("regions", seed=seed)
        rejected += plain.stats.pairs_rejected
    assert refused > 0 and rejected > 0  # the goal disc reaches x < 0.9: some pairs are bad
    assert len(checked) == len({(a.tobytes(), b.tobytes()) for a, b in checked})  # once each
