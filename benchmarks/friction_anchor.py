"""The expert's episodes of a ``bench execute`` run, run again with PyBullet's friction
anchors on the robot's links.

A pressed fingertip creeps over a light plate (``benchmarks/lost_plates.py --trace``):
Bullet re-creates friction constraints at each step's contact points, so static friction
drifts. ``changeDynamics(..., frictionAnchor=1)`` keeps each contact's anchor point across
steps and corrects that drift. This script measures what it changes: it runs every case of
ROWS (or only the failed ones) with the anchor on every link of the robot (``--on robot``:
the physics setting ``friction_anchor``, the fingertip-plate and fingertip-table contacts)
or on the plate and the table (``--on prisms``: every contact of the plate), writes one
JSON line per episode to ``--out`` as it goes (a re-run skips finished cases) and prints
the lifted count::

    slide-gym bench execute --trials 2 --scale 0.5 --workers 1 --out half.jsonl
    python benchmarks/friction_anchor.py half.jsonl --on robot --out half-anchor.jsonl
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

LOST = "slid: overhang 0.000"


def anchor_prisms() -> None:
    """Make every new :class:`~slide_gym.sim.Simulation` set ``frictionAnchor`` on the plate
    and the table (the robot's links have the physics setting ``friction_anchor``)."""
    import slide_gym.sim as sim

    create_prism_body = sim.Simulation.create_prism_body

    def prisms_anchored(self: Any, name: str, *args: Any, **kwargs: Any) -> int:
        body = create_prism_body(self, name, *args, **kwargs)
        self.client.changeDynamics(body, -1, frictionAnchor=1)
        return body

    sim.Simulation.create_prism_body = prisms_anchored  # type: ignore[method-assign]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("rows", type=Path, help="a bench execute JSONL")
    parser.add_argument("--on", choices=("robot", "prisms", "none"), default="robot")
    parser.add_argument("--failed", action="store_true", help="only the failed cases")
    parser.add_argument("--out", type=Path, required=True, help="results JSONL")
    args = parser.parse_args(argv)
    if not args.rows.is_file():
        parser.error(f"no rows file {args.rows}")
    from slide_gym.bench.execute import execute_case

    if args.on == "prisms":
        anchor_prisms()
    physics = {"friction_anchor": True} if args.on == "robot" else {}
    rows = [json.loads(line) for line in args.rows.read_text().splitlines() if line.strip()]
    cases = [r for r in rows if not (args.failed and r["success"])]
    key = ("object", "table", "seed", "scale", "on")
    done = set()
    if args.out.is_file():
        done = {tuple(json.loads(x)[k] for k in key) for x in args.out.read_text().splitlines()}
    with args.out.open("a") as out:
        for r in cases:
            result = {k: r[k] for k in key[:-1]} | {"on": args.on}
            if tuple(result.values()) in done:
                continue
            case = r["case"] | {"physics": r["case"].get("physics", {}) | physics}
            row = execute_case(case)  # the row's own planner, budget, thickness, env
            result |= {
                "success": row["success"],
                "failure": row["failure"],
                "slides_that_lost_the_plate": sum(e.startswith(LOST) for e in row["events"]),
                "was_success": bool(r["success"]),
            }
            out.write(json.dumps(result) + "\n")
            out.flush()
            print(*(result[k] for k in (*key[:-1], "success", "failure")), flush=True)
    results = [json.loads(x) for x in args.out.read_text().splitlines()]
    results = [x for x in results if x["on"] == args.on]
    print(
        json.dumps(
            {
                "episodes": len(results),
                "lifted": sum(x["success"] for x in results),
                "lifted_before": sum(x["was_success"] for x in results),
                "slides_that_lost_the_plate": sum(x["slides_that_lost_the_plate"] for x in results),
            }
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
