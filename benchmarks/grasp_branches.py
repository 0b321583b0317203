"""How far apart the expert's grasps lie in joint space, across a dataset's demonstrations.

A grasping skill learns to move the arm from where the slide ended (the first step where
:func:`agents.learned.features.slide_done` holds) to where the expert closes the hand. This
prints, over the dataset's successful episodes, the arm's joints at both moments (mean and
spread, and the grasp's range), the largest joint move between them, the steps it takes, the
expert's phase at the hand-off and how many episodes press again after it, and how the grasps
split over IK branches (the signs of joints 1, 3, 5 and 7, the WAM's redundant rotations):

    python benchmarks/grasp_branches.py slide-gym/square-grasp-v1

With ``--json`` it prints one JSON object instead. It also prints how far each grasp lies
from the expert's grasp posture (``ExpertParams.grasp_posture``, the nearest of its mirror
images; the joint-space norm), and for the grasps within 1 rad of it and beyond, the median
highest fingertip above the table and the steps from the hand-off to the grasp. With
``--near-posture RAD --write-seeds FILE`` it writes the seeds of the episodes whose grasp
lies within RAD of the posture, a JSON list for ``slide-gym train-dp --episode-seeds FILE``:

    python benchmarks/grasp_branches.py slide-gym/square-grasp-ee-stop-anchor-nearest-v1 \
        --near-posture 1.0 --write-seeds near-posture-seeds.json
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

import numpy as np  # noqa: E402 - after the thread setting

BRANCH_JOINTS = (0, 2, 4, 6)
"""Joints 1, 3, 5, 7 (0-based): the sign pattern that tells the grasps' IK branches apart."""


def grasp_spread(dataset_id: str, near_posture: float | None = None) -> dict[str, Any]:
    """Joint-space statistics of the hand-off-to-grasp moves in ``dataset_id``; with
    ``near_posture`` (rad) also the seeds whose grasp lies that close to the grasp posture."""
    import minari

    from agents.learned.features import slide_done
    from agents.params import GRASP_POSTURE
    from slide_gym.robot.kinematics import mirrored_postures

    postures = mirrored_postures(np.array(GRASP_POSTURE))

    dataset = minari.load_dataset(dataset_id)
    ids = list(range(dataset.total_episodes))
    metas = list(dataset.storage.get_episode_metadata(ids))
    handoff, grasp, steps, phases, pressed_again, seeds, rise = [], [], [], Counter(), 0, [], []
    for meta, episode in zip(metas, dataset.iterate_episodes(ids), strict=True):
        record = meta["record"]
        record = json.loads(record) if isinstance(record, str) else record
        closes = [int(k) for phase, k in record["phase_steps"] if phase == "close"]
        done = slide_done(episode.observations)
        if not meta.get("success") or not closes or not done.any():
            continue
        start, close = int(np.argmax(done)), closes[-1]
        phases[max((k, p) for p, k in record["phase_steps"] if int(k) <= start)[1]] += 1
        pressed_again += any(p == "press" and int(k) > start for p, k in record["phase_steps"])
        handoff.append(episode.observations["arm_qpos"][start])
        grasp.append(episode.observations["arm_qpos"][close])
        steps.append(close - start)
        tip_z = episode.observations["fingertip_pose"][start:close, 2]
        rise.append(float(np.max(tip_z - episode.observations["table_height"][start:close, 0])))
        seeds.append(int(meta["seed"]))
    if not grasp:
        raise ValueError(f"{dataset_id!r} holds no successful episode with a grasp")
    q0, q1 = np.array(handoff), np.array(grasp)
    move = np.abs(q1 - q0).max(axis=1)
    branches = Counter("".join("+" if v >= 0 else "-" for v in q[list(BRANCH_JOINTS)]) for q in q1)
    gap = np.linalg.norm(q1[:, None, :] - postures[None], axis=2).min(axis=1)
    near = [s for s, g in zip(seeds, gap, strict=True) if near_posture and g <= near_posture]

    def rounded(a: np.ndarray) -> list[float]:
        return [round(float(v), 2) for v in a]

    return {
        "dataset": dataset_id,
        "episodes": len(grasp),
        "handoff_q_mean": rounded(q0.mean(0)),
        "handoff_q_std": rounded(q0.std(0)),
        "grasp_q_mean": rounded(q1.mean(0)),
        "grasp_q_std": rounded(q1.std(0)),
        "grasp_q_min": rounded(q1.min(0)),
        "grasp_q_max": rounded(q1.max(0)),
        "phase_at_handoff": dict(phases.most_common()),
        "pressed_again_after_handoff": pressed_again,
        "largest_joint_move_rad_p10_p50_p90": rounded(np.percentile(move, [10, 50, 90])),
        "steps_to_close_p10_p50_p90": rounded(np.percentile(steps, [10, 50, 90])),
        "branches": dict(branches.most_common()),
        "posture_gap_rad_p10_p50_p90": rounded(np.percentile(gap, [10, 50, 90])),
        "posture_gap_above_1_rad": int((gap > 1.0).sum()),
        **{
            f"{name}_median_rise_m_steps": [
                round(float(np.median(np.array(rise)[pick])), 3),
                float(np.median(np.array(steps)[pick])),
            ]
            for name, pick in (("within_1_rad", gap <= 1.0), ("beyond_1_rad", gap > 1.0))
            if pick.any()
        },
        **({"near_posture_seeds": sorted(near)} if near_posture is not None else {}),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset", help="a local Minari dataset id of grasp demonstrations")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "--near-posture",
        type=float,
        metavar="RAD",
        help="list the seeds whose grasp lies within RAD of the grasp posture",
    )
    parser.add_argument("--write-seeds", metavar="FILE", help="write those seeds to FILE")
    args = parser.parse_args(argv)
    if args.write_seeds and args.near_posture is None:
        parser.error("--write-seeds needs --near-posture RAD")
    try:
        if args.near_posture is not None and not args.near_posture > 0:
            raise ValueError(f"--near-posture must be > 0 rad, got {args.near_posture}")
        result = grasp_spread(args.dataset, args.near_posture)
    except (ValueError, FileNotFoundError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.write_seeds:
        Path(args.write_seeds).write_text(json.dumps(result["near_posture_seeds"]) + "\n")
    if args.json:
        print(json.dumps(result))
        return 0
    for key, value in result.items():
        print(f"{key}: {value}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
