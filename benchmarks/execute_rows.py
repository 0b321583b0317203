"""What ``bench execute`` rows say beyond their summary: the figures of docs/benchmarks.md,
"Every set with the anchor".

For each rows file (``.jsonl`` or ``.jsonl.gz``), print one JSON line with the lifted count,
the slides that lost the plate (``slid: overhang 0.000`` events), the slid plate's
position and yaw error (median and 90th percentile), the failure kinds (the text before any
parenthesis) and, for generated plates, the lifted counts of plates lighter and heavier
than ``--heavy`` grams and the median circumradius and mass of the plates held but not
lifted::

    python benchmarks/execute_rows.py docs/results/bench/*-4b74df4.jsonl.gz
"""

from __future__ import annotations

import argparse
import gzip
import json
import os
import re
import sys
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

os.environ.setdefault("OMP_NUM_THREADS", "1")

LOST = "slid: overhang 0.000"
HELD = ("held", "slipped")
"""Failures of a plate the hand held but did not lift for the whole second."""


def read_rows(path: Path) -> list[dict[str, Any]]:
    opener = gzip.open if path.suffix == ".gz" else open
    with opener(path, "rt") as f:
        return [json.loads(line) for line in f if line.strip()]


def _spread(values: list[float]) -> list[float] | None:
    return [float(np.median(values)), float(np.quantile(values, 0.9))] if values else None


def plate_size(row: dict[str, Any]) -> tuple[float, float]:
    """Mass (g) and circumradius about the centroid (cm) of a generated plate's row."""
    from slide_gym.geometry import get_table
    from slide_gym.task import draw_procedural_plate

    plate = draw_procedural_plate(row["seed"], get_table(row["table"]), row.get("scale", 1.0))
    obj = plate.shape
    corners = np.asarray(obj.polygon.exterior.coords)
    radius = np.linalg.norm(corners - np.asarray(obj.polygon.centroid.coords[0]), axis=1).max()
    return 1000 * obj.mass, 100 * float(radius)


def describe(rows: list[dict[str, Any]], heavy: float) -> dict[str, Any]:
    errors = [r for r in rows if r.get("slide_error_m") is not None]
    out: dict[str, Any] = {
        "episodes": len(rows),
        "lifted": sum(r["success"] for r in rows),
        "slides_that_lost_the_plate": sum(e.startswith(LOST) for r in rows for e in r["events"]),
        "slide_error_m": _spread([r["slide_error_m"] for r in errors]),
        "slide_error_rad": _spread([r["slide_error_rad"] for r in errors]),
        "failures": dict(
            Counter(
                re.sub(r"\s*\(.*", "", r["failure"] or "") for r in rows if not r["success"]
            ).most_common()
        ),
    }
    generated = [r for r in rows if r["object"].startswith("procedural")]
    if generated:
        sizes = [plate_size(r) for r in generated]
        light = [r for r, (g, _) in zip(generated, sizes, strict=True) if g < heavy]
        held = [
            s for r, s in zip(generated, sizes, strict=True) if str(r["failure"]).startswith(HELD)
        ]
        out["generated"] = {
            "lighter": [sum(r["success"] for r in light), len(light)],
            "heavier": [
                sum(r["success"] for r in generated) - sum(r["success"] for r in light),
                len(generated) - len(light),
            ],
            "held_not_lifted": len(held),
            "held_median_mass_g": float(np.median([g for g, _ in held])) if held else None,
            "held_median_radius_cm": float(np.median([c for _, c in held])) if held else None,
        }
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("rows", type=Path, nargs="+", help="bench execute JSONL (.gz) files")
    parser.add_argument("--heavy", type=float, default=50.0, metavar="G", help="grams")
    args = parser.parse_args(argv)
    for path in args.rows:
        if not path.is_file():
            parser.error(f"no rows file {path}")
    for path in args.rows:
        print(json.dumps({"rows": str(path), **describe(read_rows(path), args.heavy)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
