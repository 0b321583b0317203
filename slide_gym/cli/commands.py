"""``slide-gym shapes|render|demo|plan|run``: the catalog, one scene, one scripted slide, one
plan, one expert episode."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from slide_gym import DICT_ENV_IDS, EXPERT_ENV_ID
from slide_gym.cli.args import (
    add_choice,
    add_command,
    add_env,
    add_physics,
    check_name,
    check_output,
    parse_floats,
    parse_physics,
)
from slide_gym.cli.text import demo_text, plan_text, run_text
from slide_gym.geometry import OBJECT_NAMES, TABLE_NAMES
from slide_gym.planning.search import PLANNERS, REFERENCE_PLANNERS
from slide_gym.task import PROCEDURAL, RANDOM

if TYPE_CHECKING:  # agents builds on slide_gym: imported on use only
    from agents.record import EpisodeRecord

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
"""What ``render --out`` writes."""
VIDEO_SUFFIXES = (".gif", ".mp4")
"""What ``demo --out`` and ``run --video`` write."""
ENV_SCENE = ((RANDOM, PROCEDURAL), (RANDOM,))
"""Extra object and table names of the commands that build the environment from names
(``render``, ``demo``, ``run``: ``random`` draws a catalog shape from the seed)."""
PLAN_SCENE = ((PROCEDURAL,), ())
"""Extra object and table names of ``plan`` (one fixed scene)."""


def _check_scene(args: argparse.Namespace, extra: tuple[tuple[str, ...], ...]) -> None:
    """``--object`` and ``--table`` are names the command knows (or ``.json`` paths)."""
    check_name(args.object, "object", OBJECT_NAMES, extra[0])
    check_name(args.table, "table", TABLE_NAMES, extra[1])


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
    from slide_gym.envs.cameras import check_size

    _check_scene(args, ENV_SCENE)
    check_output(args.out, IMAGE_SUFFIXES, "--out")
    width, height = check_size("--width", args.width), check_size("--height", args.height)
    import imageio.v3 as iio

    from slide_gym.envs.top_slide import TopSlideEnv

    env = TopSlideEnv(
        object=args.object,
        table=args.table,
        scale=args.scale,
        render_mode="rgb_array",
        render_width=width,
        render_height=height,
    )
    try:
        env.reset(seed=args.seed)
        frame = env.render()
    finally:
        env.close()
    iio.imwrite(args.out, frame)
    print(f"wrote {args.out}")
    return 0


def _run_demo() -> Callable[..., dict[str, Any]]:
    """``agents.scripted.run_demo``, imported on use."""
    from agents.scripted import run_demo

    return run_demo


def _cmd_demo(args: argparse.Namespace) -> int:
    _check_scene(args, ENV_SCENE)
    if args.out is not None:
        check_output(args.out, VIDEO_SUFFIXES, "--out")
    summary = _run_demo()(args.object, args.table, seed=args.seed, out=args.out)
    print(json.dumps(summary, indent=2) if args.json else demo_text(summary))
    return 0


def _cmd_plan(args: argparse.Namespace) -> int:
    from slide_gym.planning.runner import make_params, plan_once

    _check_scene(args, PLAN_SCENE)
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
    print(json.dumps(out) if args.json else plan_text(out))
    return 0


def _run_episode() -> Callable[..., EpisodeRecord]:
    """``agents.episode.run_episode``, imported on use."""
    from agents.episode import run_episode

    return run_episode


def _object_pose(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--object-pose",
        metavar="X,Y,YAW",
        help="start pose in m, m, rad (default: random from --seed, the env's draw)",
    )


def _cmd_run(args: argparse.Namespace) -> int:
    _check_scene(args, ENV_SCENE)
    if args.video is not None:
        check_output(args.video, VIDEO_SUFFIXES, "--video")
    pose = parse_floats(args.object_pose, 3, "--object-pose") if args.object_pose else None
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
        object_pose=pose,
        physics=parse_physics(args.physics),
    )
    if args.json:
        print(json.dumps(r.to_json_dict()))
        return 0
    print(run_text(r))
    if args.video is not None:
        print(f"  wrote {args.video}")
    return 0


def _scene_args(p: argparse.ArgumentParser, extra: tuple[tuple[str, ...], ...], seed: str) -> None:
    """``--object``, ``--table`` and ``--seed``; ``extra``: the names besides the catalog's."""
    hints = {
        RANDOM: "random (a catalog shape drawn from --seed)",
        PROCEDURAL: "procedural (the plate of --seed)",
    }
    objects, tables = (
        ", ".join(["catalog name (see: slide-gym shapes)", *(hints[n] for n in names)])
        + " or .json file"
        for names in extra
    )
    p.add_argument("--object", default="L", metavar="NAME", help=objects)
    p.add_argument("--table", default="square", metavar="NAME", help=tables)
    p.add_argument("--seed", type=int, default=0, metavar="N", help=seed)


