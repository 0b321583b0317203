"""Shared test settings: planning budgets that a loaded machine cannot run out of.

Tests assert what a plan or an episode does, never how fast: speed is measured by
``slide-gym bench``. The planners and the expert decide nothing by the clock (every inner cap
counts iterations; ``tests/test_same_on_any_machine.py`` checks it with a slowed clock), and
the time budget only decides when they give up. So a test that needs a plan uses a fixed seed
and a budget far above what its case needs. Tests marked ``slow`` run whole expert episodes;
``pytest -m "not slow"`` skips them, plain ``pytest`` (``make test``) runs everything.
"""

from __future__ import annotations

import importlib.util
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import pytest

from slide_gym.planning.api import SlideParams, TopSlidePlanner, TopSlideProblem
from slide_gym.planning.result import PlanResult

PLAN_BUDGET = 60.0
"""Seconds per planner query: the seeded cases in these tests solve in under 2 s."""


@pytest.fixture(scope="session")
def plan_budget() -> float:
    return PLAN_BUDGET


@pytest.fixture
def slow_clock(monkeypatch) -> Callable[[float], None]:
    """``slow_clock(factor)``: from now on ``time.perf_counter`` (which the planners and the
    agents read as ``time.perf_counter()``) runs ``factor`` times fast, as if the machine were
    ``factor`` times slower; undone after the test."""

    def install(factor: float) -> None:
        real = time.perf_counter
        base = real()
        monkeypatch.setattr(time, "perf_counter", lambda: base + factor * (real() - base))

    return install


@pytest.fixture(scope="session")
def solve_top_slide() -> Callable[..., PlanResult]:
    """Solve a top-slide query with a fixed seed and :data:`PLAN_BUDGET`.

    ``solve(obj, table, pose, params=None, planner="regions", seed=0)``; ``params``
    defaults to the paper's :class:`SlideParams`.
    """

    def solve(
        obj: str,
        table: str,
        pose: tuple[float, float, float],
        params: SlideParams | None = None,
        planner: str = "regions",
        seed: int = 0,
    ) -> PlanResult:
        problem = TopSlideProblem(obj, table, pose, params or SlideParams())
        with TopSlidePlanner(problem, planner, seed=seed) as pl:
            return pl.solve(PLAN_BUDGET)

    return solve


@pytest.fixture(scope="module")
def minari_root(tmp_path_factory):
    """A private Minari folder for the test module (Minari reads the variable on every call)."""
    root = tmp_path_factory.mktemp("minari")
    old = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(root)
    yield root
    if old is None:
        del os.environ["MINARI_DATASETS_PATH"]
    else:
        os.environ["MINARI_DATASETS_PATH"] = old


@pytest.fixture
def load_benchmark() -> Callable[[str], ModuleType]:
    """Import a script of ``benchmarks/`` by name (they are scripts, not a package)."""

    def load(name: str) -> ModuleType:
        path = Path(__file__).resolve().parents[1] / "benchmarks" / f"{name}.py"
        spec = importlib.util.spec_from_file_location(name, path)
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module  # dataclasses look their module up
        spec.loader.exec_module(module)
        return module

    return load
