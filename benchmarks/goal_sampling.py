"""Reduced fig10 and fig11-style runs: the planner's goal sampling at both plate scales.

The experiments' own cases and runner (``slide_gym.experiments``) on the first ``--poses``
start poses, written as they finish (a re-run resumes); ``summary`` prints what the docs'
Planners page quotes: mean and median planning time per scale, their half/full ratio, tree
nodes and pairs rejected per query. To compare with the paper's band C_g, run the same at a
commit before ``SlideParams.goal_sampling`` existed (a ``git worktree``).

    OMP_NUM_THREADS=1 python benchmarks/goal_sampling.py run fig10 --poses 2 --out f10.jsonl
    python benchmarks/goal_sampling.py summary f10.jsonl --poses 2
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import numpy as np

os.environ.setdefault("OMP_NUM_THREADS", "1")


def run(which: str, poses: int, out: Path, workers: int) -> None:
    from slide_gym.experiments import specs
    from slide_gym.experiments.run import experiment_case
    from slide_gym.jobs import run_cases
    from slide_gym.version import code_version

    version = code_version()
    if which == "fig10":
        objects = specs.PAPER_OBJECTS + specs.LETTERS
        cases = specs._fig10(  # noqa: SLF001 - the experiment's own cases, fewer poses
            version, objects, specs.TABLE_NAMES, poses=poses, time_budget=specs.TIME_BUDGET
        )
    else:  # fig11's problems, the regions planner at dZ* = 2 cm (the speed target's)
        cases = [
            specs.case("fig11", o, specs.TABLE, i, version, time_budget=specs.TIME_BUDGET)
            for i in range(poses)
            for o in specs.PAPER_OBJECTS
        ]
    run_cases(experiment_case, cases, out, workers, desc=which)


def summary(path: Path, poses: int | None = None) -> None:
    """Print the figures of ``path``'s queries (of the first ``poses`` start poses only)."""
    rows = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    rows = [r for r in rows if poses is None or r["case"]["seed"] < poses]
    print(f"{path}: {len(rows)} queries, code version {rows[0]['case']['code_version']}")
    means = {}
    for scale in sorted({r["case"]["scale"] for r in rows}, reverse=True):
        group = [r for r in rows if r["case"]["scale"] == scale]
        t = np.array([r["planning_time_s"] for r in group if r["status"] == "solved"])
        means[scale] = t.mean()
        nodes = np.mean([r["stats"]["tree_nodes"] for r in group])
        rejected = np.mean([r["stats"]["pairs_rejected"] for r in group])
        refused = np.mean([r["stats"].get("pairs_refused", 0) for r in group])
        print(
            f"  scale {scale}: {len(t)} of {len(group)} solved; mean {t.mean():.2f} s, median "
            f"{np.median(t):.2f} s, <= 1 s {100 * np.mean(t <= 1):.1f} %; tree nodes "
            f"{nodes:.0f}; pairs rejected per query {rejected:.1f}, refused {refused:.1f}"
        )
    if len(means) == 2:
        print(f"  half / full mean planning time: {means[0.5] / means[1.0]:.2f}x")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("run", help="run a reduced experiment")
    p.add_argument("which", choices=("fig10", "fig11"))
    p.add_argument("--poses", type=int, default=2, help="start poses per object (default 2)")
    p.add_argument("--out", type=Path, required=True, help="results (JSONL; resumes)")
    p.add_argument("--workers", type=int, default=1, help="worker processes (default 1)")
    s = sub.add_parser("summary", help="summarise a results file")
    s.add_argument("path", type=Path)
    s.add_argument("--poses", type=int, help="only the first N start poses' queries")
    args = parser.parse_args()
    if args.command == "run":
        run(args.which, args.poses, args.out, args.workers)
    else:
        summary(args.path, args.poses)


if __name__ == "__main__":
    main()
