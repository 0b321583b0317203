"""``slide-gym bench env|plan|execute``: one subcommand per benchmark, each with its own options."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from slide_gym import DICT_ENV_IDS
from slide_gym.cli.args import (
    HelpFormatter,
    add_backend,
    add_choice,
    add_command,
    add_env,
    add_physics,
    examples_epilog,
    parse_assignments,
    parse_floats,
    parse_names,
    parse_physics,
)
from slide_gym.planning.search import PLANNERS


def _cmd_bench_env(args: argparse.Namespace) -> int:
    from slide_gym.bench.env import bench_env, write_result

    options = ("steps", "resets", "seed", "random_steps", "against", "drag", "stability")
    options += ("rgbd", "image_size", "pointcloud", "num_points")
    result = bench_env(args.object, args.table, **{name: getattr(args, name) for name in options})
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
        backend=args.backend,
        address=args.ray_address,
    )
    print(json.dumps(summary, indent=2))
    return 0


def _cmd_bench_execute(args: argparse.Namespace) -> int:
    from slide_gym.bench.execute import bench_execute, execute_markdown_table

    options = ("trials", "out", "planner", "time_budget", "workers", "seed", "scale", "thickness")
    summary = bench_execute(
        objects=parse_names(args.objects),
        tables=parse_names(args.tables),
        env_id=args.env,
        backend=args.backend,
        address=args.ray_address,
        expert=parse_assignments(args.expert_param, "--expert-param"),
        physics=parse_physics(args.physics),
        **{name: getattr(args, name) for name in options},
    )
    print(execute_markdown_table(summary) if args.markdown else json.dumps(summary, indent=2))
    return 0


def add_parsers(sub: Any) -> None:
    """``slide-gym bench env|plan|execute``: one subcommand each, with its own options."""
    bench = sub.add_parser(
        "bench",
        help="benchmarks: env throughput, planners, expert episodes",
        description="Benchmarks; docs/benchmarks.md comes from these. Results print as JSON.\n"
        "Each benchmark has its own options and defaults: slide-gym bench env --help.",
        epilog=examples_epilog(
            ["slide-gym bench env", "slide-gym bench execute --trials 2 --markdown"]
        ),
        formatter_class=HelpFormatter,
    )
    what = bench.add_subparsers(dest="what", metavar="{env,plan,execute}", required=True)
    _add_env(what)
    _add_plan(what)
    _add_execute(what)


def _parser(
    what: Any,
    name: str,
    help: str,  # noqa: A002
    description: str,
    examples: list[str],
) -> argparse.ArgumentParser:
    """A benchmark subcommand whose help lines end with their defaults, then examples."""
    return add_command(what, name, help, description, [f"slide-gym bench {e}" for e in examples])


def _add_jobs(p: argparse.ArgumentParser, out: Path, first_seed: str) -> None:
    """Options of the resumable, parallel benchmarks."""
    p.add_argument("--seed", type=int, default=0, metavar="N", help=first_seed)
    p.add_argument(
        "--workers", type=int, metavar="N", help="worker processes (default: one per core)"
    )
    add_backend(p)
    p.add_argument(
        "--out",
        type=Path,
        default=out,
        metavar="FILE",
        help="results JSONL, one line per case as it finishes; a re-run skips finished cases, "
        "so an interrupted run resumes",
    )


def _add_trials(
    p: argparse.ArgumentParser, trials: int, trials_help: str, budget: float, budget_help: str
) -> None:
    """``--trials`` and ``--time-budget`` (planning seconds) of a benchmark."""
    p.add_argument("--trials", type=int, default=trials, metavar="N", help=trials_help)
    p.add_argument(
        "--time-budget",
        type=float,
        default=budget,
        metavar="S",
        help=f"planning seconds {budget_help}",
    )


def _add_env(what: Any) -> None:
    from slide_gym.bench import env

    p = _parser(
        what,
        "env",
        "environment throughput, real-time factor, overhead and reset time",
        "Step SlideGym/TopSlide-v0 with the scripted slider's actions (recorded once, "
        "replayed), then the same world without observations or rewards; time resets; then "
        "random actions (optionally against another environment on the same protocol).",
        [
            "env",
            "env --object L --table round --drag --out results/env.jsonl",
            "env --rgbd --pointcloud",
        ],
    )
    p.add_argument("--object", default="square", metavar="NAME", help="catalog name or .json file")
    p.add_argument("--table", default="square", metavar="NAME", help="catalog name or .json file")
    p.add_argument("--steps", type=int, default=env.STEPS, metavar="N", help="timed env steps")
    p.add_argument("--resets", type=int, default=env.RESETS, metavar="N", help="timed resets")
    p.add_argument("--seed", type=int, default=0, metavar="N", help="reset seed")
    p.add_argument(
        "--random-steps",
        type=int,
        default=env.RANDOM_STEPS,
        metavar="N",
        help="timed env steps on random actions (resets included)",
    )
    p.add_argument(
        "--against",
        choices=sorted(env.AGAINST),
        help="also run this environment on the same random actions and print the ratio of "
        "real-time factors (needs: pip install 'slide-gym[compare]')",
    )
    p.add_argument(
        "--drag",
        action="store_true",
        help="also press and drag plates of 0.5-10 mm by 20 cm (sinking, lag, ejections)",
    )
    p.add_argument(
        "--stability",
        action="store_true",
        help="also the fastest arm joint speed in each of 20 random-action episodes",
    )
    p.add_argument(
        "--rgbd",
        action="store_true",
        help="also replay the actions with obs_mode='rgbd' (scene and wrist RGB-D images): "
        "steps/s and the images' cost per step",
    )
    p.add_argument(
        "--image-size",
        type=int,
        nargs=2,
        default=env.IMAGE_SIZE,
        metavar=("W", "H"),
        help="camera size of --rgbd and --pointcloud in pixels (default: {} {})".format(
            *env.IMAGE_SIZE
        ),
    )
    p.add_argument(
        "--pointcloud",
        action="store_true",
        help="also replay the actions with obs_mode='pointcloud' (points fused from both "
        "cameras' depth): steps/s and the points' cost per step",
    )
    p.add_argument(
        "--num-points",
        type=int,
        default=env.NUM_POINTS,
        metavar="N",
        help="points of --pointcloud",
    )
    p.add_argument(
        "--out", type=Path, metavar="FILE", help="also append the result as one JSON line here"
    )
    p.set_defaults(func=_cmd_bench_env)


def _add_plan(what: Any) -> None:
    from slide_gym.bench import plan

    p = _parser(
        what,
        "plan",
        "the planners' success rate against planning time",
        "Plan from seeded random start poses with each planner; print success rates at "
        "planning-time marks (resumable, runs in parallel).",
        ["plan --trials 5 --planners regions,cbirrt2", "plan --objects L,E --plot plan.png"],
    )
    objects, planners, dz = (",".join(v) for v in (plan.OBJECTS, PLANNERS, map(str, plan.DZ)))
    p.add_argument("--objects", default=objects, metavar="NAMES", help="comma-separated objects")
    p.add_argument("--table", default=plan.TABLE, metavar="NAME", help="catalog name or .json file")
    p.add_argument(
        "--planners", default=planners, metavar="NAMES", help=f"comma-separated, from {planners}"
    )
    _add_trials(p, plan.TRIALS, "start poses per object", plan.TIME_BUDGET, "per query")
    p.add_argument("--dz", default=dz, metavar="LO,HI", help="contact depth band (m; dZ* = HI-LO)")
    _add_jobs(p, plan.OUT, "first start-pose seed (trial k uses SEED + k)")
    p.add_argument(
        "--plot", type=Path, metavar="FILE", help="also write a success-against-time figure here"
    )
    p.set_defaults(func=_cmd_bench_plan)


def _add_execute(what: Any) -> None:
    from slide_gym.bench import execute
    from slide_gym.geometry import OBJECT_NAMES, TABLE_NAMES

    p = _parser(
        what,
        "execute",
        "the expert's full episodes (slide, grasp, lift) on every object and table",
        "Run the planner expert (in SlideGym/TopSlideGrasp-v1 unless --env) for seeded "
        "episodes per object and table; print lift rates, slide errors and times (resumable, "
        "runs in parallel).",
        ["execute --trials 2 --markdown", "execute --objects L,procedural --tables square,round"],
    )
    objects, tables = ",".join(OBJECT_NAMES), ",".join(TABLE_NAMES)
    p.add_argument(
        "--objects",
        default=objects,
        metavar="NAMES",
        help="comma-separated objects; procedural: a generated plate per episode, never the "
        "same one on two tables",
    )
    p.add_argument("--tables", default=tables, metavar="NAMES", help="comma-separated tables")
    add_choice(p, "--planner", PLANNERS, "planner", "the tree search", execute.PLANNER)
    budget_help = "per episode, first plan and replans together"
    _add_trials(p, execute.TRIALS, "episodes per scene", execute.TIME_BUDGET, budget_help)
    p.add_argument("--scale", type=float, default=1.0, metavar="FACTOR", help="object size factor")
    p.add_argument(
        "--thickness",
        type=float,
        metavar="M",
        help="every plate's thickness in m (default: each object's own)",
    )
    env_help = (
        f"environment, one of {', '.join(DICT_ENV_IDS)} (TopSlide: the slide alone, "
        "success = left graspable; v0: the physics before friction anchors)"
    )
    add_env(p, "bench execute", env_help, execute.ENV_ID)
    p.add_argument(
        "--expert-param",
        action="append",
        metavar="NAME=VALUE",
        help="override one of the expert's execution settings (agents.params.ExpertParams, "
        "e.g. slide_speed=0.06); repeatable",
    )
    add_physics(p)
    _add_jobs(p, execute.OUT, "first episode seed (trial k uses SEED + k)")
    p.add_argument("--markdown", action="store_true", help="print markdown tables (default: JSON)")
    p.set_defaults(func=_cmd_bench_execute)
