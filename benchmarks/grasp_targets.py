"""Where grasp demonstrations close the hand, as ``train-dp --actions targets`` sees them.

For each successful episode of a fingertip-step grasp dataset, the target (the arm's
fingertip pose after the step, :mod:`agents.learned.frames`) of the first step that closes the
hand, in the task frame of the hand-off (the first step where ``slide_done`` holds), and the
table edge that frame faces:

    python benchmarks/grasp_targets.py slide-gym/square-grasp-ee-v4

Prints the number of episodes, how many close the hand in front of the frame's edge (x > 0),
the percentiles of those targets' x (out along the edge's normal) and y (along the edge), the
count at each height (cm, rounded) and the count of each edge normal (world x, y, rounded).
"""

from __future__ import annotations

import argparse
import os
from collections import Counter

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402 - after the thread setting


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset", help="a Minari dataset id of ee_delta grasp demonstrations")
    args = parser.parse_args()

    from agents.learned.data import load_demonstrations
    from agents.learned.features import slide_done
    from agents.learned.frames import task_frames
    from slide_gym.datasets.store import load

    dataset = load(args.dataset)
    demos = load_demonstrations(dataset, targets=True, after_slide=True)
    closes = []
    for start, n in zip(demos.starts, demos.lengths, strict=True):
        labels = demos.labels[start : start + n]
        closed = np.flatnonzero(labels[:, -1] > 0)
        if len(closed):
            closes.append(labels[closed[0], :3])
    c = np.array(closes)
    front = c[:, 0] > 0
    edges: Counter[tuple[int, int]] = Counter()
    for episode in dataset.iterate_episodes():
        if len(episode.actions) == 0:
            continue
        obs = {k: np.asarray(v)[: len(episode.actions)] for k, v in episode.observations.items()}
        done = np.flatnonzero(slide_done(obs))
        if len(done):
            frame = task_frames({k: v[done[0] : done[0] + 1] for k, v in obs.items()})[0]
            edges[tuple(int(v) for v in np.round(frame[:2, 0]))] += 1
    pct = [0, 5, 50, 95, 100]
    print(f"episodes closing the hand: {len(c)} of {demos.episodes}; in front: {front.sum()}")
    for axis, name in ((0, "x"), (1, "y")):
        values = np.percentile(c[front, axis], pct).round(3).tolist()
        print(f"{name} (m) percentiles", dict(zip(pct, values, strict=True)))
    print("height (cm)", dict(Counter(np.round(100 * c[front, 2]).astype(int).tolist())))
    print("edge normals at the hand-off", dict(edges))


if __name__ == "__main__":
    main()
