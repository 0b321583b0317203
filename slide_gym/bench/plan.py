"""``slide-gym bench plan``: the planners' success rate against planning time (the paper's
setting by default), resumable, with an optional success-against-time figure."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from slide_gym.jobs import run_cases

OBJECTS = ("square", "circle", "triangle", "crescent", "irregular")
"""The paper's plan benchmark objects."""
TABLE = "square"
TRIALS = 20
"""Seeded random start poses per object."""
TIME_BUDGET = 10.0
"""Planning seconds per query."""
DZ = (0.005, 0.025)
"""Contact depth relaxation (m): the paper's dZ* = 2 cm."""
OUT = Path("results/bench_plan.jsonl")
BUDGET_MARKS = (0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 60.0)
"""Planning times (s) at which the summary reports success rates."""


def plan_case(case: dict[str, Any]) -> dict[str, Any]:
    """One planning query of the plan benchmark (runs in a worker process)."""
    from slide_gym.planning.runner import make_params, plan_once

    out = plan_once(
        case["object"],
        case["table"],
        seed=case["seed"],
        planner=case["planner"],
        time_budget=case["budget"],
        params=make_params(dz=tuple(case["dz"])),
    )
    stats = out["stats"]
    return {
        "status": out["status"],
        "reason": out["reason"],
        "planning_time_s": out["planning_time_s"],
        "overhang_m": out["overhang_m"],
        "iterations": stats["iterations"],
        "tree_nodes": stats["tree_nodes"],
        "pairs_validated": stats["pairs_validated"],
    }


def bench_plan(
    objects: Sequence[str] = OBJECTS,
    table: str = TABLE,
    planners: Sequence[str] | None = None,
    trials: int = TRIALS,
    time_budget: float = TIME_BUDGET,
    dz: tuple[float, ...] = DZ,
    out: Path = OUT,
    workers: int | None = None,
    seed: int = 0,
    plot: Path | None = None,
    backend: str = "local",
    address: str | None = None,
) -> dict[str, Any]:
    """Success rate against planning time per planner (resumable: results go to ``out``).

    ``planners`` defaults to every name in :data:`slide_gym.planning.search.PLANNERS`.
    ``backend``, ``address``: where queries run (:func:`slide_gym.jobs.run_cases`).
    """
    from slide_gym.geometry import get_object, get_table
    from slide_gym.planning.result import check_time_budget
    from slide_gym.planning.search import PLANNERS

    planners = list(PLANNERS if planners is None else planners)
    check_time_budget(time_budget)
    if trials < 1:
        raise ValueError(f"trials must be >= 1, got {trials}")
    if not objects or not planners:
        raise ValueError("need at least one object and one planner")
    for name in planners:
        if name not in PLANNERS:
            raise ValueError(f"planners must be among {', '.join(PLANNERS)}, got {name!r}")
    for name in objects:
        get_object(name)
    get_table(table)
    cases = [
        {
            "planner": p,
            "object": o,
            "table": table,
            "seed": seed + i,
            "budget": time_budget,
            "dz": list(dz),
        }
        for i in range(trials)
        for o in objects
        for p in planners
    ]
    rows = run_cases(plan_case, cases, out, workers, desc="plan", backend=backend, address=address)
    summary = summarize_plan(rows, planners, time_budget)
    if plot is not None:
        plot_success_curves(rows, planners, time_budget, plot)
    return summary


def _planner_times(
    rows: list[dict[str, Any]], planner: str
) -> tuple[list[dict[str, Any]], np.ndarray]:
    """One planner's rows and their planning times (inf where not solved)."""
    mine = [r for r in rows if r["case"]["planner"] == planner]
    times = np.array([r["planning_time_s"] if r["status"] == "solved" else np.inf for r in mine])
    return mine, times


def summarize_plan(
    rows: list[dict[str, Any]], planners: Sequence[str], time_budget: float
) -> dict[str, Any]:
    """Per planner: runs, success rate at each budget mark, median planning time."""
    table: dict[str, Any] = {}
    for planner in planners:
        mine, times = _planner_times(rows, planner)
        if not mine:
            continue
        marks = [t for t in BUDGET_MARKS if t <= time_budget]
        table[planner] = {
            "runs": len(mine),
            "solved": int(np.isfinite(times).sum()),
            "success_rate": {f"{t:g}s": float(np.mean(times <= t)) for t in marks},
            "median_time_s": float(np.median(times)),
            "by_object": {
                o: float(
                    np.mean([r["status"] == "solved" for r in mine if r["case"]["object"] == o])
                )
                for o in sorted({r["case"]["object"] for r in mine})
            },
        }
    return {"benchmark": "plan", "time_budget_s": time_budget, "planners": table}


def plot_success_curves(
    rows: list[dict[str, Any]], planners: Sequence[str], time_budget: float, out: Path
) -> None:
    """Success rate against planning time, one curve per planner."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    grid = np.linspace(0.0, time_budget, 400)
    fig, ax = plt.subplots(figsize=(6, 4))
    for planner in planners:
        mine, times = _planner_times(rows, planner)
        if not mine:
            continue
        ax.plot(grid, [(times <= t).mean() for t in grid], label=f"{planner} (n={len(mine)})")
    ax.set_xlabel("planning time budget (s)")
    ax.set_ylabel("success rate")
    ax.set_ylim(0, 1.02)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
