"""Where an expert episode's simulated time goes, from ``slide-gym bench execute`` rows.

For each result file (plain or gzipped JSONL): episodes lifted of all, the median simulated
episode, and the median seconds of each phase over the episodes lifted without a replan
(a phase lasts from its first step to the next phase's, the last to the episode's end).

    python benchmarks/phase_times.py docs/results/bench/speed-*.jsonl.gz
    python benchmarks/phase_times.py ROWS.jsonl.gz --seeds 0 1   # only these reset seeds
"""

from __future__ import annotations

import argparse
import gzip
import json
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

STEP_S = 0.05
"""Seconds per env step (20 Hz control)."""


def load(path: Path, seeds: list[int] | None = None) -> list[dict[str, Any]]:
    """The rows of one result file, only those of ``seeds`` if given."""
    text = gzip.decompress(path.read_bytes()).decode() if path.suffix == ".gz" else path.read_text()
    rows = [json.loads(line) for line in text.splitlines() if line.strip()]
    return [r for r in rows if seeds is None or r["seed"] in seeds]


def phase_medians(rows: list[dict[str, Any]]) -> dict[str, float]:
    """Median seconds per phase over the rows lifted without a replan."""
    spans: dict[str, list[float]] = defaultdict(list)
    for row in rows:
        if not row["success"] or row.get("replans"):
            continue
        phases = [*row["phase_steps"], ["end", row["steps"]]]
        for (name, start), (_, end) in zip(phases[:-1], phases[1:], strict=True):
            spans[name].append((end - start) * STEP_S)
    return {name: float(np.median(v)) for name, v in spans.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("files", nargs="+", type=Path, help="bench execute JSONL files")
    parser.add_argument("--seeds", type=int, nargs="+", help="only these reset seeds")
    args = parser.parse_args()
    for path in args.files:
        rows = load(path, args.seeds)
        lifted = sum(bool(r["success"]) for r in rows)
        sim = float(np.median([r["sim_time_s"] for r in rows]))
        phases = ", ".join(f"{k} {v:.2f}" for k, v in phase_medians(rows).items())
        print(f"{path.name}: {lifted} of {len(rows)} lifted, simulated median {sim:.1f} s")
        print(f"  phases (s): {phases}")


if __name__ == "__main__":
    main()
