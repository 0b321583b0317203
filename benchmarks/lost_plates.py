"""Episodes where a slide lost the plate under the fingertip, run again with other settings.

Reads rows written by ``slide-gym bench execute --out ROWS.jsonl`` and picks the failed
episodes with a slide that left the plate without overhang (``slid: overhang 0.000`` among
the expert's events, the plate far from the prediction). Runs the first ``--episodes`` of
them again with the expert's slide speed or the planner's contact depth changed, and prints
how many were lifted and how many slides lost the plate again:

    slide-gym bench execute --trials 10 --scale 0.5 --workers 1 --out half.jsonl
    python benchmarks/lost_plates.py half.jsonl --scale 0.5 --slide-speed 0.03
    python benchmarks/lost_plates.py half.jsonl --scale 0.5 --dz 0.016 0.024

``--trace OBJECT TABLE SEED`` prints one such episode instead, every 10 steps of the press,
slide, pull-back and lift-off: the plate's and the fingertip's positions and the pressing
finger's bend (``--trace L round 1 --scale 0.5``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

LOST = "slid: overhang 0.000"
TRACED = ("press", "slide", "pull_back", "lift_off")


def trace(obj: str, table: str, seed: int, scale: float) -> None:
    """Print the plate, the fingertip and the finger's bend every 10 steps of the slide."""
    import gymnasium as gym
    import numpy as np

    import slide_gym  # noqa: F401 - registers the environments
    from agents.evaluate import _planner_agent

    env = gym.make("SlideGym/TopSlideGrasp-v0", object=obj, table=table, scale=scale)
    obs, _ = env.reset(seed=seed)
    agent = _planner_agent("regions", env, seed, 10.0)
    for t in range(env.spec.max_episode_steps or 1200):
        action, _ = agent.predict(obs, deterministic=True)
        expert = agent.expert(0)
        if t % 10 == 0 and expert is not None and expert.phase in TRACED:
            plate, tip = np.round(obs["object_pose"][:3], 3), np.round(obs["fingertip_pose"][:3], 3)
            print(t, expert.phase, "plate", plate, "tip", tip, f"bend {obs['finger_qpos'][0]:.2f}")
        obs, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated or (expert is not None and expert.phase == "transfer"):
            break
    env.close()


def main(argv: list[str] | None = None) -> int:
    from agents.episode import run_episode
    from agents.params import EXPERT_SLIDE_PARAMS, ExpertParams

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("rows", type=Path, nargs="?", help="a bench execute JSONL")
    parser.add_argument("--scale", type=float, default=1.0, help="the rows' --scale")
    parser.add_argument("--episodes", type=int, default=14)
    parser.add_argument("--slide-speed", type=float, default=ExpertParams().slide_speed)
    parser.add_argument("--dz", type=float, nargs=2, default=EXPERT_SLIDE_PARAMS.dz)
    parser.add_argument("--trace", nargs=3, metavar=("OBJECT", "TABLE", "SEED"))
    args = parser.parse_args(argv)
    if args.trace:
        trace(args.trace[0], args.trace[1], int(args.trace[2]), args.scale)
        return 0
    if args.rows is None:
        parser.error("give the ROWS of a bench execute run, or --trace")
    rows = [json.loads(line) for line in args.rows.read_text().splitlines() if line.strip()]
    lost = [r for r in rows if not r["success"] and any(e.startswith(LOST) for e in r["events"])]
    params = dataclasses.replace(ExpertParams(), slide_speed=args.slide_speed)
    lifted = lost_again = 0
    for r in lost[: args.episodes]:
        record = run_episode(
            r["object"],
            r["table"],
            scale=args.scale,
            seed=r["seed"],
            params=params,
            dz=tuple(args.dz),
        )
        lifted += record.success
        lost_again += sum(e.startswith(LOST) for e in record.expert.events)
        print(r["object"], r["table"], r["seed"], record.success, record.failure, flush=True)
    print(
        json.dumps(
            {
                "episodes": min(len(lost), args.episodes),
                "of_lost": len(lost),
                "slide_speed": args.slide_speed,
                "dz": list(args.dz),
                "lifted": lifted,
                "slides_that_lost_the_plate": lost_again,
            }
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
