"""``slide-gym collect | replay | export | train-bc | evaluate``: demonstration datasets and
the agents learned from them."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from slide_gym import DICT_ENV_IDS, EXPERT_ENV_ID
from slide_gym.cli.args import (
    add_backend,
    add_choice,
    add_command,
    add_env,
    add_only_success,
    add_physics,
    add_randomization,
    check_output,
    one_line_warnings,
    parse_assignments,
    parse_physics,
    parse_randomization,
)
from slide_gym.planning.search import PLANNERS
from slide_gym.splits import SPLIT_NAMES, SPLITS, TEST_SEED, TRAIN_SEED, VALIDATION_SEED


def _split_scene(args: argparse.Namespace, command: str, default_seed: int) -> str | None:
    """Apply ``--split``: its object and (unless given) its first seed; check the seeds.
    Without it, ``--seed`` defaults to ``default_seed``. The object, or None if not given."""
    if args.split is None:
        args.seed = default_seed if args.seed is None else args.seed
        return args.object
    split = SPLITS[args.split]
    if args.object is not None and args.object != split.object:
        raise ValueError(
            f"--split {split.name} sets the object ({split.object!r}); leave out --object "
            f"{args.object}"
        )
    args.seed = split.first_seed(command, args.episodes, args.seed)
    return split.object


def _add_split(p: argparse.ArgumentParser, command: str) -> None:
    names = "; ".join(f"{s.name}: {s.description}" for s in SPLITS.values())
    add_choice(
        p,
        "--split",
        SPLIT_NAMES,
        "split",
        f"a named split (slide_gym.splits): sets --object and the reset seeds {command} draws "
        f"from (--seed: default the first of them, must stay within them). {names}",
        metavar="NAME",
    )


OBS_MODES = ("state", "rgbd", "pointcloud")
""":data:`slide_gym.envs.observation.OBS_MODES`, without importing the envs for ``--help``."""


def _cmd_collect(args: argparse.Namespace) -> int:
    from slide_gym.datasets.collect import collect, failure_report
    from slide_gym.datasets.config import CollectConfig

    obj = _split_scene(args, "collect", TRAIN_SEED)
    config = CollectConfig(
        env_id=args.env,
        agent=args.agent,
        object="square" if obj is None else obj,
        table=args.table,
        scale=args.scale,
        thickness=args.thickness,
        obs_mode=args.obs_mode,
        control_mode=args.control_mode,
        time_budget=args.time_budget,
        seed=args.seed,
        only_success=args.only_success,
        action_noise=args.action_noise,
        noise_phases=None if args.noise_phases is None else args.noise_phases.split(","),
        split=args.split,
        randomization=parse_randomization(args.randomization),
        physics=parse_physics(args.physics),
        planner_params=parse_assignments(args.planner_param, "--planner-param"),
        expert_params=parse_assignments(args.expert_param, "--expert-param"),
    )
    summary = collect(
        config,
        args.episodes,
        args.dataset_id,
        workers=args.workers,
        backend=args.backend,
        address=args.ray_address,
    )
    print(json.dumps(summary, indent=2))
    print(failure_report(summary), file=sys.stderr)
    return 0


def _cmd_replay(args: argparse.Namespace) -> int:
    from slide_gym.datasets.replay import replay

    rerender_options = ("obs_mode", "save_as", "image_size", "num_points", "workers")
    if any(getattr(args, name) is not None for name in rerender_options):
        return _rerender(args)
    if args.video is not None:
        check_output(args.video, (".mp4", ".gif"), "--video")
    results = replay(args.dataset_id, episodes=args.episodes, mode=args.mode, video=args.video)
    if args.json:
        print(json.dumps([r.to_json() for r in results], indent=2))
    else:
        approximate = args.mode == "states"
        for r in results:
            if r.matched:
                state = "matches within the tolerance" if approximate else "matches"
            else:
                beyond = " beyond the tolerance" if approximate else ""
                state = f"differs{beyond} from step {r.first_mismatch}"
            worst = ", ".join(f"{k} {v:.2g}" for k, v in r.max_errors.items() if v > 0)
            print(
                f"episode {r.episode} (seed {r.seed}, {r.steps} steps): {state}; "
                f"largest differences: {worst or 'none'}"
            )
        matched = sum(r.matched for r in results)
        how = (
            "approximate: each step from its restored sim_state, within the measured worst "
            "case, slide_gym.datasets.replay.STATE_TOLERANCE"
            if approximate
            else "exact: bit for bit"
        )
        print(f"{matched} of {len(results)} episodes match ({args.mode} replay, {how})")
    return 0 if all(r.matched for r in results) else 1


def _rerender(args: argparse.Namespace) -> int:
    from slide_gym.datasets.rerender import rerender

    if args.obs_mode is None or args.save_as is None:
        raise ValueError(
            "--obs-mode and --save-as go together (--image-size, --num-points and --workers "
            "with them): replay ID --obs-mode MODE --save-as NEW_ID"
        )
    if args.mode != "actions" or args.video is not None:
        raise ValueError("--save-as replays the actions; it takes no --mode states or --video")
    summary = rerender(
        args.dataset_id,
        args.obs_mode,
        args.save_as,
        episodes=args.episodes,
        image_size=args.image_size,
        num_points=args.num_points,
        workers=args.workers,
        backend=args.backend,
        address=args.ray_address,
    )
    print(json.dumps(summary, indent=2))
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    from slide_gym.datasets.lerobot import check_export_folder, export_lerobot
    from slide_gym.datasets.store import dataset_metadata, load

    check_export_folder(args.out)
    dataset = load(args.dataset_id)
    meta = dataset_metadata(dataset)
    env = dataset.recover_environment()
    try:
        fps = float(env.metadata.get("render_fps", 20))
    finally:
        env.close()
    goal = (
        "slide it over the table edge"
        if "Grasp" not in dataset.spec.env_spec.id
        else ("slide it over the table edge, grasp it and lift it")
    )
    config = meta.get("config", {})
    task = f"Press the {config.get('object', 'thin')} plate with a fingertip, {goal}."
    summary = export_lerobot(dataset, args.out, task=task, fps=fps)
    print(json.dumps({"out": str(args.out), "format": args.format, **summary}, indent=2))
    return 0


def _cmd_train_bc(args: argparse.Namespace) -> int:
    from agents.bc import train_bc, write_model_card
    from slide_gym.datasets.store import dataset_metadata, load

    check_output(args.out, (".zip",), "--out")
    dataset = load(args.dataset_id)
    env = dataset.recover_environment()
    if args.env is not None and args.env != env.spec.id:
        env.close()
        raise ValueError(
            f"--env {args.env} differs from the dataset's env {env.spec.id}; the policy must "
            "act in the env its demonstrations come from"
        )
    try:
        model, stats = train_bc(
            dataset,
            steps=args.steps,
            batch_size=args.batch_size,
            seed=args.seed,
            env=env,
            only_success=args.only_success,
        )
        model.save(args.out)
    finally:
        env.close()
    meta = dataset_metadata(dataset)
    card = write_model_card(
        args.out,
        env.spec.id,
        dict(meta.get("env_kwargs") or {}),
        {"dataset_id": args.dataset_id, "training": stats},
    )
    print(json.dumps({"model": str(args.out), "card": str(card), **stats}, indent=2))
    return 0


def _cmd_evaluate(args: argparse.Namespace) -> int:
    from agents.evaluate import evaluate, failure_summary

    args.object = _split_scene(args, "evaluate", TEST_SEED)
    env_kwargs: dict[str, Any] = {}
    for name in ("object", "table", "control_mode"):
        if getattr(args, name) is not None:
            env_kwargs[name] = getattr(args, name)
    if args.randomization is not None:
        env_kwargs["randomization"] = parse_randomization(args.randomization)
    if args.physics:
        env_kwargs["physics"] = parse_physics(args.physics)
    with one_line_warnings("evaluate"):
        result = evaluate(
            args.agent,
            args.env,
            episodes=args.episodes,
            seed=args.seed,
            env_kwargs=env_kwargs,
            time_budget=args.time_budget,
            progress=not args.json,
            action_horizon=args.action_horizon,
            noise_scale=args.noise_scale,
            inference_steps=args.inference_steps,
            samples=args.samples,
        )
    if args.split is not None:
        result["split"] = args.split
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        lo, hi = result["ci95"]
        print(
            f"{result['agent']} in {result['env_id']}: {result['successes']} of "
            f"{result['episodes']} succeeded ({100 * result['success_rate']:.0f} %, 95 % "
            f"interval {100 * lo:.0f}-{100 * hi:.0f} %), mean length "
            f"{result['mean_length']:.0f} steps{failure_summary(result['ended'])}"
        )
    return 0


def add_parsers(sub: Any) -> None:
    """Register the dataset commands."""
    envs = ", ".join(DICT_ENV_IDS)
    p = add_command(
        sub,
        "collect",
        "record expert episodes into a Minari dataset (parallel, resumable)",
        "Run the planner expert for episodes with reset seeds SEED, SEED+1, ... and store "
        "them as a Minari dataset (observations, actions, rewards, and per step the infos "
        "with infos['sim_state']; per episode the reset seed and options and the run "
        "record). Each finished episode is saved at once, so Ctrl-C or a kill loses only "
        "the episodes in flight: the same command again continues to N. The same dataset "
        "id with another configuration is refused. Datasets live in Minari's folder "
        "(MINARI_DATASETS_PATH, default ~/.minari/datasets) and open with "
        "minari.load_dataset(ID).",
        [
            "slide-gym collect --env SlideGym/TopSlide-v0 --episodes 20 "
            "--dataset-id slide-gym/square-slide-v0",
            "slide-gym collect --env SlideGym/TopSlideGrasp-v0 --object random --table random "
            "--episodes 100 --only-success --workers 2 --dataset-id slide-gym/catalog-grasp-v0",
        ],
    )
    add_env(p, "collect", f"one of {envs}", EXPERT_ENV_ID)
    add_choice(p, "--agent", PLANNERS, "agent", "the expert's planner", "regions", "NAME")
    p.add_argument("--episodes", type=int, required=True, metavar="N", help="episodes to keep")
    p.add_argument(
        "--dataset-id", required=True, metavar="NAMESPACE/NAME-vK", help="the Minari dataset id"
    )
    p.add_argument(
        "--object",
        metavar="NAME",
        help="catalog name, .json file, random (a catalog object per episode) or procedural "
        "(the plate of each seed) (default: square, or the --split's)",
    )
    p.add_argument(
        "--table", default="square", metavar="NAME", help="catalog name, .json file or random"
    )
    p.add_argument("--scale", type=float, default=1.0, metavar="S", help="object scale factor")
    p.add_argument("--thickness", type=float, metavar="M", help="plate thickness in m")
    p.add_argument("--obs-mode", default="state", choices=OBS_MODES, help="env obs mode")
    p.add_argument(
        "--control-mode",
        default="joint_delta",
        choices=("joint_delta", "ee_delta"),
        help="env control mode",
    )
    p.add_argument(
        "--time-budget", type=float, default=10.0, metavar="S", help="planning s per episode"
    )
    p.add_argument(
        "--seed", type=int, metavar="N", help=f"first reset seed (default: {TRAIN_SEED})"
    )
    _add_split(p, "collect")
    p.add_argument("--workers", type=int, metavar="W", help="parallel episodes (default: cores)")
    add_backend(p)
    p.add_argument(
        "--only-success",
        action="store_true",
        help="keep only successful episodes, running further seeds until N succeed",
    )
    p.add_argument(
        "--action-noise",
        type=float,
        default=0.0,
        metavar="SIGMA",
        help="DART: execute the expert's arm actions plus seeded Gaussian noise of this "
        "standard deviation (action units) and store its clean actions as labels "
        "(infos['expert_action'])",
    )
    p.add_argument(
        "--noise-phases",
        metavar="PHASE,...",
        help="with --action-noise: only in these phases of the expert, e.g. "
        "approach,transfer (the free-space moves); default: every phase",
    )
    p.add_argument(
        "--planner-param",
        action="append",
        metavar="NAME=VALUE",
        help="override one of the expert's planner parameters (u_star, centroid_margin, "
        "press_radius, max_rotation), e.g. u_star=0.03: slides that stop at 3 cm of overhang; "
        "repeatable",
    )
    p.add_argument(
        "--expert-param",
        action="append",
        metavar="NAME=VALUE",
        help="override one of the expert's execution settings (agents.params.ExpertParams), "
        "e.g. stop_overhang=0.035: every slide ends once the plate overhangs 3.5 cm; repeatable",
    )
    add_randomization(p)
    add_physics(p)
    p.set_defaults(func=_cmd_collect)

    p = add_command(
        sub,
        "replay",
        "replay a dataset's episodes, check them against the record, or re-render them",
        "Replay episodes in the dataset's env. --mode actions resets with each episode's "
        "seed and options and steps its actions: every observation must match bit for bit. "
        "--mode states restores each step's infos['sim_state'] and steps its action: an "
        "approximate check, since PyBullet keeps contact caches no state vector holds, so "
        "poses must match within the largest differences measured on expert datasets "
        "(slide_gym.datasets.replay.STATE_TOLERANCE). Exit 0 only if every episode matches "
        "(1 otherwise). With --obs-mode and --save-as, the actions are replayed with another "
        "observation mode into a new dataset (state entries, rewards and sim states checked "
        "bit for bit against the source; parallel and resumable like collect; the metadata "
        "names the source).",
        [
            "slide-gym replay slide-gym/square-slide-v0",
            "slide-gym replay slide-gym/square-slide-v0 --episodes 2 --video replay.mp4",
            "slide-gym replay slide-gym/square-slide-v0 --obs-mode pointcloud "
            "--save-as slide-gym/square-slide-pointcloud-v0 --workers 2",
        ],
    )
    p.add_argument("dataset_id", metavar="DATASET_ID", help="a local Minari dataset id")
    p.add_argument("--episodes", type=int, metavar="K", help="the first K episodes (default: all)")
    p.add_argument(
        "--mode",
        default="actions",
        choices=("actions", "states"),
        help="actions: exact; states: approximate (see above)",
    )
    p.add_argument("--video", type=Path, metavar="OUT", help="render the replay to .mp4 or .gif")
    p.add_argument("--json", action="store_true", help="print the results as JSON")
    p.add_argument(
        "--obs-mode",
        metavar="MODE",
        help=f"re-render into --save-as with this observation mode: {', '.join(OBS_MODES)}",
    )
    p.add_argument("--save-as", metavar="NEW_ID", help="the new dataset's id (NAMESPACE/NAME-vK)")
    p.add_argument(
        "--image-size",
        type=int,
        nargs=2,
        metavar=("W", "H"),
        help="camera size of rgbd and pointcloud in pixels (default: the source env's, else "
        "128 128)",
    )
    p.add_argument(
        "--num-points", type=int, metavar="N", help="points of pointcloud (default: 1024)"
    )
    p.add_argument(
        "--workers", type=int, metavar="W", help="parallel episodes of --save-as (default: cores)"
    )
    add_backend(p)
    p.set_defaults(func=_cmd_replay)

    p = add_command(
        sub,
        "export",
        "export a dataset to the LeRobot v3.0 layout",
        "Write the dataset as a LeRobotDataset v3.0 folder (parquet via pyarrow; the Dict "
        "observation flattened into observation.state, keys in sorted order), without "
        "needing the lerobot package.",
        ["slide-gym export slide-gym/square-slide-v0 --format lerobot --out exports/square"],
    )
    p.add_argument("dataset_id", metavar="DATASET_ID", help="a local Minari dataset id")
    p.add_argument("--format", default="lerobot", choices=("lerobot",), help="output format")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="a new folder")
    p.set_defaults(func=_cmd_export)

    p = add_command(
        sub,
        "train-bc",
        "behaviour cloning from a dataset into a Stable-Baselines3 policy",
        "Fit an SB3 PPO MultiInputPolicy to the dataset's (observation, action) pairs by "
        "maximum likelihood and save it (PPO.load opens it); MODEL.json next to it records "
        "the env and its arguments, which `slide-gym evaluate MODEL.zip` uses.",
        ["slide-gym train-bc slide-gym/square-slide-v0 --out models/bc.zip --steps 5000"],
    )
    p.add_argument("dataset_id", metavar="DATASET_ID", help="a local Minari dataset id")
    p.add_argument("--out", type=Path, required=True, metavar="MODEL.zip", help="model file")
    p.add_argument("--steps", type=int, default=5000, metavar="N", help="gradient steps")
    p.add_argument("--batch-size", type=int, default=256, metavar="B", help="pairs per step")
    p.add_argument("--env", metavar="ENV_ID", help="must be the dataset's env (a check)")
    p.add_argument("--seed", type=int, default=0, metavar="N", help="training seed")
    add_only_success(p)
    p.set_defaults(func=_cmd_train_bc)

    p = add_command(
        sub,
        "evaluate",
        "success rate of a saved policy or a planner agent",
        f"Run episodes with reset seeds SEED, SEED+1, ... (default {TEST_SEED}: held out from "
        f"collections, which start at {TRAIN_SEED}, and from the validation seeds of train-dp, "
        f"from {VALIDATION_SEED}; see slide_gym.splits) and print the success rate with a "
        "95 % Wilson interval and the mean episode length. AGENT is a saved SB3 model, a "
        "train-dp folder, 'random' or a planner.",
        [
            "slide-gym evaluate models/bc.zip --env SlideGym/TopSlide-v0 --episodes 20",
            "slide-gym evaluate models/dp-square --env SlideGym/TopSlide-v0 --episodes 100",
            "slide-gym evaluate regions --env SlideGym/TopSlide-v0 --episodes 20 --json",
            "slide-gym evaluate regions --env SlideGym/TopSlide-v0 --episodes 40 "
            "--randomization default",
        ],
    )
    p.add_argument(
        "agent",
        metavar="AGENT",
        help="a saved SB3 model (.zip), a train-dp policy folder, 'random', or a planner: "
        f"{', '.join(PLANNERS)}",
    )
    add_env(p, "evaluate", f"one of {envs}", EXPERT_ENV_ID)
    p.add_argument("--episodes", type=int, required=True, metavar="N", help="episodes")
    p.add_argument("--seed", type=int, metavar="S", help=f"first reset seed (default: {TEST_SEED})")
    _add_split(p, "evaluate")
    p.add_argument(
        "--object",
        metavar="NAME",
        help="env object (default: the --split's, else the model's, else the env's)",
    )
    p.add_argument("--table", metavar="NAME", help="env table (as --object)")
    p.add_argument(
        "--control-mode",
        choices=("joint_delta", "ee_delta"),
        help="env control mode (default: the model's, else joint_delta)",
    )
    p.add_argument(
        "--time-budget", type=float, default=10.0, metavar="S", help="planner agents' budget"
    )
    p.add_argument(
        "--action-horizon",
        type=int,
        metavar="K",
        help="a train-dp policy's actions executed per chunk (default: the policy's, 8)",
    )
    p.add_argument(
        "--noise-scale",
        type=float,
        metavar="S",
        help="a train-dp policy's initial sampling noise, scaled: 1 samples its action "
        "distribution (default), 0 starts each chunk from zero noise; in [0, 1]",
    )
    p.add_argument(
        "--inference-steps",
        type=int,
        metavar="K",
        help="a train-dp policy's DDIM steps per chunk (default: the policy's, 10); 1..its "
        "training diffusion steps (100)",
    )
    p.add_argument(
        "--samples",
        type=int,
        metavar="K",
        help="a train-dp policy's chunks drawn per decision; it executes their medoid, the one "
        "nearest the others (default 1: a single sample); 1..64",
    )
    add_randomization(p)
    add_physics(p)
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(func=_cmd_evaluate)
