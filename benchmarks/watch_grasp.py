"""Watch a learned grasp after the hand-off: where the fingertip goes, what the hand does.

Runs one episode of a ``slide-gym train-dp`` policy in its own env from reset seed ``SEED``
and prints, every ``--every`` steps from the hand-off (the first step where the slide is done:
:func:`agents.learned.features.slide_done`), the fingertip's position, the plate's overhang,
the hand command (-1 open, +1 closed) and the plate's position. Used for the "watched"
figures of docs/learning.md:

    OMP_NUM_THREADS=1 python benchmarks/watch_grasp.py \
        models/dp-ee-square-grasp-stop-anchor-nearest-straight-b256-10k --seed 20000
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

os.environ.setdefault("OMP_NUM_THREADS", "1")


def main(argv: list[str] | None = None) -> int:
    import gymnasium as gym

    import slide_gym  # noqa: F401 - registers the envs
    from agents.learned import DiffusionPolicy
    from agents.learned.features import slide_done, task_features

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("policy", type=Path, help="a train-dp folder")
    parser.add_argument("--seed", type=int, default=20000, help="reset seed (default: 20000)")
    parser.add_argument("--every", type=int, default=15, help="print every N steps (default: 15)")
    args = parser.parse_args(argv)
    try:
        policy = DiffusionPolicy.load(args.policy)
    except ValueError as e:
        print(f"watch_grasp: {e}", file=sys.stderr)
        return 2
    env = gym.make(str(policy.card.get("env_id")), **policy.card.get("env_kwargs", {}))
    obs, info = env.reset(seed=args.seed)
    hand_off, step, done = None, 0, False
    while not done:
        action, _ = policy.predict(obs, episode_start=np.array([step == 0]))
        batch = {k: v[None] for k, v in obs.items()}
        if hand_off is None and slide_done(batch)[0]:
            hand_off = step
            print(f"hand-off at step {hand_off}")
        if hand_off is not None and (step - hand_off) % args.every == 0:
            tip = ", ".join(f"{x:.3f}" for x in obs["fingertip_pose"][:3])
            plate = ", ".join(f"{x:.3f}" for x in obs["object_pose"][:3])
            overhang = float(task_features(batch)[0, -1])
            hand = f"{action[-1]:+.0f}"
            print(
                f"  {step}: fingertip ({tip}), overhang {overhang:.3f} m, hand {hand}, "
                f"plate ({plate})"
            )
        obs, _, terminated, truncated, info = env.step(action)
        step += 1
        done = terminated or truncated
    env.close()
    print(f"{'success' if info['is_success'] else 'failure'} after {step} steps")
    return 0


if __name__ == "__main__":
    sys.exit(main())
