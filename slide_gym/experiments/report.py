"""``slide-gym report RESULTS_DIR``: plots and a markdown report from experiment results.

Reads the JSONL files ``slide-gym experiment`` wrote (one per experiment and code version;
for each experiment the file with the most rows is used, and the report names its version),
draws one PNG per experiment and writes ``report.md`` with the paper's figures beside ours.
"""

from __future__ import annotations

import os
import platform
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from slide_gym.bench.jobs import load_results
from slide_gym.experiments.specs import EXPERIMENTS, experiment_cases
from slide_gym.experiments.stats import mean_and_sem, wilson_interval

MARKS = (1.0, 5.0, 10.0, 20.0, 60.0)
"""Budgets (s) at which success rates are tabulated."""
PAPER = {
    "fig11": "90 % of queries within 20 s and 99 % at 60 s with dZ* = 2 cm; 90 % at 53 s "
    "with dZ* = 0.5 cm; 2 % within 60 s with dZ* = 0; CBiRRT and CBiRRT2 below ours.",
    "fig12": "mean planning time lowest at N* = 100.",
    "fig10": "mean planning time similar across objects and tables, and at half scale.",
    "restart": "(not in the paper: the period of our CBiRRT baseline's restarts).",
    "agents": "(not in the paper: the planners driving the expert in physics, slide, grasp "
    "and lift).",
}
"""The paper's numbers each experiment is compared with (Section V)."""
SPEED = (
    "planner speed, one core, fig11 problems at dZ* = 2 cm: >= 99 % within 1 s, median <= 0.15 s"
)


def load_experiments(results: Path) -> dict[str, tuple[str, list[dict[str, Any]]]]:
    """Experiment name -> (code version, rows) from the largest file of each experiment."""
    best: dict[str, tuple[str, list[dict[str, Any]]]] = {}
    for path in sorted(results.glob("*.jsonl")):
        rows = [r for r in load_results(path) if "case" in r]
        if not rows:
            continue
        name = rows[0]["case"]["experiment"] + ("-quick" if "-quick-" in path.name else "")
        version = rows[0]["case"]["code_version"]
        if name not in best or len(rows) > len(best[name][1]):
            best[name] = (version, rows)
    return best


def condition(row: dict[str, Any]) -> str:
    """A row's condition label: planner, and what its experiment varies."""
    c = row["case"]
    name = c["experiment"]
    if name == "fig11":
        if c["planner"] == "regions":
            return f"regions dZ*={100 * (c['dz'][1] - c['dz'][0]):g} cm"
        return c["planner"]
    if name == "fig12":
        return f"N*={c['n_star']}"
    if name == "restart":
        if c["planner"] == "cbirrt":
            return f"cbirrt restart {c['restart_iterations']}"
        return c["planner"]
    return f"{c['object']} / {c['table']} / x{c['scale']:g}"


def by_condition(rows: Sequence[dict[str, Any]]) -> dict[str, list[dict[str, Any]]]:
    """Rows grouped by :func:`condition`, ours first, then by the varied parameter's value."""
    groups: dict[str, list[dict[str, Any]]] = {}
    for r in sorted(rows, key=_condition_order):
        groups.setdefault(condition(r), []).append(r)
    return groups


def _condition_order(row: dict[str, Any]) -> tuple[Any, ...]:
    c = row["case"]
    dz = c.get("dz") or [0.0, 0.0]
    return (
        c["planner"] != "regions",
        c["planner"],
        dz[1] - dz[0],
        c.get("n_star", 0),
        c.get("restart_iterations", 0),
    )


def solve_times(rows: Sequence[dict[str, Any]]) -> np.ndarray:
    """Planning time of each row, ``inf`` where it did not solve."""
    return np.array(
        [r["planning_time_s"] if r.get("status") == "solved" else np.inf for r in rows], float
    )


