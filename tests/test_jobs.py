"""Resumable batch jobs: results are written as they finish and finished cases are skipped."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from slide_gym.jobs import load_results, run_cases

CALLS: list[int] = []


def _square(case: dict[str, Any]) -> dict[str, Any]:
    CALLS.append(case["x"])
    return {"y": case["x"] ** 2}


def test_resume_skips_finished_cases_and_torn_lines(tmp_path: Path) -> None:
    out = tmp_path / "r.jsonl"
    CALLS.clear()
    run_cases(_square, [{"x": i} for i in range(3)], out, workers=1)
    assert CALLS == [0, 1, 2]
    with out.open("a") as f:
        f.write('{"case": {"x": 9}, "y"')  # a line torn by a kill
    rows = run_cases(_square, [{"x": i} for i in range(5)], out, workers=1)
    assert CALLS == [0, 1, 2, 3, 4]  # only the new cases ran
    assert sorted(r["y"] for r in rows) == [0, 1, 4, 9, 16]
    assert len(load_results(out)) == 5


def test_parallel_workers(tmp_path: Path) -> None:
    rows = run_cases(_square, [{"x": i} for i in range(4)], tmp_path / "p.jsonl", workers=2)
    assert sorted(r["y"] for r in rows) == [0, 1, 4, 9]
