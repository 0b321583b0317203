"""Figures the docs quote about the planner's reach map and the expert's last-resort plan.

``map``: per catalog table, the seconds the reach map takes (``slide_gym.planning.grasp_reach``,
computed afresh) and the share of the goal band it keeps. ``episodes``: the expert on listed
episodes (``OBJECT:TABLE:SEED``, at ``--scale``), printing each outcome and the lifted count;
the docs list the episodes whose plans found no goal configuration before the any-turn plan.

    OMP_NUM_THREADS=1 python benchmarks/grasp_reach.py map
    OMP_NUM_THREADS=1 python benchmarks/grasp_reach.py episodes --scale 0.5 Y:triangle:0 ...
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

HALF_SCALE_NO_GOAL = [
    "irregular:long:0",
    "irregular:triangle:0",
    "Y:long:0",
    "Y:triangle:0",
    "triangle:triangle:1",
    "crescent:triangle:1",
    "irregular:long:1",
    "irregular:triangle:1",
    "Y:long:1",
    "A:triangle:1",
]
"""Half-scale episodes (`bench execute --trials 2 --scale 0.5`) whose relaxed plan found no
goal configuration at `9b7b11d`."""
FRESH_NO_GOAL = [
    "procedural:round:5009",
    "procedural:triangle:5015",
    "procedural:round:5021",
    "procedural:square:5036",
    "procedural:square:5040",
    "procedural:round:5085",
    "procedural:round:5113",
    "procedural:long:5170",
]
"""Generated plates of seeds 5000-5199 with no goal configuration at `15111d8`."""


def reach_map() -> None:
    from slide_gym.geometry.catalog import TABLES
    from slide_gym.planning.grasp_reach import _stretches, reachable_stretches
    from slide_gym.planning.regions import goal_band
    from slide_gym.robot.model import PINCH_EDGE_CLEARANCE

    for name, table in TABLES.items():
        _stretches.cache_clear()
        z = table.height + 0.001
        t0 = time.perf_counter()
        reachable_stretches(table.polygon, z, PINCH_EDGE_CLEARANCE)
        seconds = time.perf_counter() - t0
        kept = goal_band(table.polygon, 0.05, z, PINCH_EDGE_CLEARANCE).area
        print(f"{name}: {seconds:.2f} s, keeps {kept / goal_band(table.polygon, 0.05).area:.0%}")


def episodes(cases: list[str], scale: float) -> None:
    from agents.episode import run_episode

    lifted = 0
    for case in cases:
        obj, table, seed = case.split(":")
        rec = run_episode(obj, table, seed=int(seed), scale=scale)
        lifted += rec.success
        print(f"{case}: {'lifted' if rec.success else rec.failure}", flush=True)
    print(f"lifted {lifted} of {len(cases)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("map", help="the reach map's time and band share per catalog table")
    p = sub.add_parser("episodes", help="the expert on listed episodes")
    p.add_argument("cases", nargs="*", help="OBJECT:TABLE:SEED (default: --set)")
    p.add_argument("--set", choices=("half-scale", "fresh"), help="a listed set of episodes")
    p.add_argument("--scale", type=float, default=None, help="plate scale (set's own)")
    args = parser.parse_args()
    if args.command == "map":
        reach_map()
        return
    if args.set == "half-scale":
        episodes(args.cases or HALF_SCALE_NO_GOAL, args.scale or 0.5)
    else:
        episodes(args.cases or FRESH_NO_GOAL, args.scale or 1.0)


if __name__ == "__main__":
    main()
