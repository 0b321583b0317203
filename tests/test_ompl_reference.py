"""The OMPL reference planner (``planner="ompl"``, the optional ``ompl`` extra)."""

from __future__ import annotations

import builtins

import numpy as np
import pytest

from slide_gym.geometry import get_table, overhang, transform_polygon
from slide_gym.planning import ompl_reference
from slide_gym.planning.api import TopSlidePlanner, TopSlideProblem
from slide_gym.planning.runner import plan_once, seeded_generators
from slide_gym.task import scene_object, seeded_start_pose

# Seed 1: a fig11-like query (square plate, square table, dZ* = 2 cm) that RRTConnect solves
# in about ten iterations; seed 0's start pose takes it most of a 10 s budget.
SEED = 1
BUDGET = 5.0


def _problem(seed: int = SEED) -> TopSlideProblem:
    table = get_table("square")
    shape = scene_object("square", table, seed=seed)
    return TopSlideProblem(shape, table, seeded_start_pose(shape, table, seed))


@pytest.fixture(scope="module")
def solved():
    pytest.importorskip("ompl")
    problem = _problem()
    with ompl_reference.OmplReferencePlanner(problem, seeded_generators(SEED)[1]) as planner:
        result = planner.solve(BUDGET)
    return problem, result


def test_solves_on_our_manifold(solved):
    problem, result = solved
    assert result.solved, result.reason
    assert result.extra["planner"] == "ompl"
    path = result.path
    np.testing.assert_array_equal(path[0], result.start_config)
    np.testing.assert_array_equal(path[-1], result.goal_config)
    # an independent planner (own collision world, own constraints) re-checks every state
    with TopSlidePlanner(problem, "regions", seed=0) as check:
        assert check.constraints.satisfied(path).all()
        assert not any(check.collides(q) for q in path)
        steps = [check.tip_distance(a, b) for a, b in zip(path[:-1], path[1:], strict=True)]
        assert max(steps) <= problem.params.path_resolution * (1 + 1e-9)
        # Eq. 2 and the overhang from the configurations; the returned transfer re-checked
        # leg by leg (a fresh validator's own fallback search may not find the same route)
        goal = check.validator.object_goal(result.start_config, result.goal_config)
        np.testing.assert_allclose(goal, result.extra["object_goal_pose"], atol=1e-9)
        placed = transform_polygon(problem.object.polygon, *goal)
        assert overhang(placed, problem.table.polygon).graspable(problem.params.u_star)
        transfer = np.asarray(result.extra["transfer_path"])
        assert len(transfer) >= 2
        np.testing.assert_array_equal(transfer[0], result.goal_config)
        assert check.route_free(transfer[:2], goal, mode="sliding")  # off the plate
        assert check.route_free(transfer[1:], goal)
    assert result.extra["overhang_m"] >= problem.params.u_star


def test_same_seed_same_plan():
    pytest.importorskip("ompl")
    runs = [plan_once("square", "square", seed=SEED, planner="ompl", time_budget=BUDGET)]
    runs.append(plan_once("square", "square", seed=SEED + 1, planner="ompl", time_budget=BUDGET))
    runs.append(plan_once("square", "square", seed=SEED, planner="ompl", time_budget=BUDGET))
    first, _, again = runs
    assert first["status"] == again["status"] == "solved"
    assert first["planner"] == "ompl"
    np.testing.assert_array_equal(first["path"], again["path"])
    counts = ("iterations", "tree_nodes", "pairs_validated", "pairs_rejected")
    assert {k: first["stats"][k] for k in counts} == {k: again["stats"][k] for k in counts}


def test_missing_ompl_says_how_to_install(monkeypatch):
    real_import = builtins.__import__

    def no_ompl(name, *args, **kwargs):
        if name == "ompl" or name.startswith("ompl."):
            raise ImportError(f"No module named {name!r}")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_ompl)
    ompl_reference.ompl_types.cache_clear()
    try:
        with pytest.raises(ValueError, match=r"pip install 'slide-gym\[ompl\]'"):
            plan_once("square", "square", seed=SEED, planner="ompl", time_budget=BUDGET)
    finally:
        ompl_reference.ompl_types.cache_clear()
