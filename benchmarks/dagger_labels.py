"""What DAgger's labels say along one rollout: a diagnostic of the label expert.

`slide-gym dagger` labels every step of a learner rollout with one expert that keeps its plan
(:class:`agents.learned.labeler.PlanLabeler`). With ``--expert-share 1`` the expert also acts
for every chunk (the rollout shows whether its labels, followed, solve the task); with ``0``
the learner acts throughout and the labels are what the learner is trained toward. Prints
the rollout's summary (successes, label queries, failures) and, every 40 steps, the fingertip
height above the table, the plate's overhang and the label.

    OMP_NUM_THREADS=1 python benchmarks/dagger_labels.py POLICY_DIR --seed 40000 --expert-share 0
"""

from __future__ import annotations

import argparse
import json
import os

import numpy as np

os.environ.setdefault("OMP_NUM_THREADS", "1")


def main() -> None:
    from agents.learned.dagger import rollout_case
    from slide_gym.datasets.config import CollectConfig
    from slide_gym.datasets.recording import LABEL_KEY, RecordedEpisode

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("policy", help="a train-dp policy folder (acts when the expert does not)")
    parser.add_argument("--seed", type=int, default=40000, help="reset seed")
    parser.add_argument("--expert-share", type=float, default=1.0, help="chunks the expert acts")
    parser.add_argument("--max-steps", type=int, default=800)
    args = parser.parse_args()
    config = CollectConfig(
        env_id="SlideGym/TopSlide-v0", object="square", table="square", control_mode="ee_delta"
    )
    case = {
        "seed": args.seed,
        "round": 1,
        "policy": args.policy,
        "config": config.to_json(),
        "expert_share": args.expert_share,
        "label_budget": 10.0,
        "dagger_seed": 0,
        "max_steps": args.max_steps,
    }
    result = rollout_case(case)
    episode = RecordedEpisode.from_bytes(result.pop("payload"))
    print(json.dumps(result))
    table_z = episode.observations["table_height"][:, 0]
    tip_z = episode.observations["fingertip_pose"][:, 2] - table_z
    overhang = episode.infos["overhang_m"]
    labels = episode.infos[LABEL_KEY]
    for t in range(0, len(episode.actions), 40):
        print(
            f"step {t:3d}: fingertip {100 * tip_z[t]:5.1f} cm up, overhang "
            f"{100 * overhang[t]:4.1f} cm, label xyz {np.round(labels[t + 1][:3], 2)}"
        )


if __name__ == "__main__":
    main()
