"""How the expert moves from a finished slide to the grasp, in grasp demonstrations.

For each episode of each Minari dataset: the fingertip's highest point between the first step
where :func:`agents.learned.features.slide_done` holds and the first closing hand command,
the steps in between, and the sign flips of the fingertip's observed quaternion there:

    python benchmarks/transfer_height.py slide-gym/square-grasp-ee-v1 slide-gym/square-grasp-ee-v3
"""

from __future__ import annotations

import argparse
import json
import os
import sys

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402


def summary(dataset_id: str, high: float) -> dict[str, object]:
    import minari

    from agents.learned.features import slide_done

    heights, steps, flips = [], [], 0
    for episode in minari.load_dataset(dataset_id).iterate_episodes():
        obs = episode.observations
        start = int(np.argmax(slide_done(obs)))
        close = int(np.argmax(episode.actions[:, -1] > 0))
        tip = obs["fingertip_pose"][start : max(close, start + 1)]
        heights.append(float(tip[:, 2].max()))
        steps.append(close - start)
        flips += int((np.abs(np.diff(tip[:, 3:7], axis=0)).max(axis=1) > 0.5).sum())
    return {
        "dataset": dataset_id,
        "episodes": len(heights),
        f"above_{high}_m": int((np.array(heights) > high).sum()),
        "height_percentiles_10_50_90": np.percentile(heights, [10, 50, 90]).round(3).tolist(),
        "steps_median": float(np.median(steps)),
        "quaternion_flips": flips,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("datasets", nargs="+", help="Minari ids of grasp demonstrations")
    parser.add_argument("--high", type=float, default=0.5, help="m: a transfer above this")
    args = parser.parse_args(argv)
    for dataset_id in args.datasets:
        print(json.dumps(summary(dataset_id, args.high)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
