"""Shared test settings: planning budgets that a loaded machine cannot run out of.

Tests assert what a plan or an episode does, never how fast: speed is measured by
``slide-gym bench``. The planners are deterministic for a seed as long as no deadline is
hit, so a test that needs a plan uses a fixed seed and a budget far above what its case
needs; every time cap inside the planner that could otherwise decide the outcome (the pair
validator's fallback transfer planner, :attr:`GraspParams.transfer_budget`) is raised to
the same budget. Tests marked ``slow`` run whole expert episodes; ``pytest -m "not slow"``
skips them, plain ``pytest`` (``make test``) runs everything.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import pytest

from slide_gym.planning.api import SlideParams, TopSlidePlanner, TopSlideProblem
from slide_gym.planning.result import PlanResult

PLAN_BUDGET = 60.0
"""Seconds per planner query: the seeded cases in these tests solve in under 2 s."""


def unhurried(params: SlideParams, budget: float = PLAN_BUDGET) -> SlideParams:
    """``params`` with the fallback transfer planner allowed ``budget`` seconds per pair
    instead of its default fraction of a second (it succeeds in ~0.1-0.2 s in these cases,
    so a slow machine could otherwise reject a pair that an idle one accepts)."""
    return dataclasses.replace(
        params, grasp=dataclasses.replace(params.grasp, transfer_budget=budget)
    )


@pytest.fixture(scope="session")
def plan_budget() -> float:
    return PLAN_BUDGET


@pytest.fixture(scope="session")
def unhurried_params() -> Callable[..., SlideParams]:
    """:func:`unhurried`: lift the planner's internal time caps to the test budget."""
    return unhurried


@pytest.fixture(scope="session")
def solve_top_slide() -> Callable[..., PlanResult]:
    """Solve a top-slide query with a fixed seed and :data:`PLAN_BUDGET`.

    ``solve(obj, table, pose, params=None, planner="regions", seed=0)``; ``params``
    defaults to the paper's :class:`SlideParams` and gets :func:`unhurried`.
    """

    def solve(
        obj: str,
        table: str,
        pose: tuple[float, float, float],
        params: SlideParams | None = None,
        planner: str = "regions",
        seed: int = 0,
    ) -> PlanResult:
        problem = TopSlideProblem(obj, table, pose, unhurried(params or SlideParams()))
        with TopSlidePlanner(problem, planner, seed=seed) as pl:
            return pl.solve(PLAN_BUDGET)

    return solve
