"""``slide-gym train-dp``: a diffusion policy learned from a demonstration dataset."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from slide_gym.cli.args import add_command


def _cmd_train_dp(args: argparse.Namespace) -> int:
    from agents.learned.diffusion import DiffusionConfig
    from agents.learned.train import TrainConfig, train_diffusion
    from slide_gym.datasets.store import dataset_metadata, load

    config = DiffusionConfig(
        channels=tuple(args.channels),
        inference_steps=args.inference_steps,
        with_features=not args.no_features,
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
    dataset = load(args.dataset_id)
    meta = dataset_metadata(dataset)
    summary = train_diffusion(
        dataset,
        args.out,
        config=config,
        train=train,
        env_id=dataset.spec.env_spec.id,
        env_kwargs=dict(meta.get("env_kwargs") or {}),
        card={"dataset_id": args.dataset_id},
        resume=args.resume,
    )
    print(json.dumps({"out": str(args.out), **summary}, indent=2))
    return 0


def add_parsers(sub: Any) -> None:
    """Register the learning commands."""
    p = add_command(
        sub,
        "train-dp",
        "train a diffusion policy (action chunks, DDIM) on a demonstration dataset",
        "Train a 1-D U-Net diffusion policy (observation horizon 2, chunks of 16 actions, 8 "
        "executed) on the dataset's successful episodes, in the dataset's env. DIR gets "
        "checkpoint.pt (every --log-every iterations, and on Ctrl-C), progress.csv (loss; "
        "success on validation seeds from 20000 every --val-every iterations), "
        "learning_curve.png, and policy.pt/policy.json: the EMA weights of the checkpoint "
        "with the best validation success. `slide-gym evaluate DIR` tests it (seeds from "
        "10000); --resume continues a run.",
        [
            "slide-gym train-dp slide-gym/square-slide-v1 --out models/dp-square",
            "slide-gym train-dp slide-gym/square-slide-v1 --out models/dp-square --resume",
            "slide-gym evaluate models/dp-square --env SlideGym/TopSlide-v0 --episodes 100",
        ],
    )
    p.add_argument("dataset_id", metavar="DATASET_ID", help="a local Minari dataset id")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="the run folder")
    p.add_argument("--iterations", type=int, default=30_000, metavar="N", help="gradient steps")
    p.add_argument("--batch-size", type=int, default=64, metavar="B", help="windows per step")
    p.add_argument("--lr", type=float, default=3e-4, metavar="LR", help="AdamW peak rate")
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
    p.add_argument("--log-every", type=int, default=500, metavar="N", help="rows, checkpoints")
    p.add_argument("--val-every", type=int, default=5_000, metavar="N", help="0: at the end only")
    p.add_argument("--val-episodes", type=int, default=20, metavar="N", help="0: never validate")
    p.add_argument("--resume", action="store_true", help="continue the run in DIR")
    p.set_defaults(func=_cmd_train_dp)
