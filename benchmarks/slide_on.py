"""How often a fresh expert slides on from a pressed fingertip mid-slide (DAgger's label query).

For each seed, the expert plays one episode of the slide env (square on the square table);
then, at every step ``t`` that is a multiple of ``--every`` with the slide phase on both
sides of it, the episode is replayed to ``t`` and a fresh expert (the same seed) finishes it.
Each takeover is counted by its first event (slid on, lifted off a graspable plate, raised
the fingertip as the fallback, other) and whether the episode then succeeded; each line also
prints how far the takeover's plan moves the plate (its predicted pose from where it lay).

    OMP_NUM_THREADS=1 python benchmarks/slide_on.py --seeds 3-7 --control-mode ee_delta
"""

from __future__ import annotations

import argparse
import os
from collections import Counter

import numpy as np

os.environ.setdefault("OMP_NUM_THREADS", "1")

ENV_ID = "SlideGym/TopSlide-v0"
BUDGET = 60.0


def _play(env, agent, obs: dict, actions: list | None = None) -> tuple[list, list, dict]:
    """Run ``agent`` from ``obs`` to the episode's end; its actions, phases and last info."""
    acts, phases, done, info = [], [], False, {}
    while not done:
        action, _ = agent.predict(obs, episode_start=np.array([not acts]))
        obs, _, term, trunc, info = env.step(action)
        acts.append(action)
        phases.append(agent.expert(0).phase)
        done = term or trunc
    return acts, phases, info


def _kind(events: list[str]) -> str:
    first = events[0] if events else ""
    for key, name in (("slid on", "slid_on"), ("lifted it off", "lifted_off")):
        if first.startswith("took over") and first.endswith(key):
            return name
    return "raised" if any(e.endswith("raised it") for e in events) else "other"


def measure(seeds: range, control_mode: str, every: int) -> Counter:
    import gymnasium as gym

    import slide_gym  # noqa: F401 - registers the environments
    from agents.planner_agent import PlannerAgent

    counts: Counter = Counter()
    for seed in seeds:
        env = gym.make(ENV_ID, control_mode=control_mode)
        obs, _ = env.reset(seed=seed)
        agent = PlannerAgent("regions", BUDGET, seed=seed, control_mode=control_mode)
        actions, phases, info = _play(env, agent, obs)
        agent.close()
        ks = [k for k in range(every, len(phases), every) if phases[k - 1] == phases[k] == "slide"]
        print(f"seed {seed}: expert {'ok' if info['is_success'] else 'failed'}, takeovers {ks}")
        for k in ks:
            obs, _ = env.reset(seed=seed)
            for action in actions[:k]:
                obs, *_ = env.step(action)
            fresh = PlannerAgent("regions", BUDGET, seed=seed, control_mode=control_mode)
            at = np.asarray(obs["object_pose"][:2], dtype=float)
            _, _, last = _play(env, fresh, obs)
            report = fresh.expert(0).report
            goal = report.object_predicted_pose
            slid = float(np.linalg.norm(np.asarray(goal[:2]) - at)) if goal else float("nan")
            fresh.close()
            kind, ok = _kind(report.events), bool(last["is_success"])
            counts[(kind, ok)] += 1
            why = next((e for e in report.events if e.startswith("no ")), "")
            print(f"  step {k}: {kind}, {'success' if ok else 'failed'}, slide {slid:.3f} m {why}")
        env.close()
    return counts


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="3-7", help="first-last reset seeds (inclusive)")
    parser.add_argument(
        "--control-mode", default="joint_delta", choices=["joint_delta", "ee_delta"]
    )
    parser.add_argument("--every", type=int, default=8, help="steps between takeovers")
    args = parser.parse_args()
    first, _, last = args.seeds.partition("-")
    counts = measure(range(int(first), int(last or first) + 1), args.control_mode, args.every)
    print(
        f"{args.control_mode}: "
        + ", ".join(
            f"{kind} {'success' if ok else 'failed'}: {n}"
            for (kind, ok), n in sorted(counts.items())
        )
    )


if __name__ == "__main__":
    main()
