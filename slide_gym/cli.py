"""The ``slide-gym`` command. Bad input prints one line to stderr and exits with code 2."""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from slide_gym.planning.search import PLANNERS

PLAN_BENCH_OBJECTS = "square,circle,triangle,crescent,irregular"


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
    from slide_gym.demo import run_demo

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


def _run_episode() -> Callable[..., dict[str, Any]]:
    """``agents.episode.run_episode``, imported on use."""
    from agents.episode import run_episode

    return run_episode


def _opt(value: Any, spec: str, suffix: str = "") -> str:
    return "n/a" if value is None else f"{value:{spec}}{suffix}"


def _cmd_run(args: argparse.Namespace) -> int:
    s = _run_episode()(
        args.object,
        args.table,
        scale=args.scale,
        seed=args.seed,
        planner=args.planner,
        time_budget=args.time_budget,
        video=args.video,
    )
    if args.json:
        print(json.dumps(s))
        return 0
    verdict = "lifted" if s["success"] else "failed"
    print(
        f"{verdict}: {s['object']} on {s['table']}, seed {s['seed']}, {s['planner']} planner, "
        f"phase reached {s['phase_reached']}"
    )
    print(
        f"  planned {'yes' if s['planned'] else 'no'} ({s['replans']} replans, "
        f"{_opt(s['planning_time_s'], '.2f', ' s')} planning); {s['steps']} steps, "
        f"{_opt(s['sim_time_s'], '.1f', ' s')} simulated in {_opt(s['wall_time_s'], '.1f', ' s')}"
    )
    rad, cm = s["slide_error_rad"], s["slide_error_m"]
    pose = s["object_final_pose"]
    print(
        f"  slide error {_opt(None if cm is None else 100.0 * cm, '.1f', ' cm')} / "
        f"{_opt(None if rad is None else math.degrees(rad), '.1f', ' deg')}, lift "
        f"{_opt(s['lift_height_m'], '.3f', ' m')}, final pose "
        + ("n/a" if pose is None else "(" + ", ".join(f"{v:.3f}" for v in pose) + ")")
    )
    if s["failure"]:
        print(f"  failure: {s['failure']}")
    if args.video is not None:
        print(f"  wrote {args.video}")
    return 0


def _names(text: str | None, default: Sequence[str]) -> list[str]:
    return list(default) if text is None else [n for n in text.split(",") if n]


def _cmd_bench(args: argparse.Namespace) -> int:
    if args.what == "execute":
        return _bench_execute(args)
    from slide_gym.bench import bench_env, bench_plan, write_result

    if args.what == "env":
        result = bench_env(
            args.object, args.table, steps=args.steps, resets=args.resets, seed=args.seed
        )
        write_result(result, args.out)
        return 0
    summary = bench_plan(
        objects=_names(args.objects, PLAN_BENCH_OBJECTS.split(",")),
        table=args.table,
        planners=args.planners.split(","),
        trials=20 if args.trials is None else args.trials,
        time_budget=args.time_budget,
        dz=_floats(args.dz, 2, "--dz"),
        out=args.out or Path("results/bench_plan.jsonl"),
        workers=args.workers,
        seed=args.seed,
        plot=args.plot,
    )
    print(json.dumps(summary, indent=2))
    return 0


def _bench_execute(args: argparse.Namespace) -> int:
    from slide_gym.bench_execute import bench_execute, execute_markdown_table
    from slide_gym.geometry import OBJECT_NAMES, TABLE_NAMES

    summary = bench_execute(
        objects=_names(args.objects, OBJECT_NAMES),
        tables=_names(args.tables, TABLE_NAMES),
        trials=10 if args.trials is None else args.trials,
        out=args.out or Path("results/bench_execute.jsonl"),
        planner=args.planner,
        time_budget=args.time_budget,
        workers=args.workers,
        seed=args.seed,
    )
    print(execute_markdown_table(summary) if args.markdown else json.dumps(summary, indent=2))
    return 0


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

    p = sub.add_parser("bench", help="benchmarks (results printed as JSON)")
    p.add_argument(
        "what",
        choices=["env", "plan", "execute"],
        help="env: environment throughput; plan: planners; execute: expert episodes",
    )
    p.add_argument("--object", default="square", help="env: the object")
    p.add_argument(
        "--objects",
        default=None,
        help=f"plan, execute: comma-separated objects (plan: {PLAN_BENCH_OBJECTS}; execute: all)",
    )
    p.add_argument("--table", default="square", help="env, plan: the table")
    p.add_argument("--tables", default=None, help="execute: comma-separated tables (all)")
    p.add_argument("--planners", default="regions,cbirrt2,cbirrt", help="plan: which planners")
    p.add_argument("--planner", choices=PLANNERS, default="regions", help="execute: the planner")
    p.add_argument(
        "--trials",
        type=int,
        default=None,
        help="plan: start poses per object (20); execute: seeds per object and table (10)",
    )
    p.add_argument(
        "--time-budget", type=float, default=10.0, help="plan, execute: seconds per query"
    )
    p.add_argument("--dz", default="0.005,0.025", help="plan: LO,HI (the paper's dZ* = 2 cm)")
    p.add_argument(
        "--workers", type=int, default=None, help="plan, execute: processes (default: cores)"
    )
    p.add_argument(
        "--markdown", action="store_true", help="execute: print markdown tables, not JSON"
    )
    p.add_argument("--plot", type=Path, default=None, help="plan: success-vs-time figure")
    p.add_argument("--steps", type=int, default=600, help="env: steps")
    p.add_argument("--resets", type=int, default=20, help="env: timed resets")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        help="env: append the result here; plan, execute: results JSONL (resumable; default "
        "results/bench_<what>.jsonl)",
    )
    p.set_defaults(func=_cmd_bench)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except ValueError as err:
        print(f"slide-gym {args.command}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
