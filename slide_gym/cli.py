"""The ``slide-gym`` command. Bad input prints one line to stderr and exits with code 2."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path


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


def _cmd_bench(args: argparse.Namespace) -> int:
    from slide_gym.bench import bench_env, bench_plan, write_result

    if args.what == "env":
        result = bench_env(
            args.object, args.table, steps=args.steps, resets=args.resets, seed=args.seed
        )
        write_result(result, args.out)
        return 0
    summary = bench_plan(
        objects=args.objects.split(","),
        table=args.table,
        planners=args.planners.split(","),
        trials=args.trials,
        time_budget=args.time_budget,
        dz=_floats(args.dz, 2, "--dz"),
        out=args.out or Path("results/bench_plan.jsonl"),
        workers=args.workers,
        seed=args.seed,
        plot=args.plot,
    )
    print(json.dumps(summary, indent=2))
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
    p.add_argument("--planner", choices=["regions", "cbirrt", "cbirrt2"], default="regions")
    p.add_argument("--time-budget", type=float, default=10.0, help="seconds")
    p.add_argument("--dz", default=None, help="LO,HI contact depth relaxation (m)")
    p.add_argument("--dbeta", type=float, default=None, help="pitch relaxation (rad)")
    p.add_argument("--n-star", type=int, default=None, help="root-adding constant N*")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=_cmd_plan)

    p = sub.add_parser("bench", help="benchmarks (results printed as JSON)")
    p.add_argument(
        "what", choices=["env", "plan"], help="env: environment throughput; plan: planners"
    )
    p.add_argument("--object", default="square", help="env: the object")
    p.add_argument(
        "--objects",
        default="square,circle,triangle,crescent,irregular",
        help="plan: comma-separated objects",
    )
    p.add_argument("--table", default="square")
    p.add_argument("--planners", default="regions,cbirrt2,cbirrt", help="plan: which planners")
    p.add_argument("--trials", type=int, default=20, help="plan: start poses per object")
    p.add_argument("--time-budget", type=float, default=10.0, help="plan: seconds per query")
    p.add_argument("--dz", default="0.005,0.025", help="plan: LO,HI (the paper's dZ* = 2 cm)")
    p.add_argument("--workers", type=int, default=None, help="plan: processes (default: cores)")
    p.add_argument("--plot", type=Path, default=None, help="plan: success-vs-time figure")
    p.add_argument("--steps", type=int, default=600, help="env: steps")
    p.add_argument("--resets", type=int, default=20, help="env: timed resets")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        help="env: append the result here; plan: results JSONL (resumable)",
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
