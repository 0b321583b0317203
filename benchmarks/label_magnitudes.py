"""How large are DAgger's labels next to the demonstrations' actions?

Prints, for a demonstration dataset and a DAgger round's staged rollouts, the share of arm
actions at the step limit (some entry's magnitude >= 0.99), the share with no arm motion
(every entry below 1e-6) and the mean and median of the largest arm entry; for rollouts with
chunk labels (``dagger --chunk-labels``) the same over every chunk entry. Labels that catch a
lagging learner up to its expert's plan saturate far more often than the expert's own
actions do.

    OMP_NUM_THREADS=1 python benchmarks/label_magnitudes.py slide-gym/square-slide-ee-v1 \
        models/dp-dagger4-ee-square-slide/round-1/episodes
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np

os.environ.setdefault("OMP_NUM_THREADS", "1")


def summary(name: str, actions: np.ndarray) -> str:
    arm = np.abs(actions[:, :-1]).max(axis=1)
    return (
        f"{name}: {len(arm)} steps, {100 * (arm >= 0.99).mean():.1f} % at the step limit, "
        f"{100 * (arm < 1e-6).mean():.1f} % without arm motion, "
        f"largest arm entry mean {arm.mean():.3f}, median {np.median(arm):.3f}"
    )


def main() -> None:
    from slide_gym.datasets.recording import CHUNK_KEY, LABEL_KEY, RecordedEpisode
    from slide_gym.datasets.store import load

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset", help="the demonstrations' Minari id")
    parser.add_argument("rollouts", type=Path, help="a DAgger round's episodes folder")
    args = parser.parse_args()
    demos = np.concatenate([ep.actions for ep in load(args.dataset).iterate_episodes()])
    labels, chunks = [], []
    for path in sorted(args.rollouts.glob("seed-*.npz")):
        episode = RecordedEpisode.from_bytes(path.read_bytes())
        label = np.asarray(episode.infos[LABEL_KEY][1:])
        labels.append(label[np.isfinite(label).all(axis=1)])
        if CHUNK_KEY in episode.infos:
            chunk = np.asarray(episode.infos[CHUNK_KEY][1:])
            asked = chunk[np.isfinite(chunk).all(axis=(1, 2))]
            chunks.append(asked.reshape(-1, chunk.shape[-1]))
    if not labels:
        raise SystemExit(f"{args.rollouts} holds no seed-*.npz rollouts")
    print(summary("demonstrations", demos))
    print(summary("DAgger labels", np.concatenate(labels)))
    if chunks:
        print(summary("DAgger chunk label entries", np.concatenate(chunks)))


if __name__ == "__main__":
    main()
