"""The ``slide-gym`` command: output formats and exit codes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from slide_gym.cli import main
from slide_gym.geometry import OBJECT_NAMES, TABLE_NAMES


def test_shapes_json_lists_the_catalog(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["shapes", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert {r["name"] for r in rows if r["kind"] == "object"} == set(OBJECT_NAMES)
    assert {r["name"] for r in rows if r["kind"] == "table"} == set(TABLE_NAMES)
    a = next(r for r in rows if r["name"] == "A")
    assert len(a["holes"]) == 1 and len(a["vertices"]) >= 3 and a["thickness"] > 0
    assert all("height" in r for r in rows if r["kind"] == "table")


def test_shapes_text(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["shapes"]) == 0
    out = capsys.readouterr().out
    assert "crescent" in out and "triangle" in out


def test_bad_name_exits_2_with_the_valid_names() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "slide_gym.cli", "render", "--object", "banana"],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2
    assert "banana" in proc.stderr and "square" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert proc.stdout == ""


def test_bad_json_file_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bowtie.json"
    bad.write_text(json.dumps({"name": "bowtie", "vertices": [[0, 0], [1, 1], [1, 0], [0, 1]]}))
    assert main(["render", "--object", str(bad), "--out", str(tmp_path / "x.png")]) == 2
    assert "self-intersect" in capsys.readouterr().err.lower()


def test_demo_runs_and_succeeds(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["demo", "--object", "L", "--seed", "0", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["success"] is True
    assert summary["overhang_m"] >= 0.03


PLAN_KEYS = {
    "status",
    "planner",
    "planning_time_s",
    "seed",
    "object_start_pose",
    "object_goal_pose",
    "overhang_m",
    "start_config",
    "goal_config",
    "grasp_config",
    "path",
    "table_polygon",
    "object_thickness",
    "parameters",
    "stats",
}


def test_plan_json_contract(capsys: pytest.CaptureFixture[str]) -> None:
    args = ["plan", "--object", "square", "--table", "square", "--seed", "3", "--json"]
    args += ["--time-budget", "120"]  # far above the ~0.5 s it needs: load cannot flip it
    assert main(args) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out) >= PLAN_KEYS
    assert out["status"] == "solved"
    assert len(out["start_config"]) == len(out["goal_config"]) == len(out["grasp_config"]) == 7
    assert all(len(q) == 7 for q in out["path"]) and len(out["path"]) >= 2
    params = out["parameters"]
    for key in ("beta0", "dbeta", "dz", "u_star", "n_star", "contact_height_range"):
        assert key in params
    lo, hi = params["contact_height_range"]
    assert lo < hi
    assert out["overhang_m"] >= params["u_star"]


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        (["--time-budget", "nan"], "budget"),
        (["--time-budget", "0"], "budget"),
        (["--dz", "0.03,0.01"], "dz"),
        (["--object-pose", "0.6,0.24,0"], "off table"),
    ],
)
def test_plan_bad_input_exits_2(
    extra: list[str], match: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["plan", "--object", "square", "--table", "square", *extra]) == 2
    assert match in capsys.readouterr().err


def _help(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    with pytest.raises(SystemExit) as exit_:
        main([*argv, "--help"])
    assert exit_.value.code == 0
    return capsys.readouterr().out


def _words(text: str) -> str:
    return " ".join(text.split())  # argparse wraps help to the terminal's width


def test_bench_subcommands_have_their_own_options(capsys: pytest.CaptureFixture[str]) -> None:
    plan = _help(["bench", "plan"], capsys)
    assert "--steps" not in plan and "--resets" not in plan and "--markdown" not in plan
    assert "--planners" in plan and "(default: 20)" in _words(plan)
    assert "seconds per query (default: 10.0)" in _words(plan) and "bench_plan.jsonl" in plan
    env = _help(["bench", "env"], capsys)
    assert "--planners" not in env and "--trials" not in env and "--workers" not in env
    assert "(default: 600)" in _words(env)
    execute = _help(["bench", "execute"], capsys)
    assert "--steps" not in execute and "--planners" not in execute and "--plot" not in execute
    assert "(default: 10)" in _words(execute) and "results/bench_execute.jsonl" in execute
    for text in (plan, env, execute):
        assert not any(
            line.strip().startswith(("env:", "plan:", "execute:")) for line in text.splitlines()
        )


def test_bench_alone_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(["bench"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("slide-gym bench: error:") and "{env,plan,execute}" in err
    assert err.count("\n") == 1  # one line: the usage block is --help's
    assert "Traceback" not in err


def test_bench_options_of_another_benchmark_are_rejected(
    capsys: pytest.CaptureFixture[str],
) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(["bench", "plan", "--steps", "5"])
    assert exit_.value.code == 2
    assert "unrecognized arguments: --steps" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (["bench", "plan", "--planners", "regions,banana"], "banana"),
        (["bench", "plan", "--trials", "0"], "trials"),
        (["bench", "plan", "--dz", "0.01"], "--dz"),
        (["bench", "env", "--steps", "0"], "steps"),
    ],
)
def test_bench_bad_values_exit_2_with_one_line(
    argv: list[str], match: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = ["--out", str(tmp_path / "r.jsonl")]
    assert main([*argv, *out]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"slide-gym bench {argv[1]}: error: ") and match in err
    assert err.count("\n") == 1
    assert not (tmp_path / "r.jsonl").exists()
