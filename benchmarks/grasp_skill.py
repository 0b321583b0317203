"""A grasping skill on its own: the expert slides the plate, the skill takes over.

A policy trained with ``slide-gym train-dp ... --after SLIDE_POLICY`` runs its sliding skill
until :func:`agents.learned.features.slide_done` holds, then its grasping skill. Its success
is the product of both, so a failing row does not say which skill fails. Here the planner
expert acts until ``slide_done`` holds and the grasping skill (the folder's ``policy.pt``)
acts from there, with a fresh history, on validation seeds (never the test seeds):

    python benchmarks/grasp_skill.py MODEL_DIR --episodes 20

Appends one line to ``docs/results/learning/grasp_skill.jsonl`` (``--out``) with the counts
and each episode's hand-off step, length and outcome.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

from slide_gym.splits import VALIDATION_SEED  # noqa: E402 - after the thread setting
from slide_gym.stats import wilson_interval  # noqa: E402

OUT = Path("docs/results/learning/grasp_skill.jsonl")


def run(folder: Path, episodes: int, seed: int) -> dict[str, Any]:
    """Expert slide, then the folder's grasping skill, for ``episodes`` seeded episodes."""
    import gymnasium as gym
    import numpy as np

    import slide_gym  # noqa: F401 - registers the environments
    from agents.evaluate import _planner_agent
    from agents.learned.features import slide_done
    from agents.learned.policy import WEIGHTS_FILE, DiffusionPolicy, load_model
    from slide_gym.version import code_version

    card = DiffusionPolicy.load(folder).card
    if "after" not in card:
        raise ValueError(f"{str(folder)!r} is not a skill trained with --after SLIDE_POLICY")
    skill = DiffusionPolicy(load_model(folder / WEIGHTS_FILE), card=card)
    env = gym.make(card["env_id"], **card.get("env_kwargs", {}))
    results = []
    for s in range(seed, seed + episodes):
        obs, _ = env.reset(seed=s)
        expert = _planner_agent("regions", env, s, 10.0)
        handed, success, t = None, False, 0
        for t in range(env.spec.max_episode_steps or 1200):
            if handed is None and slide_done({k: v[None] for k, v in obs.items()})[0]:
                handed = t
                skill.reset(s)
            if handed is None:
                action, _ = expert.predict(obs, deterministic=True)
            else:
                action, _ = skill.predict(obs, episode_start=np.array([t == handed]))
            obs, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                success = bool(info["is_success"])
                break
        results.append({"seed": s, "handed_over": handed, "length": t + 1, "success": success})
        print(json.dumps(results[-1]), flush=True)
    env.close()
    handed_over = [r for r in results if r["handed_over"] is not None]
    wins = sum(r["success"] for r in results)
    return {
        "policy": folder.name,
        "episodes": episodes,
        "handed_over": len(handed_over),
        "successes": wins,
        "ci95": list(wilson_interval(wins, episodes)),
        "seeds": [seed, seed + episodes - 1],
        "results": results,
        "code_version": code_version(),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("policy", type=Path, help="a folder written by train-dp --after")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=VALIDATION_SEED, help="first reset seed")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    try:
        if args.episodes < 1:
            raise ValueError(f"--episodes must be at least 1, got {args.episodes}")
        record = run(args.policy, args.episodes, args.seed)
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with args.out.open("a") as f:
        f.write(json.dumps(record) + "\n")
    print(json.dumps({k: v for k, v in record.items() if k != "results"}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
