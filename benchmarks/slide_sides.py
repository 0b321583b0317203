"""Which side the expert's slides go: toward the reachable edge nearest the plate, or another.

For each episode of each dataset: the reachable stretches of the table's outline (where a
side grasp has an IK solution, :func:`~slide_gym.planning.grasp_reach.reachable_stretches`),
the group of them nearest the plate's start centroid
(:func:`~slide_gym.planning.grasp_reach.nearest_stretches`), and the stretch nearest the
plate's centroid where its overhang peaked before it left the table top (the slide's end).
Prints how many slides ended at the nearest group, e.g. to compare demonstrations of the
default expert with ``--expert-param nearest_goal_edge=1``:

    OMP_NUM_THREADS=1 python benchmarks/slide_sides.py \
        slide-gym/square-grasp-ee-stop-anchor-v1 slide-gym/square-grasp-ee-stop-anchor-nearest-v1
"""

from __future__ import annotations

import argparse
import os

import numpy as np

os.environ.setdefault("OMP_NUM_THREADS", "1")

RAISED_M = 0.005
"""A plate this far above the table top has left it (lifted): the slide ended before."""


def slide_end(plate_z: np.ndarray, overhang: np.ndarray, table_z: float) -> int:
    """The step where the overhang peaked before the plate first rose ``RAISED_M``."""
    raised = np.flatnonzero(plate_z - table_z > RAISED_M)
    last = int(raised[0]) if len(raised) else len(overhang)
    return int(np.argmax(overhang[:last]))


def toward_nearest(episode: object, scenes: object | None = None) -> bool:
    """True if the episode's slide ended at the group of reachable stretches nearest its
    start (the group nearest the plate's centroid at the slide's end is the same). The
    table is read from the first observation (``scenes``: an
    :class:`~agents.scene.SceneLibrary`, built here if None); its reach map is taken 1 mm
    above the table top, where the expert's is at the plate's mid-height (the observation
    does not give the plate's thickness; a millimetre moves no stretch's end by a cell)."""
    from agents.scene import SceneLibrary
    from slide_gym.planning.grasp_reach import nearest_stretches, reachable_stretches
    from slide_gym.planning.pair import GraspParams

    library = scenes if isinstance(scenes, SceneLibrary) else SceneLibrary()
    obs = episode.observations  # type: ignore[attr-defined]
    table = library.table_from(obs["table_outline"][0], float(obs["table_height"][0][0]))
    pose = np.asarray(obs["object_pose"], float)
    overhang = np.asarray(episode.infos["overhang_m"], float)[: len(pose)]  # type: ignore[attr-defined]
    end = pose[slide_end(pose[:, 2], overhang, table.height), :2]
    every = reachable_stretches(table.polygon, table.height + 0.001, GraspParams().edge_clearance)
    start_side = {id(s) for s in nearest_stretches(every, pose[0, :2])}
    return start_side == {id(s) for s in nearest_stretches(every, end)}


def main() -> None:
    from agents.scene import SceneLibrary
    from slide_gym.datasets.store import load

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("datasets", nargs="+", help="Minari ids")
    args = parser.parse_args()
    for dataset_id in args.datasets:
        scenes = SceneLibrary()
        sides = [toward_nearest(ep, scenes) for ep in load(dataset_id).iterate_episodes()]
        print(
            f"{dataset_id}: {sum(sides)} of {len(sides)} slides ended at the reachable edge "
            "nearest the plate's start"
        )


if __name__ == "__main__":
    main()
