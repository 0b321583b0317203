"""``slide-gym train-dp``: a diffusion policy learned from a demonstration dataset."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from slide_gym.cli.args import add_backend, add_command, add_only_success, parse_assignments
from slide_gym.splits import DAGGER_SEED, TEST_SEED, VALIDATION_SEED


def _cmd_train_dp(args: argparse.Namespace) -> int:
    from agents.learned.diffusion import DiffusionConfig
    from agents.learned.train import TrainConfig, check_device, train_diffusion
    from slide_gym.datasets.store import dataset_metadata, load

    check_device(args.device)  # before the dataset loads

    config = DiffusionConfig(
        channels=tuple(args.channels),
        inference_steps=args.inference_steps,
        with_features=not args.no_features,
        tip_axes=args.tip_axes,
        actions=args.actions,
        scaling=args.scaling,
        obs_embed=args.obs_embed,
    )
    train = TrainConfig(
        iterations=args.iterations,
        batch_size=args.batch_size,
        learning_rate=args.lr,
        seed=args.seed,
        log_every=args.log_every,
        val_every=args.val_every,
        val_episodes=args.val_episodes,
    )
    init = _policy_weights(args.init, "--init", "a folder written by `slide-gym train-dp`")
    first = _policy_weights(
        args.after, "--after", "the folder of a sliding policy written by `slide-gym train-dp`"
    )
    episode_seeds = _episode_seeds(args.episode_seeds)
    dataset = load(args.dataset_id)
    meta = dataset_metadata(dataset)
    summary = train_diffusion(
        dataset,
        args.out,
        config=config,
        train=train,
        env_id=dataset.spec.env_spec.id,
        env_kwargs=dict(meta.get("env_kwargs") or {}),
        card={
            "dataset_id": args.dataset_id,
            **({"init": str(args.init)} if init else {}),
            **({"after": str(args.after)} if first else {}),
            **({"episode_seeds": str(args.episode_seeds)} if episode_seeds else {}),
        },
        resume=args.resume,
        only_success=args.only_success,
        init=init,
        first=first,
        device=args.device,
        snapshot_every=args.snapshot_every,
        episode_seeds=episode_seeds,
    )
    print(json.dumps({"out": str(args.out), **summary}, indent=2))
    return 0


def _cmd_choose_checkpoint(args: argparse.Namespace) -> int:
    from agents.learned.train import choose_snapshot

    card = choose_snapshot(args.run, episodes=args.episodes, progress=True)
    print(json.dumps({"run": str(args.run), "checkpoint": card["checkpoint"]}, indent=2))
    return 0


def _episode_seeds(path: str | None) -> frozenset[int] | None:
    """The reset seeds listed in the JSON file ``path`` (None without one); ValueError if it
    is not a non-empty list of whole numbers."""
    if path is None:
        return None
    try:
        seeds = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"--episode-seeds {path!r}: not a readable JSON file ({exc})") from None
    if (
        not isinstance(seeds, list)
        or not seeds
        or not all(isinstance(s, int) and not isinstance(s, bool) for s in seeds)
    ):
        raise ValueError(
            f"--episode-seeds {path!r} must hold a non-empty JSON list of episode seeds "
            "(whole numbers), e.g. [0, 3, 4]"
        )
    return frozenset(seeds)


def _policy_weights(folder: str | None, option: str, what: str) -> Path | None:
    """``folder``'s ``policy.pt`` (None without ``folder``); ValueError if it holds none."""
    if folder is None:
        return None
    from agents.learned.policy import WEIGHTS_FILE, is_policy_dir

    if not is_policy_dir(folder):
        raise ValueError(
            f"{option} {str(folder)!r} holds no diffusion policy (no {WEIGHTS_FILE}); give {what}"
        )
    return Path(folder) / WEIGHTS_FILE


def _cmd_dagger(args: argparse.Namespace) -> int:
    from agents.learned.dagger import DaggerConfig, run_dagger

    config = DaggerConfig(
        rounds=args.rounds,
        episodes=args.episodes,
        beta=args.beta,
        decay=args.decay,
        label_budget=args.label_budget,
        iterations=args.iterations,
        seed=args.seed,
        max_steps=args.max_steps,
        skip_phases=tuple(args.skip_phases),
        chunk_every=args.chunk_labels,
        expert_params=parse_assignments(args.expert_param, "--expert-param"),
        label_from_overhang=args.label_from_overhang,
        label_from_miss=args.label_from_miss,
    )
    if args.env is not None:
        from agents.learned.policy import CARD_FILE, is_policy_dir

        if is_policy_dir(args.policy):
            card = json.loads((args.policy / CARD_FILE).read_text())
            if card.get("env_id") != args.env:
                raise ValueError(
                    f"--env {args.env} differs from the policy's env {card.get('env_id')}; "
                    "DAgger runs the policy in the env it was trained for"
                )
    summary = run_dagger(
        args.policy,
        args.out,
        args.dataset_id,
        config,
        workers=args.workers,
        backend=args.backend,
        address=args.ray_address,
    )
    print(json.dumps(summary, indent=2))
    return 0