def success_table(rows: list[dict[str, Any]], budget: float) -> list[dict[str, Any]]:
    """Per condition: runs, success at each mark within ``budget`` (with a 95 % Wilson
    interval), median time, largest overrun of the budget."""
    out = []
    for label, group in by_condition(rows).items():
        t = solve_times(group)
        marks = {}
        for m in (m for m in MARKS if m <= budget):
            k = int((t <= m).sum())
            marks[f"{m:g}s"] = (k / len(t), *wilson_interval(k, len(t)))
        spent = np.array([r["planning_time_s"] for r in group], float)
        out.append(
            {
                "condition": label,
                "runs": len(group),
                "success": marks,
                "median_s": float(np.median(t)),
                "largest_overrun": float(spent.max() / budget - 1.0),
            }
        )
    return out


def plot_success(rows: list[dict[str, Any]], budget: float, out: Path, title: str) -> None:
    """Success rate against planning time (log scale: most queries solve within a second)
    per condition, with 95 % Wilson bands."""
    plt = _pyplot()
    grid = np.geomspace(0.05, budget, 300)
    fig, ax = plt.subplots(figsize=(6.5, 4))
    for label, group in by_condition(rows).items():
        t = solve_times(group)
        k = np.array([(t <= g).sum() for g in grid])
        band = np.array([wilson_interval(int(v), len(t)) for v in k])
        ax.plot(grid, k / len(t), label=f"{label} (n={len(t)})")
        ax.fill_between(grid, band[:, 0], band[:, 1], alpha=0.15)
    ax.set(xlabel="planning time (s)", ylabel="success rate", ylim=(0, 1.02), title=title)
    ax.set_xscale("log")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def plot_mean_times(rows: list[dict[str, Any]], key: str, out: Path, title: str) -> None:
    """Mean planning time (solved queries) with its standard error per value of ``key``."""
    plt = _pyplot()
    values = sorted({r["case"][key] for r in rows}, key=str)
    stats = [mean_and_sem(_solved_times(rows, key, v)) for v in values]
    fig, ax = plt.subplots(figsize=(6.5, 4))
    ax.bar([str(v) for v in values], [m for m, _ in stats], yerr=[s for _, s in stats])
    ax.set(xlabel=key, ylabel="mean planning time of solved queries (s)", title=title)
    ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def write_report(results: Path, out: Path | None = None) -> Path:
    """Plots and ``report.md`` for the experiments in ``results`` (into ``out``, default
    the same folder); the report's path."""
    if not results.is_dir():
        raise ValueError(f"results folder {str(results)!r} does not exist")
    experiments = load_experiments(results)
    if not experiments:
        raise ValueError(f"no experiment results (*.jsonl) in {str(results)!r}")
    out = out or results
    out.mkdir(parents=True, exist_ok=True)
    lines = [
        "# Experiments: our numbers beside the paper's",
        "",
        f"Generated by `slide-gym report {results}` from the JSONL files of "
        "`slide-gym experiment`. Machine: "
        f"{platform.platform()}, {os.cpu_count()} cores, Python {platform.python_version()}.",
        "",
    ]
    missing = [n for n in EXPERIMENTS if n not in experiments and f"{n}-quick" not in experiments]
    if missing:
        lines += [f"Not run yet (no results here): {', '.join(missing)}.", ""]
    for name, (version, rows) in sorted(experiments.items()):
        base = name.removesuffix("-quick")
        budget = max(r["case"]["time_budget"] for r in rows)
        planned = len(experiment_cases(base, version, quick=name.endswith("-quick")))
        size = f"{len(rows)} runs" + ("" if len(rows) == planned else f" of {planned} planned")
        lines += [
            f"## {name}",
            "",
            f"{size}, code version `{version}`, {budget:g} s planning budget each. Paper: "
            f"{PAPER.get(base, 'n/a')}",
            "",
        ]
        if base in ("fig11", "restart", "fig12"):
            png = out / f"{name}.png"
            plot_success(rows, budget, png, f"{name}: success against planning time")
            lines += [f"![{name}]({png.name})", ""]
            lines += _success_markdown(success_table(rows, budget))
        if base in ("fig10", "fig12"):
            key = "n_star" if base == "fig12" else "object"
            png = out / f"{name}-mean-time.png"
            plot_mean_times(rows, key, png, f"{name}: mean planning time by {key}")
            lines += [f"![{name} mean time]({png.name})", ""]
            lines += _mean_markdown(rows, key)
            if base == "fig10":
                lines += _mean_markdown(rows, "table") + _mean_markdown(rows, "scale")
        if base == "fig11":
            lines += _speed_markdown(rows, budget)
        if base == "agents":
            lines += _agents_markdown(rows)
    path = out / "report.md"
    path.write_text("\n".join(lines) + "\n")
    return path


