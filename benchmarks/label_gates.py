"""Where DAgger's label gates open: in the demonstrations (how much of them the gated states
cover) and in a DAgger run's learner rollouts (how many of its failures they catch).

    OMP_NUM_THREADS=1 python benchmarks/label_gates.py slide-gym/square-slide-ee-stop-v1 \
        models/dp-dagger-off-demos-ee-square-slide-stop/round-1/episodes \
        --overhang 0.035 --miss 0.015

For each episode, the first step at which :func:`agents.learned.dagger.left_demonstrations`
holds with the gates given (``slide-gym dagger --label-from-overhang``, ``--label-from-miss``),
and which gate opened it. Prints, for the demonstrations and for the successful and failed
rollouts, how many episodes a gate opens in, at which steps, how many steps follow it to the
episode's end, and how many steps that makes in all (those a gated DAgger round asks the
expert about).
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from agents.learned.dagger import left_demonstrations  # noqa: E402
from slide_gym.datasets.recording import RecordedEpisode  # noqa: E402
from slide_gym.geometry import get_object  # noqa: E402


def first_open(episode: Any, overhang: float | None, miss: float | None) -> tuple[int, str] | None:
    """(step, gate) of the first step where a gate holds, or None."""
    options = episode.options
    plate = get_object(options["object"], float(options.get("scale", 1.0))).polygon
    obs, infos = episode.observations, episode.infos
    for t in range(len(obs["fingertip_pose"])):
        o = {k: obs[k][t] for k in ("fingertip_pose", "table_height")}
        info = {k: infos[k][t] for k in ("overhang_m", "object_pose_2d")}
        if left_demonstrations(o, info, plate, overhang=overhang):
            return t, "overhang"
        if left_demonstrations(o, info, plate, miss_height=miss):
            return t, "miss"
    return None


def summary(name: str, episodes: Iterable[Any], overhang: float | None, miss: float | None) -> None:
    n, opened, steps = 0, {"overhang": [], "miss": []}, 0
    for e in episodes:
        n += 1
        hit = first_open(e, overhang, miss)
        if hit is not None:
            opened[hit[1]].append((hit[0], len(e.actions) - hit[0]))
            steps += len(e.actions) - hit[0]
    parts = []
    for gate, hits in opened.items():
        if hits:
            at, left = np.array(hits).T
            parts.append(
                f"{gate} {len(hits)} (steps {at.min()}-{at.max()}, median {np.median(at):.0f}; "
                f"{left.min()}-{left.max()} steps to the end, median {np.median(left):.0f})"
            )
    print(f"{name}: {n} episodes; gate opened in {', '.join(parts) or 'none'}; {steps} steps after")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset", help="the demonstrations' Minari dataset id")
    parser.add_argument("rollouts", type=Path, nargs="?", help="a DAgger round's episodes folder")
    parser.add_argument("--overhang", type=float, help="as dagger --label-from-overhang")
    parser.add_argument("--miss", type=float, help="as dagger --label-from-miss")
    args = parser.parse_args()
    if args.overhang is None and args.miss is None:
        parser.error("give --overhang, --miss or both")
    from slide_gym.datasets.store import load, read_episodes

    summary("demonstrations", read_episodes(load(args.dataset)), args.overhang, args.miss)
    if args.rollouts is not None:
        rollouts = [
            RecordedEpisode.from_bytes(p.read_bytes())
            for p in sorted(args.rollouts.glob("seed-*.npz"))
        ]
        for ok in (True, False):
            kept = [e for e in rollouts if bool(e.record["success"]) is ok]
            name = "successful rollouts" if ok else "failed rollouts"
            summary(name, kept, args.overhang, args.miss)


if __name__ == "__main__":
    main()
