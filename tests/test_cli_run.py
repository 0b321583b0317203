"""``slide-gym run`` and ``slide-gym bench execute`` with a fake episode (no physics), and the
episode record they share."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import pytest

from agents import EpisodeRecord, ExpertReport
from slide_gym.bench import execute as bench_execute
from slide_gym.bench.execute import execute_case, execute_markdown_table, summarize_execute
from slide_gym.cli import commands, main
from slide_gym.geometry import OBJECT_NAMES, TABLE_NAMES

CONTRACT_KEYS = {
    "success",
    "planned",
    "replans",
    "planning_time_s",
    "steps",
    "sim_time_s",
    "wall_time_s",
    "object_final_pose",
    "lift_height_m",
    "slide_error_m",
    "slide_error_rad",
    "object",
    "table",
    "seed",
    "planner",
    "phase_reached",
    "failure",
}


class FakeEpisode:
    """Stands in for ``agents.episode.run_episode``; records its calls."""

    def __init__(self, error: str | None = None):
        self.error = error
        self.calls: list[dict[str, Any]] = []

    def __call__(self, object: Any, table: Any, **kwargs: Any) -> EpisodeRecord:  # noqa: A002
        self.calls.append({"object": object, "table": table, **kwargs})
        if self.error is not None:
            raise ValueError(self.error)
        return EpisodeRecord(
            object=object,
            table=table,
            seed=kwargs.get("seed", 0),
            planner=kwargs.get("planner", "regions"),
            success=True,
            phase_reached="done",
            steps=640,
            sim_time_s=32.0,
            wall_time_s=20.0,
            object_start_pose=[0.5, 0.0, 0.0],
            object_final_pose=[0.6, 0.1, 0.3],
            lift_height_m=0.07,
            max_lift_height_m=0.08,
            expert=ExpertReport(
                planned=True,
                replans=1,
                planning_time_s=0.8,
                plan_status="solved",
                events=["slid"],
                object_predicted_pose=[0.6, 0.1, 0.25],
                object_slid_pose=[0.61, 0.1, 0.3],
                slide_error_m=0.01,
                slide_error_rad=0.05,
            ),
        )


@pytest.fixture
def fake(monkeypatch: pytest.MonkeyPatch) -> FakeEpisode:
    episode = FakeEpisode()
    monkeypatch.setattr(commands, "_run_episode", lambda: episode)
    monkeypatch.setattr(bench_execute, "_run_episode", lambda: episode)
    return episode


def test_run_json_prints_one_object_with_the_contract_keys(
    fake: FakeEpisode, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["run", "--json"]) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1
    assert set(json.loads(out)) >= CONTRACT_KEYS
    assert fake.calls == [
        {
            "object": "L",
            "table": "square",
            "scale": 1.0,
            "seed": 0,
            "planner": "regions",
            "time_budget": 10.0,
            "video": None,
            "thickness": None,
            "env_id": "SlideGym/TopSlideGrasp-v1",
            "object_pose": None,
            "physics": None,
        }
    ]


def test_run_passes_options_and_prints_a_short_summary(
    fake: FakeEpisode, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    video = tmp_path / "ep.gif"
    argv = ["run", "--object", "E", "--table", "round", "--scale", "1.2", "--seed", "3"]
    argv += ["--planner", "cbirrt2", "--time-budget", "4", "--video", str(video)]
    argv += ["--thickness", "0.0008", "--env", "SlideGym/TopSlide-v0"]
    argv += ["--object-pose", "0.6,0.1,0.3", "--physics", "friction_anchor=1"]
    assert main(argv) == 0
    assert fake.calls[0] == {
        "object": "E",
        "table": "round",
        "scale": 1.2,
        "seed": 3,
        "planner": "cbirrt2",
        "time_budget": 4.0,
        "video": video,
        "thickness": 0.0008,
        "env_id": "SlideGym/TopSlide-v0",
        "object_pose": (0.6, 0.1, 0.3),
        "physics": {"friction_anchor": True},
    }
    lines = capsys.readouterr().out.splitlines()
    assert 2 <= len(lines) <= 6
    assert lines[0].startswith("lifted: E on round")
    assert "1.0 cm" in lines[2] and "2.9 deg" in lines[2]


def test_run_value_error_exits_2_with_one_line_on_stderr(
    fake: FakeEpisode, capsys: pytest.CaptureFixture[str]
) -> None:
    fake.error = "could not place object 'L' on table 'triangle': the object is too large"
    assert main(["run", "--table", "triangle", "--json"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err == f"slide-gym run: error: {fake.error}\n"


def test_execute_case_turns_a_value_error_into_a_failure_row(fake: FakeEpisode) -> None:
    fake.error = "object does not fit on the table"
    case = {"object": "E", "table": "triangle", "seed": 2, "planner": "regions", "time_budget": 5}
    row = execute_case(case)
    assert set(row) >= CONTRACT_KEYS
    assert row["success"] is False and row["planned"] is False
    assert row["failure"] == fake.error
    assert (row["object"], row["table"], row["seed"]) == ("E", "triangle", 2)
    assert fake.calls[0]["time_budget"] == 5


def test_failure_row_and_success_row_have_the_same_keys(fake: FakeEpisode) -> None:
    case = {"object": "E", "table": "triangle", "seed": 2, "planner": "regions", "time_budget": 5}
    success = execute_case(case)
    fake.error = "object does not fit on the table"
    failure = execute_case(case)
    assert success["success"] is True and failure["phase_reached"] == "rejected"
    assert list(failure) == list(success)
    assert failure["planning_time_s"] is None and failure["wall_time_s"] is None
    assert failure["events"] == [] and failure["scale"] == 1.0


def test_run_json_is_the_records_flat_dict(
    fake: FakeEpisode, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["run", "--object", "E", "--seed", "4", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    record = fake("E", "square", seed=4)
    assert out == record.to_json_dict()
    assert out["planned"] is True and out["slide_error_m"] == 0.01  # the expert's, flattened
    assert "expert" not in out


def test_record_to_json_dict_round_trips_through_json(fake: FakeEpisode) -> None:
    for record in (
        fake("L", "round", seed=7, planner="cbirrt"),
        EpisodeRecord.rejected("L", "round", seed=7, planner="cbirrt", reason="too large"),
    ):
        flat = record.to_json_dict()
        again = json.loads(json.dumps(flat))
        assert again == flat
        assert EpisodeRecord.from_json_dict(again) == record
        assert EpisodeRecord.from_json_dict({"case": {"seed": 7}, **again}) == record


def test_record_keys_are_written_once() -> None:
    episode = {f.name for f in dataclasses.fields(EpisodeRecord)} - {"expert"}
    expert = {f.name for f in dataclasses.fields(ExpertReport)}
    assert not episode & expert  # a flat key comes from exactly one of the two
    rejected = EpisodeRecord.rejected("L", "square", seed=0, planner="regions", reason="x")
    assert set(rejected.to_json_dict()) == episode | expert >= CONTRACT_KEYS


def test_records_do_not_share_event_lists() -> None:
    a, b = (
        EpisodeRecord(object="L", table="square", seed=s, planner="regions", phase_reached="plan")
        for s in (0, 1)
    )
    a.expert.events.append("slid")
    assert b.expert.events == [] and a.to_json_dict()["events"] == ["slid"]


def _row(obj: str, table: str, success: bool, error_m: float | None, wall: float) -> dict:
    return {
        "object": obj,
        "table": table,
        "planner": "regions",
        "success": success,
        "planned": error_m is not None,
        "wall_time_s": wall,
        "slide_error_m": error_m,
        "slide_error_rad": None if error_m is None else 10 * error_m,
    }


ROWS = [
    _row("L", "square", True, 0.01, 10.0),
    _row("L", "round", False, 0.03, 20.0),
    _row("L", "square", True, 0.02, 30.0),
    _row("square", "round", False, None, 40.0),
]


def test_summarize_execute_rates_medians_and_rows() -> None:
    s = summarize_execute(ROWS)
    assert s["n"] == 4 and s["planners"] == ["regions"]
    assert s["success_rate"] == 0.5 and s["planned_rate"] == 0.75
    assert s["wall_time_s_median"] == 25.0
    assert s["wall_time_s_p90"] == pytest.approx(37.0)
    assert s["slide_error_m_median"] == pytest.approx(0.02)
    assert s["slide_error_rad_median"] == pytest.approx(0.2)
    assert s["slide_error_deg_median"] == pytest.approx(math.degrees(0.2))
    assert list(s["by_object"]) == ["square", "L"]  # catalog order
    letter = s["by_object"]["L"]
    assert letter["n"] == 3 and letter["success_rate"] == pytest.approx(2 / 3)
    assert letter["slide_error_cm_median"] == pytest.approx(2.0)
    assert letter["slide_error_deg_median"] == pytest.approx(math.degrees(0.2))
    assert letter["wall_time_s_median"] == 20.0
    sq = s["by_object"]["square"]
    assert sq["slide_error_cm_median"] is None and sq["slide_error_deg_median"] is None
    assert s["by_table"]["round"] == {
        "n": 2,
        "success_rate": 0.0,
        "slide_error_cm_median": pytest.approx(3.0),
        "slide_error_deg_median": pytest.approx(math.degrees(0.3)),
        "wall_time_s_median": 30.0,
    }


def test_summarize_execute_throughput() -> None:
    rows = [
        {**_row("L", "square", True, 0.01, 2.0), "sim_time_s": 20.0, "planning_time_s": 0.5},
        {**_row("L", "round", False, 0.01, 4.0), "sim_time_s": 10.0, "planning_time_s": 2.0},
    ]
    s = summarize_execute(rows)
    assert s["real_time_factor"] == pytest.approx(5.0)  # 30 simulated s in 6 wall s
    assert s["planning_share_median"] == pytest.approx(0.375)  # of 0.25 and 0.5
    assert s["demos_per_core_min"] == pytest.approx(10.0)  # 1 lifted in 0.1 core-minutes
    assert (s["sim_time_s_total"], s["wall_time_s_total"]) == pytest.approx((30.0, 6.0))
    assert s["planning_time_s_total"] == pytest.approx(2.5)
    assert "real-time factor 5.0x" in execute_markdown_table(s)
    assert summarize_execute(ROWS)["real_time_factor"] is None  # no simulated times


def test_summarize_execute_of_nothing() -> None:
    s = summarize_execute([])
    assert s["n"] == 0 and s["success_rate"] is None and s["wall_time_s_p90"] is None
    assert "0 episodes" in execute_markdown_table(s)


def test_markdown_lists_every_object_and_table() -> None:
    rows = [_row(o, t, True, 0.01, 5.0) for o in OBJECT_NAMES for t in TABLE_NAMES]
    md = execute_markdown_table(summarize_execute(rows))
    cells = {line.split("|")[1].strip() for line in md.splitlines() if line.startswith("| ")}
    assert set(OBJECT_NAMES) | set(TABLE_NAMES) <= cells
    assert md.splitlines()[0].startswith("**Overall**")
    assert "100%" in md and "| - |" not in md


def test_bench_execute_runs_every_case_once_and_resumes(
    fake: FakeEpisode, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "execute.jsonl"
    argv = ["bench", "execute", "--objects", "L,square", "--tables", "square,round"]
    argv += ["--trials", "2", "--seed", "5", "--workers", "1", "--out", str(out)]
    assert main(argv) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["n"] == 8 and summary["success_rate"] == 1.0
    assert sorted({c["seed"] for c in fake.calls}) == [5, 6]
    assert len(out.read_text().splitlines()) == 8
    assert main([*argv, "--markdown"]) == 0
    assert len(fake.calls) == 8
    assert "| L | 4 | 100% |" in capsys.readouterr().out


def test_bench_execute_cases_name_their_env_and_old_cases_mean_v0(
    fake: FakeEpisode, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A case names its env even at the default, so a results file from before the v1 ids
    (whose cases left the then-default v0 out) is not resumed as if it were v1."""
    out = tmp_path / "execute.jsonl"
    argv = ["bench", "execute", "--objects", "L", "--tables", "square", "--trials", "1"]
    assert main([*argv, "--workers", "1", "--out", str(out)]) == 0
    assert json.loads(out.read_text())["case"]["env_id"] == "SlideGym/TopSlideGrasp-v1"
    assert fake.calls[-1]["env_id"] == "SlideGym/TopSlideGrasp-v1"
    old_case = {"object": "L", "table": "square", "seed": 0, "planner": "regions"}
    bench_execute.execute_case({**old_case, "time_budget": 10.0})
    assert fake.calls[-1]["env_id"] == "SlideGym/TopSlideGrasp-v0"


