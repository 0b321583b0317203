"""Where the expert's slides stop: the plate's overhang at the end of each demonstration.

Prints, per dataset, the 0/10/50/90/100th percentiles of the last step's
``infos["overhang_m"]`` (cm), e.g. to compare an expert planning 4 cm of overhang with one
collected with ``--planner-param u_star=0.03``:

    OMP_NUM_THREADS=1 python benchmarks/final_overhang.py slide-gym/square-slide-ee-v1 \
        slide-gym/square-slide-ee-u3-v1
"""

from __future__ import annotations

import argparse
import os

import numpy as np

os.environ.setdefault("OMP_NUM_THREADS", "1")


def main() -> None:
    from slide_gym.datasets.store import load

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("datasets", nargs="+", help="Minari ids")
    args = parser.parse_args()
    for dataset_id in args.datasets:
        final = np.array([ep.infos["overhang_m"][-1] for ep in load(dataset_id).iterate_episodes()])
        cuts = np.percentile(100 * final, [0, 10, 50, 90, 100])
        print(
            f"{dataset_id}: {len(final)} episodes, final overhang (cm) min/p10/median/p90/max "
            + " / ".join(f"{c:.1f}" for c in cuts)
        )


if __name__ == "__main__":
    main()
