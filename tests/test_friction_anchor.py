"""benchmarks/friction_anchor.py: episodes re-run with friction anchors, resumable."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path
from types import ModuleType

import pytest

import slide_gym.sim as sim


def friction_anchor() -> ModuleType:
    path = Path(__file__).resolve().parents[1] / "benchmarks" / "friction_anchor.py"
    spec = importlib.util.spec_from_file_location("friction_anchor", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_anchors_are_set_on_the_robots_links_only(monkeypatch: pytest.MonkeyPatch) -> None:
    for name in ("load_urdf", "create_prism_body"):  # restored after the test
        monkeypatch.setattr(sim.Simulation, name, getattr(sim.Simulation, name))
    friction_anchor().enable_anchors("robot")
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
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    for name in ("load_urdf", "create_prism_body"):
        monkeypatch.setattr(sim.Simulation, name, getattr(sim.Simulation, name))
    module = friction_anchor()
    rows = tmp_path / "rows.jsonl"
    case = {"object": "square", "table": "square", "seed": 0, "scale": 1.0, "success": True}
    rows.write_text(json.dumps(case) + "\n")
    out = tmp_path / "out.jsonl"
    assert module.main([str(rows), "--on", "robot", "--out", str(out)]) == 0
    (result,) = [json.loads(line) for line in out.read_text().splitlines()]
    assert result["on"] == "robot" and result["was_success"] is True
    assert isinstance(result["success"], bool)
    assert module.main([str(rows), "--on", "robot", "--out", str(out)]) == 0  # resumed
    assert len(out.read_text().splitlines()) == 1
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["episodes"] == 1


def test_a_missing_rows_file_is_a_usage_error(tmp_path: Path) -> None:
    with pytest.raises(SystemExit) as exit_info:
        friction_anchor().main([str(tmp_path / "none.jsonl"), "--out", str(tmp_path / "o")])
    assert exit_info.value.code == 2
