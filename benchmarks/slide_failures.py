"""How a learned slide or grasp fails: each failed episode of a policy, sorted by what the
plate and the robot did.

    OMP_NUM_THREADS=1 python benchmarks/slide_failures.py models/dp-ee-square-slide-stop-b256 \
        --seeds 20000-20099 --out docs/results/learning/slide_failures.jsonl

Runs the policy (a ``slide-gym train-dp`` folder) in its own env on the reset seeds given
(validation seeds by default, never the test seeds) and names each failure. A sliding
policy (``TopSlide``):

- ``pushed off``: the plate fell off the table (the episode ends there);
- ``never moved``: the time ran out with the plate within 5 mm of where it started;
- ``graspable, still touched``: the time ran out with the plate graspable (overhang >= u*,
  centroid on the table) but the robot still touching it, so the slide never ended;
- ``short of u*``: the time ran out with the plate moved but not graspable.

A grasping policy (``TopSlideGrasp``), in the order of the task's phases:

- ``pushed off``: the plate fell before it was ever lifted 1 cm; ``dropped``: after;
- ``never moved``, ``short of u*``: as for a slide (it was never graspable);
- ``graspable, never pinched``: the time ran out with the plate graspable and never
  touched by both fingers at once; ``pushed back``: the same, but the plate was pushed back
  on the table (no longer graspable at the end);
- ``pinched, not held``: both fingers touched it, and the time ran out without the lift held.

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

SLIDE_ENV_IDS = ("SlideGym/TopSlide-v0", "SlideGym/TopSlide-v1")
GRASP_ENV_IDS = ("SlideGym/TopSlideGrasp-v0", "SlideGym/TopSlideGrasp-v1")

LIFTED_M = 0.01
"""A plate that fell after being lifted this high was dropped, not pushed off."""


def failure_kind(fell_off: bool, moved_m: float, graspable: bool, touching: bool) -> str:
    """The name of a failed slide episode's ending (see the module docstring)."""
    if fell_off:
        return "pushed off"
    if moved_m < MOVED_M:
        return "never moved"
    if graspable:
        return "graspable, still touched" if touching else "graspable, not at rest"
    return "short of u*"


def grasp_failure_kind(
    fell_off: bool,
    moved_m: float,
    ever_graspable: bool,
    ever_pinched: bool,
    most_lift_m: float,
    graspable: bool,
) -> str:
    """The name of a failed grasp episode's ending (see the module docstring)."""
    if fell_off:
        return "dropped" if most_lift_m >= LIFTED_M else "pushed off"
    if moved_m < MOVED_M:
        return "never moved"
    if not ever_graspable:
        return "short of u*"
    if ever_pinched:
        return "pinched, not held"
    return "graspable, never pinched" if graspable else "pushed back"


def run_episode(env: Any, policy: Any, seed: int, grasp: bool = False) -> dict[str, Any]:
    """One episode of ``policy`` from reset seed ``seed``, with what its ending was (as a
    grasp's if ``grasp``)."""
    obs, info = env.reset(seed=seed)
    start = np.asarray(obs["object_pose"][:2], float).copy()
    steps, done, max_overhang, touched = 0, False, 0.0, 0
    first_graspable = first_pinched = None
    most_lift = 0.0
    while not done:
        action, _ = policy.predict(obs, episode_start=np.array([steps == 0]))
        obs, _, terminated, truncated, info = env.step(action)
        steps += 1
        done = terminated or truncated
        max_overhang = max(max_overhang, float(info["overhang_m"]))
        most_lift = max(most_lift, float(info["lift_m"]))
        touched += bool(info["touching_robot"])
        if first_graspable is None and info["graspable"]:
            first_graspable = steps
        if first_pinched is None and info["pinched"]:
            first_pinched = steps
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
    if not success and not grasp:
        record["kind"] = failure_kind(
            bool(info["fell_off"]), moved, bool(info["graspable"]), bool(info["touching_robot"])
        )
    if grasp:
        record.update(
            first_graspable_step=first_graspable,
            first_pinched_step=first_pinched,
            most_lift_m=round(most_lift, 4),
        )
        if not success:
            record["kind"] = grasp_failure_kind(
                bool(info["fell_off"]),
                moved,
                first_graspable is not None,
                first_pinched is not None,
                most_lift,
                bool(info["graspable"]),
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


def policy_name(path: Path) -> str:
    """The row a policy folder belongs to: its name, or ``ROW/round-R`` for a DAgger round's
    ``ROW/round-R/policy``."""
    path = path.resolve()
    if path.name == "policy" and path.parent.name.startswith("round-"):
        return f"{path.parent.parent.name}/{path.parent.name}"
    return path.name


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
    env_id = str(policy.card.get("env_id"))
    if env_id not in SLIDE_ENV_IDS + GRASP_ENV_IDS:
        print(
            f"slide_failures: the policy acts in {env_id}; this script names the failures of "
            f"{', '.join(SLIDE_ENV_IDS + GRASP_ENV_IDS)}",
            file=sys.stderr,
        )
        return 2
    env = gym.make(env_id, **policy.card.get("env_kwargs", {}))
    episodes = []
    for seed in range(first, last + 1):
        episodes.append(run_episode(env, policy, seed, grasp=env_id in GRASP_ENV_IDS))
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
        "policy": policy_name(args.policy),
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
