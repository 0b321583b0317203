"""How a learned slide fails: each failed episode of a sliding policy, sorted by what the
plate and the robot did.

    OMP_NUM_THREADS=1 python benchmarks/slide_failures.py models/dp-ee-square-slide-stop-b256 \
        --seeds 20000-20099 --out docs/results/learning/slide_failures.jsonl

Runs the policy (a ``slide-gym train-dp`` folder) in its own env on the reset seeds given
(validation seeds by default, never the test seeds) and names each failure:

- ``pushed off``: the plate fell off the table (the episode ends there);
- ``never moved``: the time ran out with the plate within 5 mm of where it started;
- ``graspable, still touched``: the time ran out with the plate graspable (overhang >= u*,
  centroid on the table) but the robot still touching it, so the slide never ended;
- ``short of u*``: the time ran out with the plate moved but not graspable.

Prints the counts (also successes per object and table) and appends one JSON line (the
policy, the seeds, the counts and every episode) to ``--out`` if given.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections import Counter
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from slide_gym.splits import VALIDATION_SEED  # noqa: E402

MOVED_M = 0.005
"""A plate displaced less than this never moved."""


def failure_kind(fell_off: bool, moved_m: float, graspable: bool, touching: bool) -> str:
    """The name of a failed slide episode's ending (see the module docstring)."""
    if fell_off:
        return "pushed off"
    if moved_m < MOVED_M:
        return "never moved"
    if graspable:
        return "graspable, still touched" if touching else "graspable, not at rest"
    return "short of u*"


def run_episode(env: Any, policy: Any, seed: int) -> dict[str, Any]:
    """One episode of ``policy`` from reset seed ``seed``, with what its ending was."""
    obs, info = env.reset(seed=seed)
    start = np.asarray(obs["object_pose"][:2], float).copy()
    steps, done, max_overhang, touched = 0, False, 0.0, 0
    while not done:
        action, _ = policy.predict(obs, episode_start=np.array([steps == 0]))
        obs, _, terminated, truncated, info = env.step(action)
        steps += 1
        done = terminated or truncated
        max_overhang = max(max_overhang, float(info["overhang_m"]))
        touched += bool(info["touching_robot"])
    moved = float(np.linalg.norm(np.asarray(obs["object_pose"][:2], float) - start))
    success = bool(info["is_success"])
    record = {
        "seed": seed,
        "object": info["object"],
        "table": info["table"],
        "success": success,
        "length": steps,
        "moved_m": round(moved, 4),
        "max_overhang_m": round(max_overhang, 4),
        "final_overhang_m": round(float(info["overhang_m"]), 4),
        "steps_touching": touched,
    }
    if not success:
        record["kind"] = failure_kind(
            bool(info["fell_off"]), moved, bool(info["graspable"]), bool(info["touching_robot"])
        )
    return record


def by_scene(episodes: list[dict[str, Any]]) -> dict[str, list[int]]:
    """Successes and episodes for each ``object/table`` pair, most episodes first."""
    tally: dict[str, list[int]] = {}
    for e in episodes:
        t = tally.setdefault(f"{e['object']}/{e['table']}", [0, 0])
        t[0] += e["success"]
        t[1] += 1
    return dict(sorted(tally.items(), key=lambda kv: (-kv[1][1], kv[0])))


def main(argv: list[str] | None = None) -> int:
    import gymnasium as gym

    import slide_gym  # noqa: F401 - registers the envs
    from agents.learned import DiffusionPolicy

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("policy", type=Path, help="a train-dp folder")
    parser.add_argument(
        "--seeds",
        default=f"{VALIDATION_SEED}-{VALIDATION_SEED + 99}",
        help="first-last reset seeds (default: 100 validation seeds)",
    )
    parser.add_argument("--out", type=Path, help="append the figures to this JSONL file")
    args = parser.parse_args(argv)
    try:
        first, last = (int(x) for x in args.seeds.split("-"))
        policy = DiffusionPolicy.load(args.policy)
    except ValueError as e:
        print(f"slide_failures: {e} (--seeds FIRST-LAST)", file=sys.stderr)
        return 2
    if policy.card.get("env_id") != "SlideGym/TopSlide-v0":
        print("slide_failures: the policy must be a sliding one (TopSlide-v0)", file=sys.stderr)
        return 2
    env = gym.make(policy.card["env_id"], **policy.card.get("env_kwargs", {}))
    episodes = []
    for seed in range(first, last + 1):
        episodes.append(run_episode(env, policy, seed))
        e = episodes[-1]
        print(
            f"seed {seed}: {'success' if e['success'] else e['kind']} after {e['length']} steps "
            f"(moved {e['moved_m']:.3f} m, most overhang {e['max_overhang_m']:.3f} m)",
            file=sys.stderr,
            flush=True,
        )
    env.close()
    kinds = Counter(e["kind"] for e in episodes if not e["success"])
    summary = {
        "policy": args.policy.name,
        "seeds": [first, last],
        "episodes": len(episodes),
        "successes": sum(e["success"] for e in episodes),
        "failures": dict(kinds.most_common()),
        "by_scene": by_scene(episodes),
        "results": episodes,
    }
    print(json.dumps({k: v for k, v in summary.items() if k != "results"}, indent=2))
    if args.out is not None:
        with args.out.open("a") as f:
            f.write(json.dumps(summary) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