def _scale(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scale", type=float, default=1.0, metavar="FACTOR", help="object size factor")


def _thickness(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--thickness",
        type=float,
        metavar="M",
        help="plate thickness in m (default: the object's own)",
    )


def _planning(
    p: argparse.ArgumentParser, budget_help: str, planners: Sequence[str] = PLANNERS
) -> None:
    """``--planner`` (one of ``planners``) and ``--time-budget``."""
    add_choice(p, "--planner", planners, "planner", "the tree search", "regions")
    p.add_argument(
        "--time-budget",
        type=float,
        default=10.0,
        metavar="S",
        help=f"planning time in s {budget_help}",
    )


def _json_flag(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument(
        "--json", action="store_true", help=f"print {what} (default: a short plain-text summary)"
    )


def add_parsers(sub: Any) -> None:
    """Register the subcommands on ``sub`` (the top-level subparsers)."""
    p = add_command(
        sub,
        "shapes",
        "list the built-in objects and tables",
        "The catalog: every object (polygon, thickness) and table (polygon, height).",
        ["slide-gym shapes", "slide-gym shapes --json > shapes.json"],
    )
    p.add_argument(
        "--json",
        action="store_true",
        help="print polygons and sizes as JSON (default: a plain-text table)",
    )
    p.set_defaults(func=_cmd_shapes)

    p = add_command(
        sub,
        "render",
        "render one start scene to a PNG",
        "Reset SlideGym/TopSlide-v0 with --seed and render the start scene to an image.",
        ["slide-gym render --object L --table round --out scene.png"],
    )
    _scene_args(p, ENV_SCENE, "reset seed: the start pose")
    _scale(p)
    p.add_argument("--width", type=int, default=640, metavar="PX", help="image width, pixels")
    p.add_argument("--height", type=int, default=480, metavar="PX", help="image height, pixels")
    p.add_argument(
        "--out", type=Path, default=Path("scene.png"), metavar="FILE", help="PNG or JPEG to write"
    )
    p.set_defaults(func=_cmd_render)

    p = add_command(
        sub,
        "demo",
        "run one scripted slide (no planner), optionally write a GIF, print a summary",
        "Run the scripted slider for one episode of SlideGym/TopSlide-v0 (no planner).",
        [
            "slide-gym demo --object L --out demo.gif",
            "slide-gym demo --object E --table round --seed 3 --json",
        ],
    )
    _scene_args(p, ENV_SCENE, "episode seed: the start pose")
    p.add_argument("--out", type=Path, metavar="FILE", help="also write a GIF (or MP4) here")
    _json_flag(p, "the summary as JSON")
    p.set_defaults(func=_cmd_demo)

    p = add_command(
        sub,
        "plan",
        "plan one top-slide (and grasp) for an object on a table",
        "Plan a slide of the object from its start pose to a graspable overhang, and the "
        "grasp; --json prints every field (see docs/planners.md, 'slide-gym plan').",
        [
            "slide-gym plan --object E --table round --seed 3",
            "slide-gym plan --object L --object-pose 0.6,0.1,0.3 --planner cbirrt2 --json",
        ],
    )
    _scene_args(p, PLAN_SCENE, "seed of the start pose (and of the procedural plate)")
    _scale(p)
    _thickness(p)
    _object_pose(p)
    _planning(p, "for the query", (*PLANNERS, *REFERENCE_PLANNERS))
    p.add_argument(
        "--dz", metavar="LO,HI", help="contact depth relaxation in m (default: the planner's)"
    )
    p.add_argument(
        "--dbeta",
        type=float,
        metavar="RAD",
        help="pitch relaxation in rad (default: the planner's)",
    )
    p.add_argument(
        "--n-star", type=int, metavar="N", help="root-adding constant N* (default: the planner's)"
    )
    _json_flag(p, "one JSON object, full precision")
    p.set_defaults(func=_cmd_plan)

    p = add_command(
        sub,
        "run",
        "run the planner expert for one episode (slide, grasp, lift), print a summary",
        "Run the planner-driven expert for one seeded episode: plan, slide, grasp, lift.",
        [
            "slide-gym run --object E --table square --seed 0 --video expert.gif",
            "slide-gym run --object procedural --seed 7 --json",
        ],
    )
    _scene_args(p, ENV_SCENE, "episode seed: the start pose (and the random or procedural draws)")
    _scale(p)
    _thickness(p)
    _object_pose(p)
    _planning(p, "per query")
    p.add_argument("--video", type=Path, metavar="FILE", help="also write an MP4 or GIF here")
    add_env(p, "run", f"environment, one of {', '.join(DICT_ENV_IDS)}", EXPERT_ENV_ID)
    add_physics(p)
    _json_flag(p, "one JSON object, full precision")
    p.set_defaults(func=_cmd_run)
