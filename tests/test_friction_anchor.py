"""benchmarks/friction_anchor.py: episodes re-run with friction anchors, resumable."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

import slide_gym.sim as sim


def test_prisms_are_anchored_and_the_robot_is_not(
    monkeypatch: pytest.MonkeyPatch, load_benchmark: Callable[[str], ModuleType]
) -> None:
    monkeypatch.setattr(sim.Simulation, "create_prism_body", sim.Simulation.create_prism_body)
    load_benchmark("friction_anchor").anchor_prisms()
    world = sim.Simulation()
    calls: list[tuple[int, int, dict]] = []
    change = world.client.changeDynamics
    world.client.changeDynamics = lambda b, link, **kw: (
        calls.append((b, link, kw)) or change(b, link, **kw)
    )
    from slide_gym.assets import robot_urdf

    plate = world.create_prism_body(
        "object", [np.array([[0, 0], [0.1, 0], [0, 0.1]])], 0, 0.004, 0.1
    )
    robot = world.load_urdf("robot", robot_urdf())
    anchored = {b for b, _, kw in calls if kw.get("frictionAnchor") == 1}
    assert anchored == {plate} and robot not in anchored
    world.close()


def test_reruns_the_rows_cases_and_resumes(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture,
    load_benchmark: Callable[[str], ModuleType],
) -> None:
    import slide_gym.bench.execute as execute

    cases: list[dict] = []
    run = execute.execute_case
    monkeypatch.setattr(execute, "execute_case", lambda case: cases.append(case) or run(case))
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
    assert cases == [case | {"physics": {"friction_anchor": True}}]
    assert module.main([str(rows), "--on", "robot", "--out", str(out)]) == 0  # resumed
    assert len(out.read_text().splitlines()) == 1 and len(cases) == 1
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
