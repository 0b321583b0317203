"""benchmarks/execute_rows.py: the figures it reads from bench execute rows."""

from __future__ import annotations

import gzip
import json
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import pytest


def _row(obj: str, seed: int, success: bool, failure: str | None, events: list[str]) -> dict:
    return {
        "object": obj,
        "table": "square",
        "seed": seed,
        "success": success,
        "failure": failure,
        "events": events,
        "slide_error_m": 0.001 * (seed + 1),
        "slide_error_rad": 0.01,
    }


def test_counts_lost_slides_failures_and_plates_by_mass(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    load_benchmark: Callable[[str], ModuleType],
) -> None:
    module = load_benchmark("execute_rows")
    lost = "slid: overhang 0.000 m, error 0.3 m"
    rows = [
        _row("procedural-0", 0, True, None, ["slid: overhang 0.030 m"]),
        _row("procedural-1", 1, False, "held but clearance below 5 cm (peaked at 1 cm)", [lost]),
        _row("procedural-2", 2, False, "the plate fell off the table in phase slide", [lost, lost]),
    ]
    path = tmp_path / "rows.jsonl.gz"
    with gzip.open(path, "wt") as f:
        f.writelines(json.dumps(r) + "\n" for r in rows)
    assert module.main([str(path), "--heavy", "1e9"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["episodes"] == 3 and out["lifted"] == 1
    assert out["slides_that_lost_the_plate"] == 3
    assert out["failures"] == {
        "held but clearance below 5 cm": 1,
        "the plate fell off the table in phase slide": 1,
    }
    assert out["slide_error_m"][0] == pytest.approx(0.002)
    generated = out["generated"]
    assert generated["lighter"] == [1, 3] and generated["heavier"] == [0, 0]
    assert generated["held_not_lifted"] == 1 and generated["held_median_mass_g"] > 0


def test_a_missing_rows_file_is_a_usage_error(
    tmp_path: Path, load_benchmark: Callable[[str], ModuleType]
) -> None:
    with pytest.raises(SystemExit) as exit_info:
        load_benchmark("execute_rows").main([str(tmp_path / "none.jsonl")])
    assert exit_info.value.code == 2
