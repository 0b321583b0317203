"""``slide-gym experiment NAME``: the paper's experiments as named, resumable runs."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from slide_gym.cli.args import add_backend, add_choice, add_command

ALL = "all"
"""Runs every implemented experiment in turn."""


def _cmd_experiment(args: argparse.Namespace) -> int:
    from slide_gym.experiments import run_experiments

    summaries = run_experiments(
        [args.name],
        quick=args.quick,
        workers=args.workers,
        backend=args.backend,
        out=args.out,
        address=args.ray_address,
        poses=args.poses,
        budget=args.budget,
    )
    print(json.dumps(summaries, indent=2))
    return 0


def add_parsers(sub: Any) -> None:
    """``slide-gym experiment NAME [--quick | --poses N --budget S] [--workers W]
    [--backend local|ray] [--out DIR]``."""
    from slide_gym.experiments.run import OUT
    from slide_gym.experiments.specs import EXPERIMENTS, LATER, QUICK_BUDGET, TIME_BUDGET

    names = (*EXPERIMENTS, ALL, *LATER)
    p = add_command(
        sub,
        "experiment",
        "the paper's experiments and the agents' comparison as resumable runs",
        "Run the planning queries of one of the paper's experiments in parallel and print a "
        "summary as JSON. fig10: 4 tables x 9 objects (5 paper objects, letters Y A L E) x 50 "
        "start poses at scales 1 and 0.5; fig11: square table, 5 objects x 100 poses with "
        "dZ* = 0, 0.5, 2 cm (dZ- = 0.5 cm), and cbirrt, "
        "cbirrt2, cbirrt-norestart at 2 cm on the same problems, plus OMPL's RRTConnect (the "
        "ompl extra) on the first 20 poses; fig12: 5 objects x 20 poses at N* = 1, 10, 100, "
        "1000, 10000; "
        "restart: fig11's problems (20 poses) with cbirrt at restart periods 25-400 search "
        "iterations and without restarts; agents: the expert with the regions, cbirrt and "
        "cbirrt2 planners on TopSlideGrasp-v0, 9 objects x 4 tables x 10 seeds, 10 s "
        "planning per episode; relaxation: the regions expert planning with the contact "
        "band of dZ* = 0, 0.5, 2 cm and with its own, 9 objects x 4 tables x 2 seeds, and the "
        "regions planner with the projection variants steps, nodes and orientation at each "
        "dZ* on fig11's problems (10 poses, 20 s per query); planners: fig11's problems with "
        "regions, cbirrt and cbirrt2 at dZ* = 2 cm, at scales 1 and 0.5; otherwise "
        f"{TIME_BUDGET:g} s per query. Each query is one JSON line, written as it finishes, "
        "to DIR/NAME-VERSION.jsonl (VERSION: the code version, package version + git commit "
        "+ dirty.HASH for uncommitted changes): a re-run of the same code skips finished "
        "queries, so Ctrl-C and resume lose nothing; other code writes a new file and never "
        "reuses another version's rows.",
        [
            "slide-gym experiment all --quick",
            "slide-gym experiment fig11 --workers 2 --out results/experiments",
            "slide-gym experiment planners --poses 10 --budget 10 --workers 1",
        ],
    )
    name_help = f"one of {', '.join(names)} ({ALL}: {', '.join(EXPERIMENTS)} in turn)"
    add_choice(p, "name", names, "experiment", name_help, metavar="NAME")
    p.add_argument(
        "--quick",
        action="store_true",
        help=f"a smoke test: square table, 2 objects, 1 start pose, {QUICK_BUDGET:g} s per "
        "query, into DIR/NAME-quick-VERSION.jsonl",
    )
    p.add_argument(
        "--poses",
        type=int,
        metavar="N",
        help="a reduced run: the first N start poses only, into DIR/NAME-posesN-VERSION.jsonl",
    )
    p.add_argument(
        "--budget",
        type=float,
        metavar="S",
        help="a reduced run: S planning seconds per query (expert episodes keep their cap), "
        "into DIR/NAME-budgetSs-VERSION.jsonl (with --poses: NAME-posesN-budgetSs-VERSION)",
    )
    p.add_argument(
        "--workers", type=int, metavar="N", help="worker processes (default: one per core)"
    )
    add_backend(p)
    p.add_argument(
        "--out",
        type=Path,
        default=OUT,
        metavar="DIR",
        help="results folder: one JSONL file per experiment and code version",
    )
    p.set_defaults(func=_cmd_experiment)

    p = add_command(
        sub,
        "report",
        "plots and a markdown report from experiment results",
        "Read the JSONL files `slide-gym experiment` wrote to RESULTS_DIR (per experiment, "
        "the file with the most rows) and write one PNG per experiment (success against "
        "planning time with 95 % Wilson bands; mean times with standard errors) and "
        "report.md, with the paper's figures beside ours and the planner speed target.",
        [
            "slide-gym report results/experiments",
            "slide-gym report results/experiments --out docs/results",
        ],
    )
    p.add_argument("results", type=Path, metavar="RESULTS_DIR", help="experiment results")
    p.add_argument("--out", type=Path, metavar="DIR", help="where to write (default: RESULTS_DIR)")
    p.set_defaults(func=_cmd_report)


def _cmd_report(args: argparse.Namespace) -> int:
    from slide_gym.experiments.report import write_report

    path = write_report(args.results, args.out)
    print(path)
    return 0