def _success_markdown(table: list[dict[str, Any]]) -> list[str]:
    marks = list(table[0]["success"]) if table else []
    head = "| condition | runs | " + " | ".join(f"within {m}" for m in marks)
    lines = [head + " | median | largest overrun |", "|---" * (len(marks) + 4) + "|"]
    for row in table:
        cells = [
            f"{100 * p:.1f} % ({100 * lo:.0f}-{100 * hi:.0f})"
            for p, lo, hi in row["success"].values()
        ]
        median = "unsolved" if not np.isfinite(row["median_s"]) else f"{row['median_s']:.2f} s"
        lines.append(
            f"| {row['condition']} | {row['runs']} | "
            + " | ".join(cells)
            + f" | {median} | {_overrun(row['largest_overrun'])} |"
        )
    return [*lines, ""]


def _overrun(fraction: float) -> str:
    return "none" if fraction <= 0 else f"{100 * fraction:.1f} %"


def _mean_markdown(rows: list[dict[str, Any]], key: str) -> list[str]:
    lines = [f"| {key} | solved | mean time (s) +- SE |", "|---|---|---|"]
    for v in sorted({r["case"][key] for r in rows}, key=str):
        mine = [r for r in rows if r["case"][key] == v]
        t = _solved_times(rows, key, v)
        m, se = mean_and_sem(t)
        lines.append(f"| {v} | {len(t)} of {len(mine)} | {m:.2f} +- {se:.2f} |")
    return [*lines, ""]


def _speed_markdown(rows: list[dict[str, Any]], budget: float) -> list[str]:
    ours = [r for r in rows if r["case"]["planner"] == "regions" and r["case"]["dz"][1] == 0.025]
    if not ours:
        return []
    t = solve_times(ours)
    within = float((t <= 1.0).mean())
    median = float(np.median(t))
    verdict = "met" if within >= 0.99 and median <= 0.15 else "not met"
    return [
        f"Target, {SPEED}: **{verdict}** ({100 * within:.1f} % within 1 s, median "
        f"{median:.2f} s, over {len(ours)} queries).",
        "",
    ]


def _agents_markdown(rows: list[dict[str, Any]]) -> list[str]:
    """Per planner: lifted rate (95 % Wilson), median planning and wall time, failures."""
    from slide_gym.bench.execute import failure_kind

    lines = [
        "| planner | episodes | lifted | median planning | median wall | failures |",
        "|---|---|---|---|---|---|",
    ]
    for planner in sorted({r["case"]["planner"] for r in rows}):
        mine = [r for r in rows if r["case"]["planner"] == planner]
        k = sum(bool(r.get("success")) for r in mine)
        lo, hi = wilson_interval(k, len(mine))
        counts: dict[str, int] = {}
        for r in mine:
            kind = failure_kind(r)
            if kind is not None:
                counts[kind] = counts.get(kind, 0) + 1
        causes = "; ".join(f"{n} {kind}" for kind, n in sorted(counts.items(), key=lambda x: -x[1]))
        lines.append(
            f"| {planner} | {len(mine)} | {100 * k / len(mine):.1f} % ({100 * lo:.0f}-"
            f"{100 * hi:.0f}) | {_median_of(mine, 'planning_time_s')} | "
            f"{_median_of(mine, 'wall_time_s')} | {causes or 'none'} |"
        )
    return [*lines, ""]


def _median_of(rows: list[dict[str, Any]], key: str) -> str:
    values = [float(r[key]) for r in rows if r.get(key) is not None]
    return f"{np.median(values):.2f} s" if values else "n/a"


def _solved_times(rows: list[dict[str, Any]], key: str, value: Any) -> np.ndarray:
    t = solve_times([r for r in rows if r["case"][key] == value])
    return t[np.isfinite(t)]


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt
