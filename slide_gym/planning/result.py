"""Planner outputs in the spirit of OMPL: status, statistics, result and the planner base."""

from __future__ import annotations

import math
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from enum import Enum
from numbers import Real
from pathlib import Path
from typing import Any

import numpy as np


class PlanStatus(str, Enum):
    """Outcome of one ``solve`` call."""

    SOLVED = "solved"
    TIMEOUT = "timeout"
    INFEASIBLE = "infeasible"
    ITERATION_LIMIT = "iteration_limit"
    """The search stopped at :attr:`SearchParams.max_iterations` (a count, not a clock)."""


class OutOfTime(RuntimeError):
    """A give-up deadline passed in the middle of a step whose outcome would otherwise depend
    on how far it got (a shortcut loop, a densification): the caller gives up instead."""


@dataclass
class PlannerStats:
    """Counters and callable timings of one search (times in seconds)."""

    iterations: int = 0
    roots_added_start: int = 0
    roots_added_goal: int = 0
    tree_nodes: int = 0
    pairs_validated: int = 0
    pairs_rejected: int = 0
    pairs_refused: int = 0  # by the quick check, before any connection was tried
    time_projection_s: float = 0.0
    time_collision_s: float = 0.0
    time_validation_s: float = 0.0
    time_sampling_s: float = 0.0
    time_total_s: float = 0.0

    def counts(self) -> dict[str, int]:
        """The integer counters only (reproducible for a fixed seed, unlike the times)."""
        return {k: v for k, v in asdict(self).items() if isinstance(v, int)}


def json_values(value: Any) -> Any:
    """NumPy values, enums, paths, bytes (UTF-8) and containers of them as JSON values."""
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Enum):
        return value.value
    if isinstance(value, dict):
        return {str(k): json_values(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_values(v) for v in value]
    return value


@dataclass
class PlanResult:
    """What a planner returns; ``path`` runs from ``start_config`` to ``goal_config``."""

    status: PlanStatus
    reason: str | None = None
    start_config: np.ndarray | None = None
    goal_config: np.ndarray | None = None
    path: np.ndarray | None = None
    stats: PlannerStats = field(default_factory=PlannerStats)
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def solved(self) -> bool:
        """True when a validated path was found."""
        return self.status is PlanStatus.SOLVED

    def to_json_dict(self) -> dict[str, Any]:
        """A dict of plain lists, floats, ints and strings."""
        return {
            "status": self.status.value,
            "reason": self.reason,
            "start_config": json_values(self.start_config),
            "goal_config": json_values(self.goal_config),
            "path": json_values(self.path),
            "stats": json_values(asdict(self.stats)),
            "extra": json_values(self.extra),
        }


def timed(fn: Callable[..., Any] | None, stats: PlannerStats, attr: str) -> Any:
    """Wrap ``fn`` so each call adds its run time to ``stats.<attr>`` (None stays None)."""
    if fn is None:
        return None

    def wrapped(*args: Any) -> Any:
        t0 = time.perf_counter()
        try:
            return fn(*args)
        finally:
            setattr(stats, attr, getattr(stats, attr) + time.perf_counter() - t0)

    return wrapped


def check_time_budget(time_budget: float) -> float:
    """Return the budget as a float, or raise ValueError unless it is finite and positive."""
    if isinstance(time_budget, bool) or not isinstance(time_budget, Real):
        raise ValueError(
            f"time_budget must be a finite positive number of seconds, got {time_budget!r}"
        )
    budget = float(time_budget)
    if not math.isfinite(budget) or budget <= 0.0:
        raise ValueError(f"time_budget must be a finite positive number of seconds, got {budget}")
    return budget


class Planner(ABC):
    """Base of all planners: ``solve(time_budget)`` searches until a wall-clock deadline.

    Subclasses implement :meth:`_solve`, which must check ``time.perf_counter() >= deadline``
    often enough that the overrun stays well under 5 % of the budget.
    """

    name: str = "planner"

    def solve(self, time_budget: float) -> PlanResult:
        """Plan for at most ``time_budget`` seconds (finite, > 0)."""
        budget = check_time_budget(time_budget)
        return self.solve_until(time.perf_counter() + budget)

    def solve_until(self, deadline: float) -> PlanResult:
        """Plan until ``time.perf_counter()`` reaches ``deadline`` (``math.inf``: never; then
        only the planner's counts, such as :attr:`SearchParams.max_iterations`, stop it)."""
        if math.isnan(deadline):
            raise ValueError("deadline must be a number of seconds (time.perf_counter), got NaN")
        stats = PlannerStats()
        t0 = time.perf_counter()
        result = self._solve(deadline, stats)
        stats.time_total_s = time.perf_counter() - t0
        result.stats = stats
        return result

    @abstractmethod
    def _solve(self, deadline: float, stats: PlannerStats) -> PlanResult:
        """Run one search until solved, proven infeasible or ``deadline`` (perf_counter)."""


@dataclass(frozen=True)
class SearchParams:
    """Tuning of the forest-connect search (distances are weighted, in configuration units).

    ``goal_tolerance`` defaults to ``step_size / 10``; ``distance_weights`` (per joint) overrides
    the weights a problem supplies in its ``SearchFunctions``. ``max_iterations`` (None: no
    cap) stops the search with status ``ITERATION_LIMIT`` once ``stats.iterations`` reaches
    it: a cap that does not depend on how fast the machine is, unlike the deadline.
    """

    step_size: float
    n_star: int = 100
    goal_tolerance: float | None = None
    max_extend_steps: int = 500
    distance_weights: tuple[float, ...] | None = None
    max_iterations: int | None = None

    def __post_init__(self) -> None:
        step = _positive_float(self.step_size, "step_size")
        object.__setattr__(self, "step_size", step)
        object.__setattr__(self, "n_star", _positive_int(self.n_star, "n_star"))
        steps = _positive_int(self.max_extend_steps, "max_extend_steps")
        object.__setattr__(self, "max_extend_steps", steps)
        if self.max_iterations is not None:
            cap = _positive_int(self.max_iterations, "max_iterations")
            object.__setattr__(self, "max_iterations", cap)
        if self.goal_tolerance is None:
            object.__setattr__(self, "goal_tolerance", step / 10.0)
        else:
            tol = _positive_float(self.goal_tolerance, "goal_tolerance")
            if tol > step:
                raise ValueError(f"goal_tolerance must be in (0, step_size={step}], got {tol}")
            object.__setattr__(self, "goal_tolerance", tol)
        if self.distance_weights is not None:
            w = np.asarray(self.distance_weights, dtype=float)
            if w.ndim != 1 or w.size == 0 or not (np.isfinite(w).all() and (w > 0).all()):
                raise ValueError(
                    "distance_weights must be None or a non-empty 1-D sequence of finite "
                    f"positive numbers, got {self.distance_weights!r}"
                )
            object.__setattr__(self, "distance_weights", tuple(float(v) for v in w))


def _positive_float(value: Any, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, Real) or not math.isfinite(value):
        raise ValueError(f"{name} must be a finite positive number, got {value!r}")
    if value <= 0:
        raise ValueError(f"{name} must be a finite positive number, got {value!r}")
    return float(value)


def _positive_int(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    return int(value)
