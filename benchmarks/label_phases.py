"""What DAgger's label expert is doing while a learner acts: its phase at every step.

Runs learner-only rollouts (no expert control) of a trained policy on the square slide in
fingertip steps, labelled by :class:`agents.learned.labeler.PlanLabeler`, and prints per
phase of the label expert how many steps it labelled, the share of labels at the step limit
and the median largest arm entry (next to the learner's own actions), then how each fresh
expert took over (its first event), and which table edge each one's plan slides the plate to
(the edge its predicted slid pose overhangs): how many edges one rollout's labels aim at, and
how often one takeover's edge differs from the one before. ``--clock`` keeps the plan's clock
(no re-timing); ``--expert-param NAME=VALUE`` sets the labelling expert's settings (as
``slide-gym dagger`` takes them from the dataset and its own ``--expert-param``).

    OMP_NUM_THREADS=1 python benchmarks/label_phases.py models/dp-ee-square-slide-stop \
        --seeds 40000-40009 --expert-param stop_overhang=0.035
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
from collections import Counter, defaultdict

import numpy as np

os.environ.setdefault("OMP_NUM_THREADS", "1")


def rollout(
    policy_dir: str, seed: int, retime: bool, expert: dict[str, float] | None = None
) -> dict:
    """One learner episode: per step the label expert's phase, the label and the action."""
    import gymnasium as gym

    import slide_gym  # noqa: F401 - registers the envs
    from agents.learned import DiffusionPolicy
    from agents.learned.labeler import PlanLabeler
    from slide_gym.datasets.config import CollectConfig

    config = CollectConfig(
        env_id="SlideGym/TopSlide-v0",
        object="square",
        table="square",
        control_mode="ee_delta",
        expert_params=expert,
    )
    policy = DiffusionPolicy.load(policy_dir, seed=seed)
    horizon = policy.config.action_horizon
    env = gym.make(config.env_id, **config.env_kwargs())
    obs, info = env.reset(seed=seed)
    task = env.unwrapped.task
    labeler = PlanLabeler(config, seed, 10.0, task.object, task.table, retime=retime)
    phases, labels, actions, takeovers, edges, low = [], [], [], [], [], []
    start_xy = np.asarray(obs["object_pose"][:2], dtype=float)
    try:
        t, done = 0, False
        while not done:
            queries = labeler.queries
            label = labeler.label(obs, t, t % horizon == 0)
            expert = labeler.agent.expert(0) if labeler.agent is not None else None
            if labeler.queries > queries and expert is not None:
                events = expert.report.events
                what = next((e for e in events if e.startswith("took over")), "planned anew")
                if any(e.startswith("no slide on") for e in events):
                    what += ", no slide on found"
                takeovers.append(what)
                if "low over the table" in what:
                    low.append(_where(expert, obs, t, start_xy))
                predicted = getattr(expert, "predicted", None)
                if predicted is not None:
                    edge = expert._overhang_at(np.asarray(predicted)).edge
                    if edge is not None:
                        edges.append(tuple(np.round(np.asarray(edge).ravel(), 3)))
            action, _ = policy.predict(obs, episode_start=np.array([t == 0]))
            labeler.executed(action)
            if label is not None and expert is not None:
                phases.append(expert.phase)
                labels.append(np.asarray(label))
                actions.append(np.asarray(action))
            obs, _, terminated, truncated, info = env.step(action)
            t += 1
            done = terminated or truncated
    finally:
        labeler.close()
        env.close()
    return {
        "seed": seed,
        "success": bool(info["is_success"]),
        "steps": t,
        "phases": phases,
        "labels": labels,
        "actions": actions,
        "takeovers": takeovers,
        "edges": edges,
        "low": low,
    }


def _where(expert, obs: dict, t: int, start_xy: np.ndarray) -> tuple[int, float, float, float]:
    """A low takeover's step, the fingertip's height over the table and distance from the
    plate's outline, and how far the plate has moved since the reset (all in m)."""
    import shapely

    from slide_gym.geometry import transform_polygon

    pose = expert._object_pose(obs)
    plate = transform_polygon(expert.obj.polygon, *pose)
    tip = np.asarray(obs["fingertip_pose"][:3], dtype=float)
    height = float(tip[2] - obs["table_height"][0])
    gap = float(plate.exterior.distance(shapely.Point(tip[0], tip[1])))
    return t, height, gap, float(np.linalg.norm(pose[:2] - start_xy))


def _largest(actions: list[np.ndarray]) -> np.ndarray:
    return np.abs(np.stack(actions)[:, :-1]).max(axis=1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("policy", help="a train-dp policy folder (the learner)")
    parser.add_argument("--seeds", default="40000-40009", help="reset seeds FIRST-LAST")
    parser.add_argument("--clock", action="store_true", help="keep the plan's clock")
    parser.add_argument(
        "--expert-param",
        action="append",
        metavar="NAME=VALUE",
        help="the labelling expert's settings, e.g. stop_overhang=0.035 (repeatable)",
    )
    args = parser.parse_args()
    from slide_gym.cli.args import parse_assignments

    expert = parse_assignments(args.expert_param, "--expert-param")
    first, last = (int(s) for s in args.seeds.split("-"))
    runs = [rollout(args.policy, s, not args.clock, expert) for s in range(first, last + 1)]
    wins = sum(r["success"] for r in runs)
    print(f"{wins} of {len(runs)} learner episodes succeeded; labels per phase of the expert:")
    by_phase: dict[str, list[int]] = defaultdict(list)
    labels = [x for r in runs for x in r["labels"]]
    actions = [x for r in runs for x in r["actions"]]
    for i, phase in enumerate(p for r in runs for p in r["phases"]):
        by_phase[phase].append(i)
    for phase, idx in by_phase.items():
        lab, act = _largest([labels[i] for i in idx]), _largest([actions[i] for i in idx])
        print(
            f"  {phase:15s} {len(idx):5d} steps: labels {100 * (lab >= 0.99).mean():4.1f} % at "
            f"the step limit, largest entry median {np.median(lab):.2f} "
            f"(the learner's {np.median(act):.2f})"
        )
    print("fresh experts took over by:")
    for what, n in Counter(t for r in runs for t in r["takeovers"]).most_common():
        print(f"  {n:4d} x {what}")
    low = np.array([w for r in runs for w in r["low"]]).reshape(-1, 4)
    if len(low):
        q = np.percentile(low, [10, 50, 90], axis=0)
        print(
            f"the {len(low)} low takeovers (10th/50th/90th percentile): step "
            f"{q[:, 0].round().astype(int).tolist()}, fingertip height "
            f"{(100 * q[:, 1]).round(1).tolist()} cm, off the plate's outline "
            f"{(100 * q[:, 2]).round(1).tolist()} cm, plate moved "
            f"{(100 * q[:, 3]).round(1).tolist()} cm"
        )
    distinct = [len(set(r["edges"])) for r in runs]
    switches = sum(sum(a != b for a, b in itertools.pairwise(r["edges"])) for r in runs)
    pairs = sum(max(0, len(r["edges"]) - 1) for r in runs)
    print(
        f"goal edges of the planned takeovers: {sum(len(r['edges']) for r in runs)} plans; "
        f"edges per rollout {distinct}; a takeover's edge differs from the one before in "
        f"{switches} of {pairs}"
    )
    summary = {
        r["seed"]: {"success": r["success"], "steps": r["steps"], "edges": len(set(r["edges"]))}
        for r in runs
    }
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
