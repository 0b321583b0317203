"""``slide-gym bench env|plan|execute``: one subcommand per benchmark, each with its own options."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from slide_gym.cli.args import parse_floats, parse_names
from slide_gym.planning.search import PLANNERS


def _cmd_bench_env(args: argparse.Namespace) -> int:
    from slide_gym.bench.env import bench_env, write_result

    result = bench_env(
        args.object, args.table, steps=args.steps, resets=args.resets, seed=args.seed
    )
    write_result(result, args.out)
    return 0


def _cmd_bench_plan(args: argparse.Namespace) -> int:
    from slide_gym.bench.plan import bench_plan

    summary = bench_plan(
        objects=parse_names(args.objects),
        table=args.table,
        planners=parse_names(args.planners),
        trials=args.trials,
        time_budget=args.time_budget,
        dz=parse_floats(args.dz, 2, "--dz"),
        out=args.out,
        workers=args.workers,
        seed=args.seed,
        plot=args.plot,
    )
    print(json.dumps(summary, indent=2))
    return 0


def _cmd_bench_execute(args: argparse.Namespace) -> int:
    from slide_gym.bench.execute import bench_execute, execute_markdown_table

    summary = bench_execute(
        objects=parse_names(args.objects),
        tables=parse_names(args.tables),
        trials=args.trials,
        out=args.out,
        planner=args.planner,
        time_budget=args.time_budget,
        workers=args.workers,
        seed=args.seed,
    )
    print(execute_markdown_table(summary) if args.markdown else json.dumps(summary, indent=2))
    return 0


def add_parsers(sub: Any) -> None:
    """``slide-gym bench env|plan|execute``: one subcommand each, with its own options."""
    from slide_gym.bench import env, execute, plan
    from slide_gym.geometry import OBJECT_NAMES, TABLE_NAMES

    bench = sub.add_parser(
        "bench",
        help="benchmarks: env throughput, planners, expert episodes",
        description="Benchmarks; the README's numbers come from these. Results print as JSON.",
    )
    what = bench.add_subparsers(dest="what", metavar="{env,plan,execute}", required=True)

    def common(p: argparse.ArgumentParser, first_seed: str) -> None:
        p.add_argument("--seed", type=int, default=0, help=f"{first_seed} (default: %(default)s)")

    def jobs(p: argparse.ArgumentParser, out: Path) -> None:
        p.add_argument(
            "--workers",
            type=int,
            default=None,
            metavar="N",
            help="worker processes (default: one per CPU core)",
        )
        p.add_argument(
            "--out",
            type=Path,
            default=out,
            metavar="FILE",
            help="results JSONL, one line per case as it finishes; a re-run skips finished "
            "cases, so an interrupted run resumes (default: %(default)s)",
        )

    p = what.add_parser(
        "env",
        help="environment throughput, real-time factor, overhead and reset time",
        description="Step SlideGym/TopSlide-v0 with the scripted slider's actions (recorded "
        "once, replayed), then the same world without observations or rewards; time resets.",
    )
    p.add_argument(
        "--object",
        default="square",
        metavar="NAME",
        help="catalog name or JSON file (default: %(default)s)",
    )
    p.add_argument(
        "--table",
        default="square",
        metavar="NAME",
        help="catalog name or JSON file (default: %(default)s)",
    )
    p.add_argument(
        "--steps",
        type=int,
        default=env.STEPS,
        metavar="N",
        help="timed env steps, 50 ms simulated each (default: %(default)s)",
    )
    p.add_argument(
        "--resets",
        type=int,
        default=env.RESETS,
        metavar="N",
        help="timed resets (default: %(default)s)",
    )
    common(p, "reset seed")
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        metavar="FILE",
        help="also append the result as one JSON line here (default: print only)",
    )
    p.set_defaults(func=_cmd_bench_env)

    p = what.add_parser(
        "plan",
        help="the planners' success rate against planning time",
        description="Plan from seeded random start poses with each planner; print success "
        "rates at planning-time marks (resumable, runs in parallel).",
    )
    p.add_argument(
        "--objects",
        default=",".join(plan.OBJECTS),
        metavar="NAMES",
        help="comma-separated objects (default: %(default)s)",
    )
    p.add_argument(
        "--table",
        default=plan.TABLE,
        metavar="NAME",
        help="catalog name or JSON file (default: %(default)s)",
    )
    p.add_argument(
        "--planners",
        default=",".join(PLANNERS),
        metavar="NAMES",
        help=f"comma-separated, from {', '.join(PLANNERS)} (default: %(default)s)",
    )
    p.add_argument(
        "--trials",
        type=int,
        default=plan.TRIALS,
        metavar="N",
        help="start poses per object, seeds SEED..SEED+N-1 (default: %(default)s)",
    )
    p.add_argument(
        "--time-budget",
        type=float,
        default=plan.TIME_BUDGET,
        metavar="SECONDS",
        help="planning time per query (default: %(default)s s)",
    )
    p.add_argument(
        "--dz",
        default=",".join(f"{v:g}" for v in plan.DZ),
        metavar="LO,HI",
        help="contact depth relaxation in metres (default: %(default)s m, the paper's dZ* = 2 cm)",
    )
    common(p, "first start-pose seed")
    jobs(p, plan.OUT)
    p.add_argument(
        "--plot",
        type=Path,
        default=None,
        metavar="FILE",
        help="also write a success-against-time figure here (default: none)",
    )
    p.set_defaults(func=_cmd_bench_plan)

    p = what.add_parser(
        "execute",
        help="the expert's full episodes (slide, grasp, lift) on every object and table",
        description="Run the planner expert in SlideGym/TopSlideGrasp-v0 for seeded episodes "
        "per object and table; print lift rates, slide errors and times (resumable, runs in "
        "parallel).",
    )
    p.add_argument(
        "--objects",
        default=",".join(OBJECT_NAMES),
        metavar="NAMES",
        help="comma-separated objects (default: %(default)s)",
    )
    p.add_argument(
        "--tables",
        default=",".join(TABLE_NAMES),
        metavar="NAMES",
        help="comma-separated tables (default: %(default)s)",
    )
    p.add_argument(
        "--planner",
        choices=PLANNERS,
        default=execute.PLANNER,
        help="the expert's planner (default: %(default)s)",
    )
    p.add_argument(
        "--trials",
        type=int,
        default=execute.TRIALS,
        metavar="N",
        help="episodes per object and table, seeds SEED..SEED+N-1 (default: %(default)s)",
    )
    p.add_argument(
        "--time-budget",
        type=float,
        default=execute.TIME_BUDGET,
        metavar="SECONDS",
        help="planning time per episode, first plan and replans together (default: %(default)s s)",
    )
    common(p, "first episode seed")
    jobs(p, execute.OUT)
    p.add_argument("--markdown", action="store_true", help="print markdown tables, not JSON")
    p.set_defaults(func=_cmd_bench_execute)
