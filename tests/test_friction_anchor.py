"""benchmarks/friction_anchor.py: episodes re-run with friction anchors, resumable."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import pytest

import slide_gym.sim as sim


def test_anchors_are_set_on_the_robots_links_only(
    monkeypatch: pytest.MonkeyPatch, load_benchmark: Callable[[str], ModuleType]
) -> None:
    for name in ("load_urdf", "create_prism_body"):  # restored after the test
        monkeypatch.setattr(sim.Simulation, name, getattr(sim.Simulation, name))
    load_benchmark("friction_anchor").enable_anchors("robot")
    world = sim.Simulation()
    calls: list[tuple[int, int, dict]] = []
    change = world.client.changeDynamics
    world.client.changeDynamics = lambda b, link, **kw: (
        calls.append((b, link, kw)) or change(b, link, **kw)
    )
    from slide_gym.assets import robot_urdf

    body = world.load_urdf("robot", robot_urdf())
    anchored = {link for b, link, kw in calls if b == body and kw.get("frictionAnchor") == 1}
    assert anchored == set(range(-1, world.client.getNumJoints(body)))
    world.close()


def test_reruns_the_rows_cases_and_resumes(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture,
    load_benchmark: Callable[[str], ModuleType],
) -> None:
    for name in ("load_urdf", "create_prism_body"):
        monkeypatch.setattr(sim.Simulation, name, getattr(sim.Simulation, name))
    module = load_benchmark("friction_anchor")
    rows = tmp_path / "rows.jsonl"
    scene = {"object": "square", "table": "square", "seed": 0, "scale": 1.0}
    case = scene | {"planner": "regions", "time_budget": 10.0}  # as bench execute writes it
    rows.write_text(json.dumps(scene | {"case": case, "success": True}) + "\n")
    out = tmp_path / "out.jsonl"
    assert module.main([str(rows), "--on", "robot", "--out", str(out)]) == 0
    (result,) = [json.loads(line) for line in out.read_text().splitlines()]
    assert result["on"] == "robot" and result["was_success"] is True
    assert isinstance(result["success"], bool)
    assert module.main([str(rows), "--on", "robot", "--out", str(out)]) == 0  # resumed
    assert len(out.read_text().splitlines()) == 1
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["episodes"] == 1


def test_a_missing_rows_file_is_a_usage_error(
    tmp_path: Path, load_benchmark: Callable[[str], ModuleType]
) -> None:
    with pytest.raises(SystemExit) as exit_info:
        load_benchmark("friction_anchor").main(
            [str(tmp_path / "none.jsonl"), "--out", str(tmp_path / "o")]
        )
    assert exit_info.value.code == 2
