"""A grasping skill on its own: the expert slides the plate, the skill takes over.

A policy trained with ``slide-gym train-dp ... --after SLIDE_POLICY`` runs its sliding skill
until :func:`agents.learned.features.slide_done` holds, then its grasping skill. Its success
is the product of both, so a failing row does not say which skill fails. Here the planner
expert acts until ``slide_done`` holds and the grasping skill (the folder's ``policy.pt``)
acts from there, with a fresh history, on validation seeds (never the test seeds):

    python benchmarks/grasp_skill.py MODEL_DIR --episodes 20

Appends one line to ``docs/results/learning/grasp_skill.jsonl`` (``--out``) with the counts
and each episode's hand-off step, length and outcome. With ``--trace`` each seed is first
run by the expert alone (the same slide, then its own grasp), and each episode also records
how near the skill came to the expert's grasp: the least largest-joint gap and grasp-frame
distance over its steps, the step it first closed the hand and its gaps there, and how far
the plate moved after the hand-off. ``--report`` prints, for every run in ``--out``, how its
episodes ended (:func:`outcomes`).
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


def _name(folder: Path) -> str:
    """A policy folder's name; a DAgger round's (``RUN/round-R/policy``) with its run's."""
    parts = folder.resolve().parts
    return "/".join(parts[-3:]) if folder.name == "policy" and len(parts) >= 3 else folder.name


def _expert_grasp(env: Any, seed: int) -> Any:
    """The arm's joints where the expert alone first closes the hand on ``seed``, or None."""
    from agents.evaluate import _planner_agent

    obs, _ = env.reset(seed=seed)
    expert = _planner_agent("regions", env, seed, 10.0)
    for _ in range(env.spec.max_episode_steps or 1200):
        action, _ = expert.predict(obs, deterministic=True)
        if action[-1] > 0:
            return obs["arm_qpos"].copy()
        obs, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            break
    return None


def run(folder: Path, episodes: int, seed: int, trace: bool = False) -> dict[str, Any]:
    """Expert slide, then the folder's grasping skill, for ``episodes`` seeded episodes
    (``trace``: also how near the skill came to the expert's own grasp)."""
    import gymnasium as gym
    import numpy as np

    import slide_gym  # noqa: F401 - registers the environments
    from agents.evaluate import _planner_agent
    from agents.learned.features import slide_done
    from agents.learned.policy import WEIGHTS_FILE, DiffusionPolicy, load_model
    from slide_gym.robot.kinematics import grasp_chain
    from slide_gym.version import code_version

    hand = grasp_chain()
    card = DiffusionPolicy.load(folder).card
    if "after" not in card:
        raise ValueError(f"{str(folder)!r} is not a skill trained with --after SLIDE_POLICY")
    skill = DiffusionPolicy(load_model(folder / WEIGHTS_FILE), card=card)
    env = gym.make(card["env_id"], **card.get("env_kwargs", {}))
    results = []
    for s in range(seed, seed + episodes):
        goal = _expert_grasp(env, s) if trace else None
        goal_xyz = None if goal is None else hand.forward(goal[None])[0, :3, 3]
        obs, _ = env.reset(seed=s)
        expert = _planner_agent("regions", env, s, 10.0)
        handed, success, t = None, False, 0
        gaps: list[tuple[float, float]] = []  # (largest joint gap, grasp-frame distance)
        closed, plate_at_handoff, plate = None, None, obs["object_pose"][:2]
        for t in range(env.spec.max_episode_steps or 1200):
            if handed is None and slide_done({k: v[None] for k, v in obs.items()})[0]:
                handed, plate_at_handoff = t, obs["object_pose"][:2].copy()
                skill.reset(s)
            if handed is None:
                action, _ = expert.predict(obs, deterministic=True)
            else:
                action, _ = skill.predict(obs, episode_start=np.array([t == handed]))
                if goal is not None:
                    q = obs["arm_qpos"]
                    xyz = hand.forward(np.asarray(q, dtype=float)[None])[0, :3, 3]
                    gaps.append(
                        (float(np.abs(q - goal).max()), float(np.linalg.norm(xyz - goal_xyz)))
                    )
                    if closed is None and action[-1] > 0:
                        closed = len(gaps) - 1
            obs, _, terminated, truncated, info = env.step(action)
            plate = obs["object_pose"][:2]
            if terminated or truncated:
                success = bool(info["is_success"])
                break
        row: dict[str, Any] = {
            "seed": s,
            "handed_over": handed,
            "length": t + 1,
            "success": success,
        }
        if trace and gaps:
            g = np.array(gaps)
            row["least_joint_gap_rad"] = round(float(g[:, 0].min()), 3)
            row["least_grasp_gap_m"] = round(float(g[:, 1].min()), 3)
            row["closed_after_steps"] = closed
            if closed is not None:
                row["gaps_at_close"] = [round(float(v), 3) for v in g[closed]]
            row["plate_moved_m"] = round(float(np.linalg.norm(plate - plate_at_handoff)), 3)
        elif trace:
            row["expert_grasp_found"] = goal is not None
        results.append(row)
        print(json.dumps(results[-1]), flush=True)
    env.close()
    handed_over = [r for r in results if r["handed_over"] is not None]
    wins = sum(r["success"] for r in results)
    return {
        "policy": _name(folder),
        "episodes": episodes,
        "handed_over": len(handed_over),
        "successes": wins,
        "ci95": list(wilson_interval(wins, episodes)),
        "seeds": [seed, seed + episodes - 1],
        "results": results,
        "max_steps": env.spec.max_episode_steps or 1200,
        "code_version": code_version(),
    }


def outcomes(record: dict[str, Any]) -> dict[str, Any]:
    """How a run's episodes ended: lifted, out of time (with the grasp-frame gap where the
    skill first closed the hand, if traced), or the plate lost (and how many of those within
    100 steps of the hand-off)."""
    limit = int(record.get("max_steps", 1200))
    rows = record["results"]
    late = [r for r in rows if not r["success"] and r["length"] >= limit]
    lost = [r for r in rows if not r["success"] and r["length"] < limit]
    early = [r for r in lost if r["handed_over"] is not None]
    early = [r for r in early if r["length"] - r["handed_over"] <= 100]
    return {
        "policy": record["policy"],
        "code_version": record["code_version"],
        "episodes": len(rows),
        "lifted": sum(r["success"] for r in rows),
        "out_of_time": len(late),
        "out_of_time_gap_at_close_m": sorted(
            r["gaps_at_close"][1] for r in late if "gaps_at_close" in r
        ),
        "lost": len(lost),
        "lost_within_100_steps": len(early),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("policy", type=Path, nargs="?", help="a folder written by train-dp --after")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=VALIDATION_SEED, help="first reset seed")
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument(
        "--trace", action="store_true", help="also how near the skill came to the expert's grasp"
    )
    parser.add_argument("--report", action="store_true", help="how the runs in --out ended")
    args = parser.parse_args(argv)
    if args.report:
        for line in args.out.read_text().splitlines():
            print(json.dumps(outcomes(json.loads(line))))
        return 0
    try:
        if args.policy is None:
            raise ValueError("give a policy folder (or --report)")
        if args.episodes < 1:
            raise ValueError(f"--episodes must be at least 1, got {args.episodes}")
        record = run(args.policy, args.episodes, args.seed, args.trace)
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
