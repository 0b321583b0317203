"""The ``slide-gym`` command. Bad input prints one line to stderr and exits with code 2."""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from slide_gym.planning.search import PLANNERS

if TYPE_CHECKING:  # agents builds on slide_gym: imported on use only
    from agents.record import EpisodeRecord


def _cmd_shapes(args: argparse.Namespace) -> int:
    from slide_gym.geometry import OBJECTS, TABLES, catalog_summary

    rows = catalog_summary()
    if args.json:
        shapes = {"object": OBJECTS, "table": TABLES}
        # the shapes' own JSON (vertex and hole lists) replaces the summary's counts
        full = [{**r, "holes": [], **shapes[r["kind"]][r["name"]].to_json()} for r in rows]
        print(json.dumps(full, indent=2))
        return 0
    print(f"{'kind':<7}{'name':<11}{'vertices':>9}{'holes':>6}{'pieces':>7}{'area cm2':>10}  size")
    for r in rows:
        size = (
            f"thickness {r['thickness'] * 1e3:.1f} mm"
            if r["kind"] == "object"
            else f"height {r['height']:.3f} m"
        )
        print(
            f"{r['kind']:<7}{r['name']:<11}{r['vertices']:>9}{r['holes']:>6}"
            f"{r['convex_pieces']:>7}{r['area'] * 1e4:>10.1f}  {size}"
        )
    return 0


def _cmd_render(args: argparse.Namespace) -> int:
    import imageio.v3 as iio

    from slide_gym.envs.top_slide import TopSlideEnv

    env = TopSlideEnv(
        object=args.object, table=args.table, scale=args.scale, render_mode="rgb_array"
    )
    try:
        env.reset(seed=args.seed)
        frame = env.sim.render(width=args.width, height=args.height)
    finally:
        env.close()
    iio.imwrite(args.out, frame)
    print(f"wrote {args.out}")
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    from agents.scripted import run_demo

    summary = run_demo(args.object, args.table, seed=args.seed, out=args.out)
    print(json.dumps(summary, indent=2))
    return 0


def _floats(text: str, n: int, what: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != n:
        raise ValueError(f"{what} must be {n} comma-separated numbers, got {text!r}")
    return values


def _cmd_plan(args: argparse.Namespace) -> int:
    from slide_gym.planning.runner import make_params, plan_once

    params = make_params(
        dz=_floats(args.dz, 2, "--dz") if args.dz else None, dbeta=args.dbeta, n_star=args.n_star
    )
    pose = _floats(args.object_pose, 3, "--object-pose") if args.object_pose else None
    out = plan_once(
        args.object,
        args.table,
        scale=args.scale,
        object_pose=pose,
        seed=args.seed,
        planner=args.planner,
        time_budget=args.time_budget,
        params=params,
    )
    if args.json:
        print(json.dumps(out))
        return 0
    print(
        f"{out['status']} ({out['planner']}, {out['planning_time_s']:.3f} s): "
        f"{out['object']} on {out['table']} from {out['object_start_pose']}"
    )
    if out["status"] == "solved":
        print(
            f"  goal pose {out['object_goal_pose']}, overhang {out['overhang_m']:.3f} m, "
            f"{len(out['path'])} path configurations"
        )
    elif out["reason"]:
        print(f"  {out['reason']}")
    return 0


def _run_episode() -> Callable[..., EpisodeRecord]:
    """``agents.episode.run_episode``, imported on use."""
    from agents.episode import run_episode

    return run_episode


def _opt(value: Any, spec: str, suffix: str = "") -> str:
    return "n/a" if value is None else f"{value:{spec}}{suffix}"


def _cmd_run(args: argparse.Namespace) -> int:
    r = _run_episode()(
        args.object,
        args.table,
        scale=args.scale,
        seed=args.seed,
        planner=args.planner,
        time_budget=args.time_budget,
        video=args.video,
    )
    if args.json:
        print(json.dumps(r.to_json_dict()))
        return 0
    e = r.expert
    print(
        f"{'lifted' if r.success else 'failed'}: {r.object} on {r.table}, seed {r.seed}, "
        f"{r.planner} planner, phase reached {r.phase_reached}"
    )
    print(
        f"  planned {'yes' if e.planned else 'no'} ({e.replans} replans, "
        f"{_opt(e.planning_time_s, '.2f', ' s')} planning); {r.steps} steps, "
        f"{_opt(r.sim_time_s, '.1f', ' s')} simulated in {_opt(r.wall_time_s, '.1f', ' s')}"
    )
    cm = None if e.slide_error_m is None else 100.0 * e.slide_error_m
    deg = None if e.slide_error_rad is None else math.degrees(e.slide_error_rad)
    pose = r.object_final_pose
    print(
        f"  slide error {_opt(cm, '.1f', ' cm')} / {_opt(deg, '.1f', ' deg')}, lift "
        f"{_opt(r.lift_height_m, '.3f', ' m')}, final pose "
        + ("n/a" if pose is None else "(" + ", ".join(f"{v:.3f}" for v in pose) + ")")
    )
    if e.failure:
        print(f"  failure: {e.failure}")
    if args.video is not None:
        print(f"  wrote {args.video}")
    return 0


def _names(text: str) -> list[str]:
    """A comma-separated list of names (empty items dropped)."""
    return [n for n in text.split(",") if n]


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
        objects=_names(args.objects),
        table=args.table,
        planners=_names(args.planners),
        trials=args.trials,
        time_budget=args.time_budget,
        dz=_floats(args.dz, 2, "--dz"),
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
        objects=_names(args.objects),
        tables=_names(args.tables),
        trials=args.trials,
        out=args.out,
        planner=args.planner,
        time_budget=args.time_budget,
        workers=args.workers,
        seed=args.seed,
    )
    print(execute_markdown_table(summary) if args.markdown else json.dumps(summary, indent=2))
    return 0


