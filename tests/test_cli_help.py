"""``slide-gym`` help, ``--version``, "did you mean", ``--json`` and plain-text rounding; no
episode, plan or physics runs here (fakes stand in for them)."""

from __future__ import annotations

import json
import re
import shlex
from typing import Any

import pytest

from agents import EpisodeRecord, ExpertReport
from slide_gym import __version__
from slide_gym.cli import build_parser, commands, main

COMMANDS = [
    [],
    ["shapes"],
    ["render"],
    ["demo"],
    ["plan"],
    ["run"],
    ["bench"],
    ["bench", "env"],
    ["bench", "plan"],
    ["bench", "execute"],
    ["experiment"],
]
LONG_FLOAT = re.compile(r"\d\.\d{5,}")
"""A float printed with more than 4 decimals."""


def _help(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    with pytest.raises(SystemExit) as exit_:
        main([*argv, "--help"])
    assert exit_.value.code == 0
    return capsys.readouterr().out


def _refuse(*args: object, **kwargs: object) -> Any:
    raise AssertionError("the work started although the input was bad")


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out == f"slide-gym {__version__}\n"


@pytest.mark.parametrize("argv", COMMANDS, ids=lambda a: " ".join(a) or "slide-gym")
def test_every_help_shows_defaults_and_examples_that_parse(
    argv: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    text = _help(argv, capsys)
    assert "default" in text
    head, examples = text.split("\nExamples:\n")
    lines = [line.split(">")[0] for line in examples.splitlines() if "--help" not in line]
    assert 1 <= len(lines) <= 3
    for line in lines:
        words = shlex.split(line)
        assert words[: 1 + len(argv)] == ["slide-gym", *argv]
        build_parser().parse_args(words[1:])  # a real invocation: it parses


def test_help_gives_units(capsys: pytest.CaptureFixture[str]) -> None:
    plan = " ".join(_help(["plan"], capsys).split())
    for text in ("in s for the query (default: 10.0)", "in m, m, rad", "in rad", "(default: L)"):
        assert text in plan
    run = " ".join(_help(["run"], capsys).split())
    assert "thickness in m" in run and "(default: 0)" in run and "(default: square)" in run


def test_plan_has_the_same_scene_defaults_as_run() -> None:
    parser = build_parser()
    plan, run = parser.parse_args(["plan"]), parser.parse_args(["run"])
    assert (plan.object, plan.table, plan.seed) == (run.object, run.table, run.seed)
    assert (plan.object, plan.table, plan.seed) == ("L", "square", 0)
    assert plan.json is run.json is parser.parse_args(["demo"]).json is False


@pytest.mark.parametrize(
    ("argv", "near"),
    [
        (["run", "--object", "l"], "L"),
        (["plan", "--object", "l"], "L"),
        (["plan", "--table", "Squar"], "square"),
        (["demo", "--object", "circel"], "circle"),
        (["render", "--table", "rnd"], "round"),
    ],
)
def test_near_miss_name_exits_2_before_any_work(
    argv: list[str],
    near: str,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(commands, "_run_episode", _refuse)
    monkeypatch.setattr(commands, "_run_demo", _refuse)
    monkeypatch.setattr("slide_gym.planning.runner.plan_once", _refuse)
    monkeypatch.setattr("slide_gym.envs.top_slide.TopSlideEnv", _refuse)
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.startswith(f"slide-gym {argv[0]}: error: unknown ")
    assert f"did you mean {near!r}?" in captured.err and captured.err.count("\n") == 1


def test_far_miss_lists_the_names_and_extras_pass(monkeypatch: pytest.MonkeyPatch) -> None:
    from slide_gym.cli.args import check_name

    with pytest.raises(ValueError, match="unknown object 'banana'; valid names: .*procedural"):
        check_name("banana", "object", ("L", "E"), ("procedural",))
    assert check_name("procedural", "object", ("L",), ("procedural",)) == "procedural"
    assert check_name("my/plate.json", "object", ("L",)) == "my/plate.json"


def test_near_miss_choice_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(["run", "--planner", "region"])
    assert exit_.value.code == 2
    assert "did you mean 'regions'?" in capsys.readouterr().err


SUMMARY = {
    "object": "L",
    "table": "square",
    "seed": 0,
    "success": True,
    "steps": 120,
    "sim_time_s": 6.000000000000001,
    "wall_time_s": 3.2109876543,
    "object_start_pose": [0.5123456789, -0.0123456789, 0.3141592653589793],
    "object_final_pose": [0.6123456789, 0.1123456789, 0.3141592653589793],
    "overhang_m": 0.04512345678,
    "video": None,
}


@pytest.fixture
def fake_demo(monkeypatch: pytest.MonkeyPatch) -> list[dict[str, Any]]:
    calls: list[dict[str, Any]] = []

    def run_demo(object_name: str, table_name: str, **kwargs: Any) -> dict[str, Any]:
        calls.append({"object": object_name, "table": table_name, **kwargs})
        return dict(SUMMARY)

    monkeypatch.setattr(commands, "_run_demo", lambda: run_demo)
    return calls


def test_demo_prints_text_by_default_and_json_with_the_flag(
    fake_demo: list[dict[str, Any]], capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["demo"]) == 0
    text = capsys.readouterr().out
    assert text.startswith("success: L on square, seed 0, overhang 0.045 m")
    assert "6.00 s simulated" in text and "yaw 0.314 rad" in text
    assert not LONG_FLOAT.search(text)
    with pytest.raises(json.JSONDecodeError):
        json.loads(text)
    assert main(["demo", "--json"]) == 0
    assert capsys.readouterr().out == json.dumps(SUMMARY, indent=2) + "\n"
    assert fake_demo == [{"object": "L", "table": "square", "seed": 0, "out": None}] * 2


def test_plan_without_scene_options_prints_rounded_text(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    calls: list[tuple[Any, ...]] = []
    report = {
        "status": "solved",
        "reason": None,
        "planner": "regions",
        "planning_time_s": 0.5123456789,
        "object": "L",
        "table": "square",
        "object_start_pose": [0.5123456789, -0.0123456789, 0.3141592653589793],
        "object_goal_pose": [0.6523456789, 0.0123456789, 1.5707963267948966],
        "overhang_m": 0.0412345678,
        "path": [[0.0] * 7] * 3,
    }

    def plan_once(obj: str, table: str, **kwargs: Any) -> dict[str, Any]:
        calls.append((obj, table, kwargs["seed"]))
        return report

    monkeypatch.setattr("slide_gym.planning.runner.plan_once", plan_once)
    assert main(["plan"]) == 0
    text = capsys.readouterr().out
    assert calls == [("L", "square", 0)]
    assert text.startswith("solved (regions, 0.51 s): L on square from (x 0.512 m, y -0.012 m")
    assert "yaw 1.571 rad" in text and "overhang 0.041 m" in text
    assert not LONG_FLOAT.search(text)
    assert main(["plan", "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == report  # full precision


def test_run_text_is_rounded(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def run_episode(obj: str, table: str, **kwargs: Any) -> EpisodeRecord:
        return EpisodeRecord(
            object=obj,
            table=table,
            seed=0,
            planner="regions",
            success=True,
            phase_reached="done",
            steps=640,
            sim_time_s=32.000000000000004,
            wall_time_s=20.123456789,
            object_final_pose=[0.6123456789, 0.1123456789, 0.3123456789],
            lift_height_m=0.0712345678,
            expert=ExpertReport(planned=True, planning_time_s=0.8123456789),
        )

    monkeypatch.setattr(commands, "_run_episode", lambda: run_episode)
    assert main(["run"]) == 0
    text = capsys.readouterr().out
    assert "32.00 s simulated in 20.12 s" in text and "0.81 s planning" in text
    assert "final pose (x 0.612 m, y 0.112 m, yaw 0.312 rad)" in text
    assert not LONG_FLOAT.search(text)
