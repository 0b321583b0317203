"""The relaxation experiment (issue 11): the planner's projection variants
(``SlideParams.projection``), the expert planning with a given contact band, the experiment's
cases, rows and report."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from slide_gym.cli import main
from slide_gym.experiments import report, run, specs
from slide_gym.experiments.specs import dz_band, experiment_cases
from slide_gym.geometry import get_object, get_table
from slide_gym.planning.api import SlideParams, TopSlidePlanner, TopSlideProblem
from slide_gym.planning.params import PROJECTIONS
from slide_gym.planning.runner import make_params, plan_once
from slide_gym.robot.model import ARM_LOWER, ARM_UPPER
from slide_gym.task import seeded_start_pose

ZERO = dz_band(0.0)


def test_projection_knob_defaults_to_todays_planner_and_checks_its_value() -> None:
    assert SlideParams().projection == PROJECTIONS[0] == "steps"
    assert set(PROJECTIONS) == {"steps", "nodes", "ompl", "orientation"}
    for bad in ("newton", "", None, 3, "Nodes"):
        with pytest.raises(ValueError, match="projection must be one of steps, nodes, ompl"):
            SlideParams(projection=bad)  # type: ignore[arg-type]
    assert SlideParams(projection="nodes").as_dict()["projection"] == "nodes"


def _planner(projection: str, dz: list[float], seed: int = 0) -> TopSlidePlanner:
    pose = seeded_start_pose(get_object("square"), get_table("square"), 0)
    params = SlideParams(dz=(dz[0], dz[1]), projection=projection)
    return TopSlidePlanner(TopSlideProblem("square", "square", pose, params), "regions", seed)


def _roots(pl: TopSlidePlanner, n: int) -> list[np.ndarray]:
    rng, out = np.random.default_rng(3), []
    while len(out) < n:
        q = pl.start_region.sample(rng)
        if q is not None:
            out.append(q)
    return out


def test_each_projection_lands_on_the_manifold_and_only_nodes_checks_edges() -> None:
    rng = np.random.default_rng(5)
    for projection in PROJECTIONS:
        with _planner(projection, ZERO) as pl:
            fns = pl.functions()
            assert (fns.motion_valid is not None) == (projection == "nodes")
            landed = 0
            for q0 in _roots(pl, 6):
                q = pl.project(q0 + rng.normal(0.0, 0.02, 7), q0)
                if q is not None:
                    assert pl.constraints.satisfied(q)
                    assert np.all(q >= ARM_LOWER) and np.all(q <= ARM_UPPER)
                    landed += 1
            if projection != "orientation":  # it cannot fix the depth of a zero-width band
                assert landed >= 5, projection


def test_orientation_projection_never_moves_the_depth() -> None:
    with _planner("orientation", dz_band(0.02)) as pl:
        q0 = _roots(pl, 1)[0]
        c = pl.constraints
        assert pl.project(q0, q0) is not None
        deeper = q0.copy()
        deeper[1] += 0.05  # the shoulder pitches the fingertip out of the band
        z = c.chain.forward(deeper)[2, 3]
        assert not c.band.z_lo - c.tolerance <= z <= c.band.z_hi + c.tolerance
        assert pl.project(deeper, q0) is None
        assert c.project(deeper, q0) is not None  # the default projection does move it


def test_chord_check_accepts_a_short_edge_and_rejects_a_bent_one() -> None:
    with _planner("nodes", ZERO) as pl:
        a, b = _roots(pl, 2)
        assert pl.chord_valid(a, a)
        assert not pl.chord_valid(a, b)  # far apart: the chord leaves the zero-width band
        assert pl.chord_valid(a, pl.project(a + 1e-4, a))


@pytest.mark.parametrize("projection", ["nodes", "orientation", "ompl"])
def test_a_variant_plans_the_same_twice(projection: str, plan_budget: float) -> None:
    params = dataclasses.replace(make_params(dz=(0.005, 0.025)), projection=projection)
    runs = [
        plan_once("square", "square", seed=0, time_budget=plan_budget, params=params)
        for _ in range(2)
    ]
    assert runs[0]["status"] == "solved", runs[0]["reason"]
    assert runs[0]["parameters"]["projection"] == projection
    for key in ("status", "start_config", "goal_config", "path"):
        assert runs[0][key] == runs[1][key], key
    counts = [{k: v for k, v in r["stats"].items() if not k.startswith("time_")} for r in runs]
    assert counts[0] == counts[1]


def test_the_expert_plans_every_attempt_with_the_case_band() -> None:
    from agents.params import EXPERT_SLIDE_PARAMS
    from agents.planner_agent import PlannerAgent

    assert EXPERT_SLIDE_PARAMS.dz == specs.EXPERT_DZ
    agent = PlannerAgent("regions", 10.0, dz=(0.005, 0.005))
    expert = agent._new_expert()
    expert.obj = get_object("square")
    attempts = expert._slide_params()
    assert [name for name, _ in attempts] == ["strict", "relaxed", "turning"]
    assert all(p.dz == (0.005, 0.005) for _, p in attempts)
    assert all(p.projection == "steps" for _, p in attempts)
    agent.close()


def test_full_and_quick_cases() -> None:
    full = experiment_cases("relaxation", "v")
    expert = [c for c in full if "env_id" in c]
    plans = [c for c in full if "env_id" not in c]
    assert (len(expert), len(plans)) == (288, 450)
    bands = {json.dumps(c["dz"]) for c in expert}
    assert bands == {json.dumps(dz_band(d)) for d in specs.DZ_STARS} | {"[0.012, 0.02]"}
    assert {c["planner"] for c in full} == {"regions"}
    assert {c["seed"] for c in expert} == {0, 1} and len({c["object"] for c in expert}) == 9
    assert {c["time_budget"] for c in expert} == {10.0}
    assert {c["time_budget"] for c in plans} == {20.0} and {c["table"] for c in plans} == {"square"}
    assert {c["projection"] for c in plans} == set(specs.VARIANTS)
    assert {c["seed"] for c in plans} == set(range(10))
    fig11 = {(c["object"], c["seed"]) for c in experiment_cases("fig11", "v")}
    assert {(c["object"], c["seed"]) for c in plans} <= fig11  # fig11's problems
    assert all("projection" not in c for c in experiment_cases("fig11", "v"))  # keys unchanged
    quick = experiment_cases("relaxation", "v", quick=True)
    assert len(quick) == 17 and {c["time_budget"] for c in quick} == {2.0}
    assert sum("env_id" in c for c in quick) == 8
    assert "relaxation" in specs.EXPERIMENTS and not specs.LATER


def _subset() -> list[dict[str, Any]]:
    quick = experiment_cases("relaxation", run.code_version(), quick=True)
    plan = next(c for c in quick if c.get("projection") == "nodes" and c["dz"] == ZERO)
    episode = next(c for c in quick if "env_id" in c and c["dz"] == ZERO)
    return [plan, episode]


@pytest.mark.slow
def test_a_tiny_run_writes_rows_and_a_report(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    cases = _subset()
    monkeypatch.setattr(run, "experiment_cases", lambda name, version, quick, *size, **kw: cases)
    summary = run.run_experiment("relaxation", quick=True, workers=1, out=tmp_path)
    assert summary["runs"] == summary["of"] == 2
    rows = [json.loads(line) for line in Path(summary["file"]).read_text().splitlines()]
    plan = next(r for r in rows if "projection" in r["case"])
    episode = next(r for r in rows if "env_id" in r["case"])
    assert plan["status"] in {"solved", "timeout"} and plan["projection"] == "nodes"
    assert plan["parameters"]["projection"] == "nodes" and plan["dz"] == ZERO
    assert plan["parameters"]["dz"] == ZERO
    assert {"success", "slide_error_m", "slide_error_rad", "failure"} <= episode.keys()
    assert episode["dz"] == ZERO and episode["planner"] == "regions"
    monkeypatch.setattr(report, "experiment_cases", lambda name, version, quick, *size, **kw: cases)
    assert main(["report", str(tmp_path)]) == 0
    text = (tmp_path / "report.md").read_text()
    assert "## relaxation-quick" in text and "| dZ* = 0 cm | 1 |" in text
    assert (tmp_path / "relaxation-quick.png").exists()


def _rows(times: dict[tuple[str, float], list[float]], budget: float) -> list[dict[str, Any]]:
    rows = []
    for (projection, d), ts in times.items():
        for seed, t in enumerate(ts):
            case = specs.case("relaxation", "square", "square", seed, "v", dz_star=d)
            case.update(projection=projection, time_budget=budget)
            solved = t <= budget
            rows.append(
                {"status": "solved" if solved else "timeout", "planning_time_s": t, "case": case}
            )
    return rows


def test_the_verdict_is_computed_from_the_rows() -> None:
    fast = [0.1] * 10
    slow = [0.1] + [99.0] * 9  # 10 % solved
    times = {
        ("steps", 0.0): fast,
        ("steps", 0.005): fast,
        ("steps", 0.02): fast,
        ("orientation", 0.0): slow,
        ("orientation", 0.005): [0.1] * 9 + [5.0],
        ("orientation", 0.02): fast,
    }
    variants = report._variants(_rows(times, 20.0))
    assert list(variants) == ["steps", "orientation"]
    speed = report.paper_speed(variants["orientation"], 20.0)
    assert speed is not None and speed["scale"] == pytest.approx(200.0)
    assert speed["by_60s"][0.0] == pytest.approx(0.1) and not speed["censored"]
    assert speed["t90"][0.005] == pytest.approx(20.0)
    text = report.drop_verdict(variants, 20.0)
    assert "budget" in text and ": `orientation`." in text
    assert "Closest at the paper's speed: `orientation`, 10 % solved at dZ* = 0" in text
    assert "dZ* = 0.5 cm reaches 90 % at 20 s" in text
    times[("orientation", 0.0)] = [0.1] * 5 + [99.0] * 5
    text = report.drop_verdict(report._variants(_rows(times, 20.0)), 20.0)
    assert text.count(": none.") == 2 and "`orientation`, 50 % solved at dZ* = 0" in text
