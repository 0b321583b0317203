"""``slide-gym experiment``: the experiments' cases at full and quick size, rows written per
query with the code version, resume, one file per code version, and the command's errors."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from slide_gym import __version__, version
from slide_gym.cli import main
from slide_gym.experiments import run, specs
from slide_gym.experiments.specs import experiment_cases

ROW_KEYS = {
    "status", "reason", "planning_time_s", "object_start_pose", "object_goal_pose", "stats",
    "parameters", "experiment", "object", "table", "scale", "planner", "dz", "n_star", "seed",
    "time_budget", "code_version",
}  # fmt: skip
PAPER = {"square", "circle", "triangle", "crescent", "irregular"}
DZ_2CM = [0.005, 0.025]


def _values(cases: list[dict[str, Any]], key: str) -> set[Any]:
    return {json.dumps(c[key]) if isinstance(c[key], list) else c[key] for c in cases}


def test_full_sizes_follow_the_issue() -> None:
    names = ("fig10", "fig11", "fig12", "restart")
    fig10, fig11, fig12, restart = (experiment_cases(n, "v") for n in names)
    assert (len(fig10), len(fig11), len(fig12), len(restart)) == (3600, 3100, 500, 600)
    for cases in (fig10, fig11, fig12, restart):
        assert _values(cases, "time_budget") == {60.0} and _values(cases, "code_version") == {"v"}
    assert _values(fig10, "object") == PAPER | {"Y", "A", "L", "E"}
    assert _values(fig10, "table") == {"square", "round", "long", "triangle"}
    assert _values(fig10, "scale") == {1.0, 0.5} and _values(fig10, "seed") == set(range(50))
    assert _values(fig10, "dz") == {json.dumps(DZ_2CM)} and _values(fig10, "n_star") == {100}
    problems: dict[tuple[str, str], set[tuple[str, int]]] = {}
    for c in fig11:
        condition = (c["planner"], json.dumps(c["dz"]))
        problems.setdefault(condition, set()).add((c["object"], c["seed"]))
    same = {(o, s) for o in PAPER for s in range(100)}
    assert problems == {
        ("regions", "[0.005, 0.005]"): same,  # dZ* = 0
        ("regions", "[0.005, 0.01]"): same,  # dZ* = 0.5 cm
        ("regions", "[0.005, 0.025]"): same,  # dZ* = 2 cm
        ("cbirrt", "[0.005, 0.025]"): same,
        ("cbirrt2", "[0.005, 0.025]"): same,
        ("cbirrt-norestart", "[0.005, 0.025]"): same,
        ("ompl", "[0.005, 0.025]"): {(o, s) for o in PAPER for s in range(20)},
    }
    assert _values(fig11, "table") == _values(fig12, "table") == {"square"}
    assert _values(fig12, "n_star") == {1, 10, 100, 1000, 10000}
    assert _values(fig12, "dz") == {json.dumps(DZ_2CM)} and _values(fig12, "seed") == set(range(20))
    assert fig10[0]["seed"] == 0 and fig10[-1]["seed"] == 49  # the pose is the outer loop
    sweep = {(c["planner"], c["restart_iterations"]) for c in restart}
    assert sweep == {("cbirrt", r) for r in (25, 50, 100, 200, 400)} | {("cbirrt-norestart", 100)}
    assert _values(restart, "dz") == {json.dumps(DZ_2CM)} and _values(restart, "table") == {
        "square"
    }


def test_quick_sizes_are_a_smoke_test() -> None:
    sizes = {n: len(experiment_cases(n, "v", quick=True)) for n in specs.EXPERIMENTS}
    assert sizes == {
        "fig10": 4, "fig11": 14, "fig12": 4, "restart": 12, "agents": 6, "relaxation": 17,
        "planners": 12,
    }  # fmt: skip
    for name in specs.EXPERIMENTS:
        cases = experiment_cases(name, "v", quick=True)
        assert _values(cases, "time_budget") == {2.0} and _values(cases, "table") == {"square"}
        assert _values(cases, "seed") == {0}


def test_planners_is_fig11s_comparison_at_both_scales() -> None:
    full = experiment_cases("planners", "v")
    assert len(full) == 3000 and _values(full, "time_budget") == {60.0}
    problems: dict[tuple[str, float], set[tuple[str, int]]] = {}
    for c in full:
        problems.setdefault((c["planner"], c["scale"]), set()).add((c["object"], c["seed"]))
    same = {(o, s) for o in PAPER for s in range(100)}
    assert problems == {(p, s): same for p in ("regions", "cbirrt", "cbirrt2") for s in (1.0, 0.5)}
    assert _values(full, "dz") == {json.dumps(DZ_2CM)} and _values(full, "table") == {"square"}
    assert full[0]["seed"] == 0 and full[-1]["seed"] == 99  # the pose is the outer loop
    reduced = experiment_cases("planners", "v", poses=10, time_budget=10)
    assert len(reduced) == 300 and _values(reduced, "time_budget") == {10.0}
    assert reduced[:150] == [c | {"time_budget": 10.0} for c in full[:150]]  # the first poses
    assert _values(reduced, "seed") == set(range(10))


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"poses": 0}, "--poses must be 1 to 100 for planners, got 0"),
        ({"poses": 101}, "--poses must be 1 to 100 for planners, got 101"),
        ({"time_budget": 0.0}, "--budget must be > 0 s, got 0"),
        ({"quick": True, "poses": 2}, "--quick has its own size"),
    ],
)
def test_a_reduced_size_is_checked(kwargs: dict[str, Any], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        experiment_cases("planners", "v", **kwargs)


def test_fig11_quick_writes_a_row_per_query_and_resumes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    summary = run.run_experiment("fig11", quick=True, workers=1, out=tmp_path)
    stamp = version.code_version()
    path = tmp_path / f"fig11-quick-{stamp}.jsonl"
    assert summary["file"] == str(path) and summary["runs"] == summary["of"] == 14
    rows = [json.loads(line) for line in path.read_text().splitlines()]
    assert len(rows) == 14 and [p.name for p in tmp_path.iterdir()] == [path.name]
    for row in rows:
        assert row.keys() >= ROW_KEYS and not {"path", "transfer_path"} & row.keys()
        assert row["code_version"] == row["case"]["code_version"] == stamp
        assert row["experiment"] == "fig11"
        assert row["status"] in {"solved", "timeout", "infeasible"}
    planners = {r["planner"] for r in rows}
    assert planners == {"regions", "cbirrt", "cbirrt2", "cbirrt-norestart", "ompl"}

    def refuse(case: dict[str, Any]) -> dict[str, Any]:
        raise AssertionError("a finished query ran again")

    monkeypatch.setattr(run, "experiment_case", refuse)
    again = run.run_experiment("fig11", quick=True, workers=1, out=tmp_path)
    assert again["runs"] == 14 and len(path.read_text().splitlines()) == 14


def _fake_case(case: dict[str, Any]) -> dict[str, Any]:
    return {"status": "solved", "planning_time_s": 0.1, **case}


def test_another_code_version_gets_its_own_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(run, "experiment_case", _fake_case)
    monkeypatch.setattr(run, "code_version", lambda: "1.0+aaa")
    old = Path(run.run_experiment("fig12", quick=True, workers=1, out=tmp_path)["file"])
    old_text = old.read_text()
    monkeypatch.setattr(run, "code_version", lambda: "1.0+bbb")
    new = run.run_experiment("fig12", quick=True, workers=1, out=tmp_path)
    assert new["file"] == str(tmp_path / "fig12-quick-1.0+bbb.jsonl") and new["runs"] == 4
    assert "4 to run" in capsys.readouterr().err  # nothing of 1.0+aaa was reused ...
    run.run_experiment("fig12", quick=True, workers=1, out=tmp_path)
    assert f"not reusing {old}" in capsys.readouterr().err  # ... and the run says so
    assert old.read_text() == old_text
    with Path(new["file"]).open("a") as f:  # rows of another version, copied in by hand
        f.write(old_text.splitlines()[0] + "\n")
    with pytest.raises(ValueError, match=r"code version '1.0\+aaa', not '1.0\+bbb'"):
        run.run_experiment("fig12", quick=True, workers=1, out=tmp_path)


def test_code_version() -> None:
    stamp = version.code_version()
    assert stamp == __version__ or stamp.startswith(f"{__version__}+")


def test_code_version_outside_a_checkout(monkeypatch: pytest.MonkeyPatch) -> None:
    def no_git(*args: Any) -> str:
        raise FileNotFoundError("git")

    monkeypatch.setattr(version, "_git", no_git)
    version.code_version.cache_clear()
    try:
        assert version.code_version() == __version__
    finally:
        version.code_version.cache_clear()


def test_a_scene_the_planner_refuses_is_a_row() -> None:
    case = specs.case("fig10", "no-such-plate", "square", 0, "v", time_budget=1.0)
    row = run.experiment_case(case)
    assert row["status"] == run.REJECTED and "no-such-plate" in row["reason"]
    assert row["code_version"] == "v"


def _refuse(*args: object, **kwargs: object) -> Any:
    raise AssertionError("the work started although the input was bad")


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["nope"], "unknown experiment 'nope'; choose from fig10, fig11, fig12, restart, agents, "),
        (["fig10", "--ray-address", "10.0.0.1:6379"], "--ray-address goes with --backend ray"),
        (["relaxation", "--workers", "-1"], "--workers must be >= 1"),
        (["all", "--workers", "0"], "--workers must be >= 1"),
        (["planners", "--poses", "0"], "--poses must be 1 to 100 for planners, got 0"),
        (["all", "--poses", "5"], "--poses must be 1 to 2 for relaxation, got 5"),
        (["fig11", "--quick", "--budget", "5"], "--quick has its own size"),
    ],
)
def test_bad_input_exits_2_before_any_work(
    argv: list[str],
    message: str,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    tmp_path: Path,
) -> None:
    monkeypatch.setattr(run, "run_cases", _refuse)
    try:
        code = main(["experiment", *argv, "--out", str(tmp_path)])
    except SystemExit as exit_:  # argparse's usage errors
        code = exit_.code
    assert code == 2
    err = " ".join(capsys.readouterr().err.split())
    assert message in err
    assert not list(tmp_path.iterdir())


def test_file_names_keep_sizes_and_versions_apart(tmp_path: Path) -> None:
    assert run.results_file(tmp_path, "fig10", "1.0+a") == tmp_path / "fig10-1.0+a.jsonl"
    for name in ("fig10-1.0+a", "fig10-1.0+b", "fig10-quick-1.0+b", "fig11-1.0+b"):
        (tmp_path / f"{name}.jsonl").touch()
    others = run.other_versions(tmp_path, "fig10", "1.0+b")
    assert others == [tmp_path / "fig10-1.0+a.jsonl"]  # not the quick run, nor fig11
    assert run.other_versions(tmp_path, "fig10", "1.0+a", quick=True) == [
        tmp_path / "fig10-quick-1.0+b.jsonl"
    ]


def test_reduced_runs_get_their_own_files(tmp_path: Path) -> None:
    path = run.results_file(tmp_path, "planners", "1.0+a", poses=10, budget=10.0)
    assert path == tmp_path / "planners-poses10-budget10s-1.0+a.jsonl"
    assert run.file_tag(path.name, "planners") == "poses10-budget10s"
    assert run.file_tag("planners-1.0+a.jsonl.gz", "planners") == ""
    assert run.file_tag("fig11-quick-1.0+a.jsonl", "fig11") == "quick"
    assert run.file_tag("planners-1.0+a.json", "planners") is None
    assert run.parse_size_tag("poses10-budget2.5s") == {
        "quick": False, "poses": 10, "time_budget": 2.5
    }  # fmt: skip
    with pytest.raises(ValueError, match="not a size tag"):
        run.parse_size_tag("big")
    for name in ("planners-1.0+b", "planners-poses10-budget10s-1.0+b", "planners-quick-1.0+b"):
        (tmp_path / f"{name}.jsonl").touch()
    assert run.other_versions(tmp_path, "planners", "1.0+a", poses=10, budget=10.0) == [
        tmp_path / "planners-poses10-budget10s-1.0+b.jsonl"
    ]
    assert run.other_versions(tmp_path, "planners", "1.0+a") == [tmp_path / "planners-1.0+b.jsonl"]


def test_report_plots_and_quotes_the_paper(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def fake(case: dict[str, Any]) -> dict[str, Any]:
        solved = case["planner"] != "cbirrt-norestart"  # a condition that never solves
        return {"status": "solved" if solved else "timeout", "planning_time_s": 0.5, **case}

    monkeypatch.setattr(run, "experiment_case", fake)
    for name in ("fig10", "fig11", "fig12", "restart", "agents", "relaxation", "planners"):
        run.run_experiment(name, quick=True, workers=1, out=tmp_path)
    run.run_experiment("planners", workers=1, out=tmp_path, poses=1, budget=1.0)
    assert main(["report", str(tmp_path), "--out", str(tmp_path / "report")]) == 0
    out = tmp_path / "report"
    text = (out / "report.md").read_text()
    for name in specs.EXPERIMENTS:
        assert f"## {name}-quick" in text
    assert "Not run yet" not in text
    assert "| regions | 2 | 0.0 % (0-" in text  # fake agents rows carry no success
    pngs = {"fig11-quick.png", "fig12-quick-mean-time.png", "relaxation-quick.png"}
    assert {p.name for p in out.glob("*.png")} >= pngs
    assert "| dZ* = 0 cm | 2 | 0.0 % (0-" in text  # the expert's episodes per band
    assert "| expert's own band (1.2 cm to 2 cm) | 2 |" in text
    assert "| orientation | 0.5 cm | 1 | 100 % (" in text and "2 % within 60 s" in text
    assert "Reproduces the drop within our 2 s budget" in text
    assert "99 % at 60 s" in text and "lowest at N* = 100" in text
    row = next(line for line in text.splitlines() if line.startswith("| cbirrt-norestart |"))
    assert "0.0 % (0-" in row and "unsolved" in row
    assert (
        "asked for at least 99 % of queries solved within 1 s and a median of at most 0.15 s; "
        "measured 100.0 % within 1 s and a median of 0.500 s over"
    ) in text
    assert "**Not met**: the median misses by 350 ms (233 % over 0.15 s)." in text
    assert "Target (half scale): asked for a mean planning time at half scale at most 1.5x" in text
    assert (
        "## planners-poses1-budget1s" in text and "30 runs (a reduced run: poses1-budget1s)" in text
    )
    assert "| cbirrt2 | 0.5 | 2 | 100.0 % (" in text  # the quick run: 2 objects per scale
    assert "measured scale 1 median: regions 0.500 s against cbirrt 0.500 s;" in text


def test_report_refuses_an_empty_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    assert main(["report", str(tmp_path)]) == 2
    assert "no experiment results" in capsys.readouterr().err


def test_report_reads_compressed_files_and_prefers_the_larger_then_current(
    tmp_path: Path,
) -> None:
    import gzip

    from slide_gym.experiments.report import load_experiments

    def rows(version: str, n: int) -> str:
        case = {"experiment": "fig12", "code_version": version}
        return "".join(json.dumps({"case": case, "status": "solved"}) + "\n" for _ in range(n))

    current = version.code_version()
    (tmp_path / "fig12-old.jsonl.gz").write_bytes(gzip.compress(rows("old", 3).encode()))
    (tmp_path / "fig12-new.jsonl").write_text(rows(current, 2))
    assert load_experiments(tmp_path)["fig12"][0] == "old"  # the larger file wins
    (tmp_path / "fig12-new.jsonl").write_text(rows(current, 3))
    assert load_experiments(tmp_path)["fig12"][0] == current  # a tie: the current code's


def test_planners_target_names_the_best_baseline_and_the_gap() -> None:
    from slide_gym.experiments.report import _planners_markdown

    def row(planner: str, scale: float, t: float | None, rejected: int = 0) -> dict:
        case = {"planner": planner, "scale": scale}
        checks = {"overhang": rejected, "grasp_ik": 1, "valid": 1}
        stats = {"pairs_rejected": rejected, "pair_checks": checks, "iterations": 4}
        stats |= {"pairs_refused": 2 * rejected, "tree_nodes": 40}
        status = "solved" if t is not None else "timeout"
        return {"case": case, "status": status, "planning_time_s": t or 10.0, "stats": stats}

    rows = [row("regions", 1.0, t, 3) for t in (0.1, 0.2, 0.3, 0.4)]
    rows += [row("cbirrt", 1.0, t) for t in (0.1, 0.1, 0.2, 0.5)]
    rows += [row("cbirrt2", 1.0, t) for t in (0.3, 0.3, 0.3, 0.3)]
    rows += [row("regions", 0.5, t) for t in (0.1, 0.1, 0.1, None)]
    rows += [row("cbirrt", 0.5, t) for t in (0.2, 0.2, 0.2, 0.2)]
    text = "\n".join(_planners_markdown(rows, 10.0))
    assert (
        "| regions | 1 | 4 | 100.0 % (" in text
        and "| 0.250 s | 0.400 s | 0.250 s | 3.0 | 6.0 | 4.0 |" in text
    )
    assert "| regions | 0.5 | 4 | 75.0 % (" in text and "| 0.100 s | unsolved | 0.100 s |" in text
    assert "scale 1 median: regions 0.250 s against cbirrt 0.150 s" in text
    assert "scale 1 p90: regions 0.400 s against cbirrt2 0.300 s" in text  # the best per statistic
    assert "scale 0.5 median: regions 0.100 s against cbirrt 0.200 s" in text
    assert (
        "**Not met**: scale 1 median (100 ms behind cbirrt); scale 1 p90 (100 ms behind cbirrt2); "
        "scale 0.5 p90 (too few regions queries solved behind cbirrt)."
    ) in text


def test_target_lines_say_what_was_asked_measured_and_missed() -> None:
    from slide_gym.experiments.report import _scale_markdown, _speed_markdown

    def row(scale: float, t: float, dz_hi: float = 0.025) -> dict:
        case = {"planner": "regions", "scale": scale, "dz": [0.005, dz_hi]}
        return {"case": case, "status": "solved", "planning_time_s": t}

    scale = _scale_markdown([row(1.0, 0.2), row(1.0, 0.4), row(0.5, 0.9)])[0]
    assert "asked for a mean planning time at half scale at most 1.5x that at full scale" in scale
    assert "measured 0.90 s at half scale against 0.30 s at full scale, 3.00x" in scale
    assert "**Not met**: the ratio misses by 1.50 (100 % over 1.5); at half scale that is " in scale
    assert "0.45 s over the 0.45 s the target allows" in scale
    assert "**Met**." in _scale_markdown([row(1.0, 0.3), row(0.5, 0.4)])[0]

    times = [0.1] * 98 + [2.0, 3.0]  # 98 % within 1 s, median 0.1 s
    speed = _speed_markdown([row(1.0, t) for t in times], 60.0)[0]
    assert "measured 98.0 % within 1 s and a median of 0.100 s over 100 queries" in speed
    assert "**Not met**: the share within 1 s misses by 1.0 percentage points (1 of 100" in speed
    assert "median misses" not in speed
    assert "**Met**." in _speed_markdown([row(1.0, 0.1)] * 100, 60.0)[0]