def test_bench_execute_rejects_bad_input(
    fake: FakeEpisode, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = str(tmp_path / "x.jsonl")
    assert main(["bench", "execute", "--objects", "banana", "--out", out]) == 2
    assert "banana" in capsys.readouterr().err
    assert main(["bench", "execute", "--trials", "0", "--out", out]) == 2
    assert main(["bench", "execute", "--time-budget", "0", "--out", out]) == 2
    assert fake.calls == []


def test_bench_execute_passes_expert_params_to_every_episode(
    fake: FakeEpisode, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "execute.jsonl"
    argv = ["bench", "execute", "--objects", "L", "--tables", "square", "--trials", "2"]
    argv += ["--workers", "1", "--out", str(out), "--expert-param", "slide_speed=0.06"]
    assert main([*argv, "--expert-param", "max_replans=3"]) == 0
    params = [c["params"] for c in fake.calls]
    assert [(p.slide_speed, p.max_replans) for p in params] == [(0.06, 3), (0.06, 3)]
    assert isinstance(params[0].max_replans, int)
    assert all(json.loads(line)["case"]["expert"]["slide_speed"] == 0.06 for line in out.open())


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("slide_sped=0.07", "unknown expert parameters ['slide_sped']; allowed: approach_speed"),
        ("slide_speed=-1", "slide_speed must be a finite positive number"),
        ("slide_speed", "--expert-param takes NAME=NUMBER, got 'slide_speed'"),
    ],
)
def test_bench_execute_rejects_a_bad_expert_param(
    fake: FakeEpisode, tmp_path: Path, capsys: pytest.CaptureFixture[str], value: str, message: str
) -> None:
    argv = ["bench", "execute", "--expert-param", value, "--out", str(tmp_path / "x.jsonl")]
    assert main(argv) == 2
    assert message in capsys.readouterr().err
    assert fake.calls == []


def test_failures_are_counted_by_cause_without_their_numbers() -> None:
    from agents.outcome import failure_kind

    base = {"success": False, "fell_off": False, "truncated": False, "phase_reached": "failed"}
    rows = [
        {**base, "failure": "planner: time budget exhausted after 63 iterations (24 start)"},
        {**base, "failure": "planner: time budget exhausted after 86 iterations (35 start)"},
        {**base, "phase_reached": "slide", "fell_off": True, "failure": None},
        {**base, "phase_reached": "lift_off", "truncated": True, "failure": None},
        {**base, "success": True, "failure": None},
    ]
    assert [failure_kind(r) for r in rows] == [
        "planner: time budget exhausted",
        "planner: time budget exhausted",
        "the plate fell off the table in phase slide",
        "out of episode time in phase lift_off",
        None,
    ]
    summary = summarize_execute(
        [{**r, "object": "E", "table": "square", "planner": "regions"} for r in rows]
    )
    assert summary["failures"] == {
        "planner: time budget exhausted": 2,
        "the plate fell off the table in phase slide": 1,
        "out of episode time in phase lift_off": 1,
    }
    assert "| planner: time budget exhausted | 2 |" in execute_markdown_table(summary)