def _add_bench(sub: Any) -> None:
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


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="slide-gym", description="Pre-grasp top-sliding of thin objects: tools."
    )
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("shapes", help="list the built-in objects and tables")
    p.add_argument("--json", action="store_true", help="print polygons and sizes as JSON")
    p.set_defaults(func=_cmd_shapes)

    def scene_args(p: argparse.ArgumentParser) -> None:
        p.add_argument("--object", default="L", help="catalog name or JSON file")
        p.add_argument("--table", default="square", help="catalog name or JSON file")
        p.add_argument("--seed", type=int, default=0)

    p = sub.add_parser("render", help="render one start scene to a PNG")
    scene_args(p)
    p.add_argument("--scale", type=float, default=1.0)
    p.add_argument("--width", type=int, default=640)
    p.add_argument("--height", type=int, default=480)
    p.add_argument("--out", type=Path, default=Path("scene.png"))
    p.set_defaults(func=_cmd_render)

    p = sub.add_parser("demo", help="run one scripted episode, write a GIF, print a summary")
    scene_args(p)
    p.add_argument("--out", type=Path, default=None, help="write a GIF (or MP4) here")
    p.set_defaults(func=_cmd_demo)

    p = sub.add_parser("plan", help="plan one top-slide (and grasp) for an object on a table")
    p.add_argument("--object", required=True, help="catalog name or JSON file")
    p.add_argument("--table", required=True, help="catalog name or JSON file")
    p.add_argument("--scale", type=float, default=1.0)
    p.add_argument("--object-pose", default=None, help="X,Y,YAW; default: random from --seed")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--planner", choices=PLANNERS, default="regions")
    p.add_argument("--time-budget", type=float, default=10.0, help="seconds")
    p.add_argument("--dz", default=None, help="LO,HI contact depth relaxation (m)")
    p.add_argument("--dbeta", type=float, default=None, help="pitch relaxation (rad)")
    p.add_argument("--n-star", type=int, default=None, help="root-adding constant N*")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=_cmd_plan)

    p = sub.add_parser(
        "run", help="run the planner expert for one episode (slide, grasp, lift), print a summary"
    )
    scene_args(p)
    p.add_argument("--scale", type=float, default=1.0)
    p.add_argument("--planner", choices=PLANNERS, default="regions")
    p.add_argument("--time-budget", type=float, default=10.0, help="planning seconds per query")
    p.add_argument("--video", type=Path, default=None, help="write an MP4 or GIF here")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=_cmd_run)

    _add_bench(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except ValueError as err:
        command = " ".join(c for c in (args.command, getattr(args, "what", None)) if c)
        print(f"slide-gym {command}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
