"""``slide-gym shapes|render|demo|plan|run``: the catalog, one scene, one scripted slide, one
plan, one expert episode."""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from slide_gym import ENV_IDS
from slide_gym.cli.args import check_output, or_na, parse_floats
from slide_gym.planning.search import PLANNERS

if TYPE_CHECKING:  # agents builds on slide_gym: imported on use only
    from agents.record import EpisodeRecord

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
"""What ``render --out`` writes."""
VIDEO_SUFFIXES = (".gif", ".mp4")
"""What ``demo --out`` and ``run --video`` write."""


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
    from slide_gym.sim import MAX_IMAGE_SIDE

    check_output(args.out, IMAGE_SUFFIXES, "--out")
    for option, value in (("--width", args.width), ("--height", args.height)):
        if not 1 <= value <= MAX_IMAGE_SIDE:
            raise ValueError(f"{option} must be 1..{MAX_IMAGE_SIDE} pixels, got {value}")
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

    if args.out is not None:
        check_output(args.out, VIDEO_SUFFIXES, "--out")
    summary = run_demo(args.object, args.table, seed=args.seed, out=args.out)
    print(json.dumps(summary, indent=2))
    return 0


def _cmd_plan(args: argparse.Namespace) -> int:
    from slide_gym.planning.runner import make_params, plan_once

    dz = parse_floats(args.dz, 2, "--dz") if args.dz else None
    params = make_params(dz=dz, dbeta=args.dbeta, n_star=args.n_star)
    pose = parse_floats(args.object_pose, 3, "--object-pose") if args.object_pose else None
    out = plan_once(
        args.object,
        args.table,
        scale=args.scale,
        thickness=args.thickness,
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


def _cmd_run(args: argparse.Namespace) -> int:
    if args.video is not None:
        check_output(args.video, VIDEO_SUFFIXES, "--video")
    r = _run_episode()(
        args.object,
        args.table,
        scale=args.scale,
        seed=args.seed,
        planner=args.planner,
        time_budget=args.time_budget,
        video=args.video,
        thickness=args.thickness,
        env_id=args.env,
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
        f"{or_na(e.planning_time_s, '.2f', ' s')} planning); {r.steps} steps, "
        f"{or_na(r.sim_time_s, '.1f', ' s')} simulated in {or_na(r.wall_time_s, '.1f', ' s')}"
    )
    cm = None if e.slide_error_m is None else 100.0 * e.slide_error_m
    deg = None if e.slide_error_rad is None else math.degrees(e.slide_error_rad)
    pose = r.object_final_pose
    print(
        f"  slide error {or_na(cm, '.1f', ' cm')} / {or_na(deg, '.1f', ' deg')}, lift "
        f"{or_na(r.lift_height_m, '.3f', ' m')}, final pose "
        + ("n/a" if pose is None else "(" + ", ".join(f"{v:.3f}" for v in pose) + ")")
    )
    if e.failure:
        print(f"  failure: {e.failure}")
    if args.video is not None:
        print(f"  wrote {args.video}")
    return 0


def add_parsers(sub: Any) -> None:
    """Register the subcommands on ``sub`` (the top-level subparsers)."""
    p = sub.add_parser("shapes", help="list the built-in objects and tables")
    p.add_argument("--json", action="store_true", help="print polygons and sizes as JSON")
    p.set_defaults(func=_cmd_shapes)

    def scene_args(p: argparse.ArgumentParser, objects: str = "catalog name or JSON file") -> None:
        p.add_argument("--object", default="L", help=objects)
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
    p.add_argument(
        "--object",
        required=True,
        help="catalog name, JSON file, or procedural (the plate of --seed)",
    )
    p.add_argument("--table", required=True, help="catalog name or JSON file")
    p.add_argument("--scale", type=float, default=1.0)
    p.add_argument("--thickness", type=float, default=None, help="override the plate's (m)")
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
    scene_args(p, "catalog name, JSON file, or procedural (the plate of --seed)")
    p.add_argument("--scale", type=float, default=1.0)
    p.add_argument("--thickness", type=float, default=None, help="override the plate's (m)")
    p.add_argument("--planner", choices=PLANNERS, default="regions")
    p.add_argument("--time-budget", type=float, default=10.0, help="planning seconds per query")
    p.add_argument("--video", type=Path, default=None, help="write an MP4 or GIF here")
    p.add_argument(
        "--env", choices=ENV_IDS, default="SlideGym/TopSlideGrasp-v0", help="environment"
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=_cmd_run)