def add_parsers(sub: Any) -> None:
    """Register the learning commands."""
    p = add_command(
        sub,
        "train-dp",
        "train a diffusion policy (action chunks, DDIM) on a demonstration dataset",
        "Train a 1-D U-Net diffusion policy (observation horizon 2, chunks of 16 actions, 8 "
        "executed) on the dataset's successful episodes (--only-success, the default) and its "
        "DAgger rollouts, in the dataset's env. DIR gets "
        "checkpoint.pt (every --log-every iterations, and on Ctrl-C), progress.csv (loss; "
        f"success on validation seeds from {VALIDATION_SEED} every --val-every iterations), "
        "learning_curve.png, and policy.pt/policy.json: the EMA weights of the checkpoint "
        "with the best validation success. `slide-gym evaluate DIR` tests it (seeds from "
        f"{TEST_SEED}); --resume continues a run.",
        [
            "slide-gym train-dp slide-gym/square-slide-v1 --out models/dp-square",
            "slide-gym train-dp slide-gym/square-slide-v1 --out models/dp-square --resume",
            "slide-gym evaluate models/dp-square --env SlideGym/TopSlide-v0 --episodes 100",
        ],
    )
    p.add_argument("dataset_id", metavar="DATASET_ID", help="a local Minari dataset id")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="the run folder")
    p.add_argument("--iterations", type=int, default=20_000, metavar="N", help="gradient steps")
    p.add_argument("--batch-size", type=int, default=64, metavar="B", help="windows per step")
    p.add_argument("--lr", type=float, default=1e-3, metavar="LR", help="AdamW peak rate")
    p.add_argument("--seed", type=int, default=0, metavar="N", help="training seed")
    p.add_argument(
        "--channels",
        type=int,
        nargs="+",
        default=[32, 64, 128],
        metavar="C",
        help="U-Net widths, top to bottom",
    )
    p.add_argument("--inference-steps", type=int, default=10, metavar="K", help="DDIM steps")
    p.add_argument(
        "--no-features",
        action="store_true",
        help="leave out the task features (plate in the fingertip frame, edge, overhang)",
    )
    p.add_argument(
        "--tip-axes",
        action="store_true",
        help="add the fingertip's x and z axes to the inputs (smooth where its quaternion "
        "flips sign; for skills that turn the hand)",
    )
    p.add_argument(
        "--actions",
        default="deltas",
        choices=("offsets", "deltas", "targets"),
        help="chunk arm motion as offsets from the current target, per-step increments, or "
        "fingertip poses in the plate's edge frame (ee_delta demonstrations only)",
    )
    p.add_argument(
        "--scaling",
        default="standard",
        choices=("standard", "minmax"),
        help="chunk entries standardised, or scaled to [-1, 1] by their range",
    )
    p.add_argument(
        "--obs-embed",
        type=int,
        default=0,
        metavar="N",
        help="condition on an MLP embedding of this size (0: the observations themselves)",
    )
    p.add_argument("--log-every", type=int, default=500, metavar="N", help="rows, checkpoints")
    p.add_argument("--val-every", type=int, default=5_000, metavar="N", help="0: at the end only")
    p.add_argument("--val-episodes", type=int, default=20, metavar="N", help="0: never validate")
    p.add_argument("--resume", action="store_true", help="continue the run in DIR")
    p.add_argument(
        "--device",
        default="cpu",
        choices=("cpu", "cuda"),
        help="where to train (the saved policy acts on the CPU either way)",
    )
    p.add_argument(
        "--snapshot-every",
        type=int,
        default=0,
        metavar="N",
        help="also keep the EMA weights every N iterations in DIR/snapshots/ (for "
        "`slide-gym choose-checkpoint DIR` after training without the simulator); 0: never",
    )
    p.add_argument(
        "--init",
        metavar="POLICY_DIR",
        help="start from this trained policy's weights and network (fine-tuning; the "
        "learning rate schedule starts again)",
    )
    p.add_argument(
        "--after",
        metavar="POLICY_DIR",
        help="a sliding policy (trained on TopSlide-v0) that acts first: learn only what "
        "follows a finished slide in each episode (the plate overhanging u* and the pressing "
        "finger unbent); the saved policy runs POLICY_DIR's skill until then, this one after",
    )
    p.add_argument(
        "--episode-seeds",
        metavar="FILE",
        help="train only on the episodes reset with the seeds of this JSON list (e.g. those "
        "`python benchmarks/grasp_branches.py DATASET --near-posture RAD` writes)",
    )
    add_only_success(p, "; DAgger rollouts are kept either way (their labels are the expert's)")
    p.set_defaults(func=_cmd_train_dp)

    p = add_command(
        sub,
        "choose-checkpoint",
        "validate a train-dp run's snapshots and make the best one its policy",
        "For a run trained with --snapshot-every (e.g. on a GPU machine without the "
        f"simulator, with --val-episodes 0): run each snapshot on validation seeds from "
        f"{VALIDATION_SEED} (never the test seeds), record the rates in DIR/progress.csv and "
        "the learning curve, and copy the best snapshot (the later one on a tie) to "
        "DIR/policy.pt with its card. Snapshots already validated are not run again.",
        ["slide-gym choose-checkpoint models/dp-square --episodes 20"],
    )
    p.add_argument("run", type=Path, metavar="DIR", help="a train-dp run folder")
    p.add_argument("--episodes", type=int, default=20, metavar="N", help="per snapshot")
    p.set_defaults(func=_cmd_choose_checkpoint)

    p = add_command(
        sub,
        "dagger",
        "DAgger: the learner acts, the replanning expert labels its states, retrain",
        "Run R rounds of DAgger from a train-dp policy. Each round runs E learner episodes "
        f"(reset seeds from {DAGGER_SEED}); at every chunk boundary a fresh expert plans from the "
        "state the learner reached and labels the chunk (a failed query is dropped and "
        "counted), and it executes a decaying share of the chunks (--beta, --decay). The "
        "episodes, with the labels in infos['expert_action'] and the round in their "
        "metadata, join the policy's dataset in the Minari dataset --dataset-id, and the "
        "policy is trained again from its last weights. OUT/round-R/policy is each round's "
        "policy; OUT/dagger.json the figures. The same command again resumes.",
        [
            "slide-gym dagger --env SlideGym/TopSlide-v0 --policy models/dp-square --rounds 2 "
            "--episodes 20 --out models/dagger --dataset-id slide-gym/square-slide-dagger-v0",
        ],
    )
    p.add_argument("--policy", type=Path, required=True, metavar="DIR", help="a train-dp folder")
    p.add_argument("--env", metavar="ENV_ID", help="must be the policy's env (a check)")
    p.add_argument("--rounds", type=int, default=2, metavar="R", help="DAgger rounds")
    p.add_argument("--episodes", type=int, default=20, metavar="E", help="learner episodes/round")
    p.add_argument("--out", type=Path, required=True, metavar="OUT", help="the run folder")
    p.add_argument(
        "--dataset-id", required=True, metavar="NAMESPACE/NAME-vK", help="the aggregated dataset"
    )
    p.add_argument("--beta", type=float, default=0.5, help="expert share of chunks in round 1")
    p.add_argument("--decay", type=float, default=0.5, help="its factor per later round")
    p.add_argument(
        "--label-budget", type=float, default=10.0, metavar="S", help="planning s per label query"
    )
    p.add_argument(
        "--iterations", type=int, default=5_000, metavar="N", help="training iterations per round"
    )
    p.add_argument("--seed", type=int, default=0, metavar="N", help="learner noise, expert draws")
    p.add_argument("--max-steps", type=int, metavar="N", help="cut learner episodes at N steps")
    p.add_argument(
        "--skip-phases",
        nargs="+",
        default=[],
        metavar="PHASE",
        help="withhold the labels the expert gives in these phases (e.g. release)",
    )
    p.add_argument(
        "--chunk-labels",
        type=int,
        default=0,
        metavar="K",
        help="every K steps, label the expert's own next chunk from the learner's state (run "
        "in a second env); training then uses those windows of the rollouts only (0: per-step "
        "labels)",
    )
    p.add_argument(
        "--label-from-overhang",
        type=float,
        metavar="M",
        help="label each rollout only from the first step where the plate overhangs the "
        "table by M metres (e.g. 0.035, the demonstrations' stop): the expert is asked only "
        "past where every demonstration stopped (default: label every step)",
    )
    p.add_argument(
        "--label-from-miss",
        type=float,
        metavar="H",
        help="label each rollout only from the first step where the fingertip is within H "
        "metres of the table top and more than 1 cm off the plate (it came down beside the "
        "plate), e.g. 0.015; with --label-from-overhang, from whichever comes first",
    )
    p.add_argument(
        "--expert-param",
        action="append",
        metavar="NAME=VALUE",
        help="override one of the labelling expert's execution settings "
        "(agents.params.ExpertParams) on top of the dataset's, e.g. straight_slide_on=1; "
        "repeatable",
    )
    p.add_argument("--workers", type=int, metavar="W", help="parallel episodes (default: cores)")
    add_backend(p)
    p.set_defaults(func=_cmd_dagger)
