"""Train a diffusion policy on a machine that has a GPU but not the simulator or the dataset.

A Minari dataset of fingertip-step slides is about 120 MB; the policy inputs and labels that
training reads from it are a tenth of that compressed. ``export`` writes them (with the
dataset's env and id) to one ``.npz``; ``train`` runs ``slide-gym train-dp``'s own code on
that file, with ``--device cuda --val-episodes 0 --snapshot-every N`` (nothing there can
validate without the simulator), and ``slide-gym choose-checkpoint DIR`` back here picks the
checkpoint on validation seeds::

    python benchmarks/remote_train.py export slide-gym/square-slide-ee-stop-v1 stop.npz
    # on the GPU machine (no pybullet needed: --stub-pybullet)
    python benchmarks/remote_train.py train stop.npz --stub-pybullet -- --out runs/a \\
        --device cuda --batch-size 256 --iterations 50000 --snapshot-every 25000 \\
        --val-episodes 0
    # back here
    slide-gym choose-checkpoint runs/a --episodes 20

The arrays are what :func:`agents.learned.data.load_demonstrations` returns for the default
inputs (task features, no fingertip axes, successful episodes), so ``train`` refuses
options that would need others.
"""

from __future__ import annotations

import argparse
import json
import sys
import types
from pathlib import Path
from typing import Any

import numpy as np


def export(dataset_id: str, out: Path) -> dict[str, Any]:
    """Write the training arrays of ``dataset_id`` to ``out`` and return its header."""
    from agents.learned.data import load_demonstrations
    from slide_gym.datasets.store import dataset_metadata, load

    dataset = load(dataset_id)
    demos = load_demonstrations(dataset)
    header = {
        "dataset_id": dataset_id,
        "env_id": dataset.spec.env_spec.id,
        "metadata": dataset_metadata(dataset),
        "seeds": demos.seeds,
        "skipped": demos.skipped,
    }
    np.savez_compressed(
        out,
        inputs=demos.inputs,
        labels=demos.labels,
        lengths=demos.lengths,
        header=np.array(json.dumps(header)),
    )
    return header


def _stub_pybullet() -> None:
    """Let the package import where pybullet is not installed (training never calls it)."""

    def placeholder(name: str) -> int:
        if name.startswith("__"):
            raise AttributeError(name)
        return 0

    for name in ("pybullet", "pybullet_data", "pybullet_utils", "pybullet_utils.bullet_client"):
        stub = types.ModuleType(name)
        stub.__getattr__ = placeholder  # type: ignore[attr-defined]
        sys.modules.setdefault(name, stub)


def train(arrays: Path, train_dp_args: list[str], stub_pybullet: bool = False) -> int:
    """``slide-gym train-dp`` on the exported ``arrays`` with ``train_dp_args``."""
    if stub_pybullet:
        _stub_pybullet()
    from agents.learned import train as train_module
    from agents.learned.data import Demonstrations
    from slide_gym.cli import main
    from slide_gym.datasets import store

    with np.load(arrays) as blob:
        header = json.loads(str(blob["header"]))
        lengths = blob["lengths"]
        demos = Demonstrations(
            inputs=blob["inputs"],
            labels=blob["labels"],
            starts=np.concatenate([[0], np.cumsum(lengths)[:-1]]),
            lengths=lengths,
            seeds=list(header["seeds"]),
            skipped=int(header["skipped"]),
        )
    for flag in ("--no-features", "--tip-axes", "--after", "--no-only-success"):
        if flag in train_dp_args:
            raise ValueError(f"{flag} needs other arrays than `export` writes; train here")
    dataset = types.SimpleNamespace(
        spec=types.SimpleNamespace(env_spec=types.SimpleNamespace(id=header["env_id"])),
        storage=types.SimpleNamespace(metadata={store.METADATA_KEY: header["metadata"]}),
    )
    store.load = lambda dataset_id: dataset  # type: ignore[assignment]
    train_module.load_demonstrations = lambda *a, **k: demos  # type: ignore[assignment]
    return main(["train-dp", header["dataset_id"], *train_dp_args])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("export", help="a dataset's training arrays to one .npz")
    p.add_argument("dataset_id")
    p.add_argument("out", type=Path)
    p = sub.add_parser("train", help="slide-gym train-dp on exported arrays (its options after --)")
    p.add_argument("arrays", type=Path)
    p.add_argument("--stub-pybullet", action="store_true", help="where pybullet is missing")
    argv = sys.argv[1:] if argv is None else argv
    rest = argv[argv.index("--") + 1 :] if "--" in argv else []
    args = parser.parse_args(argv[: len(argv) - len(rest) - (1 if "--" in argv else 0)])
    if args.command == "export":
        header = export(args.dataset_id, args.out)
        size = args.out.stat().st_size / 1e6
        print(f"{args.out}: {header['dataset_id']}, {len(header['seeds'])} episodes, {size:.1f} MB")
        return 0
    return train(args.arrays, rest, args.stub_pybullet)


if __name__ == "__main__":
    sys.exit(main())
