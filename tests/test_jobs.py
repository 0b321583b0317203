"""Resumable batch jobs: results are written as they finish, finished cases are skipped, and
both benchmarks identify their cases through the one key function."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from agents import EpisodeRecord
from slide_gym import jobs
from slide_gym.bench import execute, plan
from slide_gym.jobs import case_key, load_results, run_cases

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


def test_returns_only_the_requested_cases(tmp_path: Path) -> None:
    out = tmp_path / "r.jsonl"
    CALLS.clear()
    run_cases(_square, [{"x": i} for i in range(4)], out, workers=1)
    rows = run_cases(_square, [{"x": 1}, {"x": 3}], out, workers=1)
    assert CALLS == [0, 1, 2, 3]  # nothing new ran
    assert [r["case"] for r in rows] == [{"x": 1}, {"x": 3}]
    assert len(load_results(out)) == 4  # other cases stay in the file


def test_case_key_ignores_key_order() -> None:
    assert case_key({"a": 1, "b": [2, 3]}) == case_key(json.loads('{"b": [2, 3], "a": 1}'))


def test_parallel_workers(tmp_path: Path) -> None:
    rows = run_cases(_square, [{"x": i} for i in range(4)], tmp_path / "p.jsonl", workers=2)
    assert sorted(r["y"] for r in rows) == [0, 1, 4, 9]


@pytest.fixture
def keys(monkeypatch: pytest.MonkeyPatch) -> list[dict[str, Any]]:
    """Every case keyed, through a spy on :func:`jobs.case_key`."""
    seen: list[dict[str, Any]] = []

    def spy(case: dict[str, Any]) -> str:
        seen.append(case)
        return case_key(case)

    monkeypatch.setattr(jobs, "case_key", spy)
    return seen


def _fake_plan(case: dict[str, Any]) -> dict[str, Any]:
    CALLS.append(case["seed"])
    solved = case["planner"] == "regions"
    return {"status": "solved" if solved else "timeout", "planning_time_s": 0.1 * case["seed"]}


def test_bench_plan_resumes_through_the_one_key(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, keys: list[dict[str, Any]]
) -> None:
    monkeypatch.setattr(plan, "plan_case", _fake_plan)
    out = tmp_path / "plan.jsonl"
    args: dict[str, Any] = dict(objects=["square"], planners=["regions", "cbirrt"], out=out)
    CALLS.clear()
    plan.bench_plan(trials=2, workers=1, **args)
    assert sorted(CALLS) == [0, 0, 1, 1]
    assert keys and all("planner" in c and "budget" in c for c in keys)
    summary = plan.bench_plan(trials=3, workers=1, **args)
    assert sorted(CALLS) == [0, 0, 1, 1, 2, 2]  # only the new trial ran
    assert summary["planners"]["regions"]["runs"] == 3
    assert summary["planners"]["cbirrt"]["solved"] == 0
    # a smaller run over the same file counts only its own cases
    assert plan.bench_plan(trials=1, workers=1, **args)["planners"]["regions"]["runs"] == 1
    assert len(CALLS) == 6


def test_bench_execute_resumes_through_the_one_key(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, keys: list[dict[str, Any]]
) -> None:
    def episode(obj: str, table: str, *, seed: int, planner: str, **_: Any) -> EpisodeRecord:
        CALLS.append(seed)
        return EpisodeRecord(
            object=obj, table=table, seed=seed, planner=planner, phase_reached="done", success=True
        )

    monkeypatch.setattr(execute, "_run_episode", lambda: episode)
    out = tmp_path / "execute.jsonl"
    CALLS.clear()
    execute.bench_execute(["L"], ["square"], trials=2, out=out, workers=1)
    assert CALLS == [0, 1]
    assert keys and all("time_budget" in c for c in keys)
    summary = execute.bench_execute(["L"], ["square"], trials=3, out=out, workers=1)
    assert CALLS == [0, 1, 2] and summary["n"] == 3
    other = execute.bench_execute(["L"], ["square"], trials=1, out=out, planner="cbirrt", workers=1)
    assert CALLS == [0, 1, 2, 0] and other["n"] == 1 and other["planners"] == ["cbirrt"]


def test_bench_execute_spreads_procedural_plates_over_the_tables(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls: list[tuple[str, str, int, float, float | None]] = []

    def episode(obj: str, table: str, *, seed: int, planner: str, **kw: Any) -> EpisodeRecord:
        calls.append((obj, table, seed, kw["scale"], kw["thickness"]))
        return EpisodeRecord(
            object=obj, table=table, seed=seed, planner=planner, phase_reached="done"
        )

    monkeypatch.setattr(execute, "_run_episode", lambda: episode)
    tables = ["square", "round"]
    out = tmp_path / "execute.jsonl"
    execute.bench_execute(["procedural", "E"], tables, trials=2, out=out, workers=1, scale=0.5)
    plates = sorted((seed, table) for obj, table, seed, *_ in calls if obj == "procedural")
    assert plates == [(0, "square"), (1, "round"), (2, "square"), (3, "round")]
    assert sorted(seed for obj, _, seed, *_ in calls if obj == "E") == [0, 0, 1, 1]
    assert {(s, t) for *_, s, t in calls} == {(0.5, None)}
    execute.bench_execute(["E"], ["square"], trials=1, out=out, workers=1, thickness=0.0008)
    assert calls[-1] == ("E", "square", 0, 1.0, 0.0008)  # another case: it ran
