"""Plates the pinch held but could not lift, run again with the expert pinching deeper.

Reads rows written by ``slide-gym bench execute --out ROWS.jsonl`` (gzipped or not), picks
the failed episodes whose plate was held or slipped from the pinch ("held ...", "slipped
from the pinch ..."), or takes ``--cases OBJECT:TABLE:SEED ...`` instead, and runs each
again at every ``--depth`` (how far in from the overhang's outer end the fingertips pinch,
``GraspParams.depth``) and grasp stand-off ``--retreat``, in the physics given with
``--physics`` (the rows' own). Prints one JSON line per episode and how many were lifted at
each setting:

    python benchmarks/pinch_depth.py docs/results/bench/gen0-anchor-4b74df4.jsonl.gz \
        --physics friction_anchor=1 --depth 0.015 0.025 0.035 --retreat 0.06
    python benchmarks/pinch_depth.py --cases procedural:round:25 procedural:long:54 \
        --physics friction_anchor=1 --depth 0.035 --retreat 0.06 0.08
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

# the sibling script (run from benchmarks/); after the thread setting: it imports NumPy
from execute_rows import HELD, read_rows  # noqa: E402


def named_cases(specs: list[str]) -> list[dict[str, Any]]:
    """``OBJECT:TABLE:SEED`` strings as cases."""
    cases = []
    for spec in specs:
        parts = spec.split(":")
        if len(parts) != 3 or not parts[2].isdigit():
            raise SystemExit(f"--cases takes OBJECT:TABLE:SEED, got {spec!r}")
        cases.append({"object": parts[0], "table": parts[1], "seed": int(parts[2])})
    return cases


def pinched_failures(path: Path) -> list[dict[str, Any]]:
    """The rows of ``path`` whose plate the pinch held, or lost, without lifting it."""
    rows = read_rows(path)
    return [r for r in rows if not r["success"] and (r["failure"] or "").startswith(HELD)]


def main() -> int:
    from agents.episode import run_episode
    from agents.params import EXPERT_SLIDE_PARAMS
    from slide_gym.cli.args import parse_physics

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "rows", type=Path, nargs="?", help="bench execute rows (.jsonl or .jsonl.gz)"
    )
    parser.add_argument("--cases", nargs="+", metavar="OBJECT:TABLE:SEED", help="instead of rows")
    parser.add_argument("--depth", type=float, nargs="+", required=True, metavar="M")
    parser.add_argument(
        "--retreat",
        type=float,
        nargs="+",
        default=[EXPERT_SLIDE_PARAMS.grasp.retreat],
        metavar="M",
        help="grasp stand-offs (default: the expert's)",
    )
    parser.add_argument("--physics", action="append", default=[], metavar="NAME=VALUE")
    args = parser.parse_args()
    physics = parse_physics(args.physics)
    if (args.rows is None) == (args.cases is None):
        parser.error("give either ROWS or --cases")
    cases = named_cases(args.cases) if args.cases else pinched_failures(args.rows)
    settings = [(d, r) for d in args.depth for r in args.retreat]
    lifted = dict.fromkeys(settings, 0)
    for depth, retreat in settings:
        grasp = dataclasses.replace(EXPERT_SLIDE_PARAMS.grasp, depth=depth, retreat=retreat)
        for case in cases:
            record = run_episode(
                "procedural" if case["object"].startswith("procedural-") else case["object"],
                case["table"],
                seed=case["seed"],
                scale=case.get("scale", 1.0),
                physics=physics,
                grasp=grasp,
            )
            lifted[depth, retreat] += bool(record.success)
            print(
                json.dumps(
                    {
                        "depth": depth,
                        "retreat": retreat,
                        "object": case["object"],
                        "table": case["table"],
                        "seed": case["seed"],
                        "success": record.success,
                        "failure": record.failure,
                        "before": case.get("failure"),
                    }
                ),
                flush=True,
            )
    for (depth, retreat), n in lifted.items():
        print(f"depth {depth:.3f} m, stand-off {retreat:.3f} m: {n} of {len(cases)} lifted")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
