"""Every failed episode names its cause: the decision on synthetic outcomes, an expert that
gives up (a plate too small to plan) ending its episode at once in ``run`` and ``collect``,
the collection's failure breakdown, and the trainers' ``--only-success``."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from agents import run_episode
from agents.outcome import Outcome, failure_cause, row_failure
from slide_gym.cli import main
from slide_gym.cli.text import run_text
from slide_gym.datasets.store import build_dataset, load, read_episodes

TINY = {"object": "circle", "scale": 0.4}
"""A 4 cm disc: no point of it can overhang u* = 2 cm with its centroid on the table."""
FAILED = "test/tiny-grasp-v0"


def _info(clearance: float, pinched: bool, held: float = 0.0, table: bool = False) -> dict:
    return {
        "clearance_m": clearance,
        "pinched": pinched,
        "lift_held_s": held,
        "touching_table": table,
        "touching_robot": pinched,
        "graspable": True,
        "overhang_m": 0.03,
        "fell_off": False,
    }


def _outcome(*infos: dict, truncated: bool = True, goal: str = "grasp") -> Outcome:
    outcome = Outcome(goal)
    for info in infos:
        outcome.update(info)
    outcome.update(infos[-1], truncated)
    return outcome


def test_the_grasp_causes_once_the_expert_is_done() -> None:
    low = _outcome(_info(0.0, False), _info(0.036, True), _info(0.02, True))
    assert failure_cause(False, low, "done") == "held but clearance below 5 cm (peaked at 3.6 cm)"
    tail = _outcome(_info(0.0, True), _info(0.004, True, table=True))
    assert failure_cause(False, tail, "done") == (
        "held but clearance below 5 cm (peaked at 0.4 cm, the plate touching the table)"
    )
    short = _outcome(_info(0.06, True, held=0.4), _info(0.07, True, held=0.0))
    held = "held 5 cm up but not for 1 s (0.40 s at most, peak 7.0 cm)"
    assert failure_cause(False, short, "done") == held
    slipped = _outcome(_info(0.03, True), _info(0.0, False))
    slip = "slipped from the pinch (clearance peaked at 3.0 cm)"
    assert failure_cause(False, slipped, "done") == slip
    missed = _outcome(_info(0.001, False))
    assert failure_cause(False, missed, "done") == (
        "never held between both fingers (clearance peaked at 0.1 cm)"
    )
    one_finger = _outcome({**_info(0.152, False), "touching_robot": True})  # seen: square, seed 7
    assert failure_cause(False, one_finger, "done") == (
        "never held between both fingers (caught in the hand, clearance 15.2 cm)"
    )
    assert failure_cause(False, low, "done", lift_height=0.03) is not None
    assert failure_cause(True, low, "done") is None


def test_precedence_fell_off_then_gave_up_then_time() -> None:
    outcome = _outcome(_info(0.0, False))
    assert failure_cause(False, outcome, "slide") == "out of episode time in phase slide"
    gave_up = "plan infeasible: no stretch of the table edge allows a side grasp"
    assert failure_cause(False, outcome, "failed", gave_up) == gave_up
    outcome.update({**_info(-0.05, False), "fell_off": True})
    assert failure_cause(False, outcome, "transfer", gave_up) == (
        "the plate fell off the table in phase transfer"
    )
    assert failure_cause(False, outcome, "failed", gave_up) == (
        "the plate fell off the table after the expert gave up"
    )


def test_the_slide_causes() -> None:
    info = _info(0.0, False)
    outcome = _outcome({**info, "graspable": False, "overhang_m": 0.012}, goal="slide")
    assert failure_cause(False, outcome, "done") == "not left graspable (overhang 1.2 cm)"
    outcome = _outcome({**info, "touching_robot": True}, goal="slide")
    assert failure_cause(False, outcome, "done") == "left graspable but still touched by the robot"
    assert failure_cause(False, _outcome(info, goal="slide"), "done") == (
        "left graspable but not at rest"
    )
    with pytest.raises(ValueError, match="goal must be one of grasp, slide, got 'lift'"):
        Outcome("lift")


def test_a_failure_is_never_null() -> None:
    flags = itertools.product((False, True), repeat=5)
    for pinched, table, fell, truncated, slide in flags:
        info = {**_info(0.02, pinched, table=table), "fell_off": fell}
        outcome = _outcome(info, truncated=truncated, goal="slide" if slide else "grasp")
        for phase in ("plan", "slide", "lift", "done"):
            for gave_up in (None, "planning budget used up"):
                cause = failure_cause(False, outcome, phase, gave_up)
                assert isinstance(cause, str) and cause


def test_rows_from_before_every_failure_was_named() -> None:
    old = {"success": False, "phase_reached": "done", "truncated": True, "failure": None}
    assert row_failure(old) == "out of episode time in phase done"
    assert row_failure({**old, "failure": "planning budget used up"}) == "planning budget used up"
    assert row_failure({**old, "fell_off": True}) == "the plate fell off the table in phase done"
    new = {"success": False, "gave_up": None, "failure": "slipped from the pinch (...)"}
    assert row_failure(new) == "slipped from the pinch (...)"
    assert row_failure({"success": True, "failure": "x"}) is None
    assert row_failure({"success": False, "steps": 3}) == "failure not recorded"


def test_an_infeasible_plan_ends_the_episode_at_once_with_its_reason() -> None:
    record = run_episode(TINY["object"], "square", scale=TINY["scale"], seed=0)
    assert not record.success and record.steps == 1 and record.truncated
    assert record.phase_reached == "failed" and record.expert.plan_status == "infeasible"
    assert record.failure == record.expert.gave_up
    assert record.failure.startswith("plan infeasible: the plate cannot overhang u* = 0.0")
    text = run_text(record)
    assert "plate rose" in text and "clearance" in text and " lift " not in text
    assert f"failure: {record.failure}" in text


@pytest.mark.slow
def test_a_plate_held_too_low_says_so() -> None:
    """A 25 cm disc: grasped and lifted, but it hangs from the pinch onto the table."""
    record = run_episode("circle", "square", scale=2.5, seed=1)
    assert not record.success and record.phase_reached == "done" and record.truncated
    assert record.expert.gave_up is None
    assert record.failure.startswith("held but clearance below 5 cm (peaked at ")
    assert record.max_clearance_m is not None and record.max_clearance_m < 0.05


@pytest.fixture(scope="module")
def failed(minari_root):
    """Two episodes of the 4 cm disc: the expert gives up on its first step."""
    args = ["collect", "--object", TINY["object"], "--scale", str(TINY["scale"])]
    args += ["--episodes", "2", "--workers", "1", "--dataset-id", FAILED]
    return main(args)


def test_collect_ends_a_given_up_episode_at_once(failed) -> None:
    assert failed == 0
    for e in read_episodes(load(FAILED)):
        assert len(e.actions) == 1 and e.truncations.tolist() == [True]
        assert not e.record["success"] and e.record["failure"].startswith("plan infeasible")


def test_failure_report_warns_below_80_percent() -> None:
    from slide_gym.datasets.collect import failure_report

    summary = {"episodes_run": 4, "expert_success_rate": 0.75, "failures": {"slipped": 1}}
    text = failure_report(summary)
    assert text.splitlines() == [
        "expert success: 3 of 4 episodes (75 %)",
        "  1 x slipped",
        "warning: expert success 75 % is below 80 %: the scene may be too hard for the expert "
        "(see the failures above)",
    ]
    assert "warning" not in failure_report({**summary, "expert_success_rate": 0.8})


def test_collect_command_prints_the_failures(failed, capsys) -> None:
    args = ["collect", "--object", TINY["object"], "--scale", str(TINY["scale"])]
    assert main([*args, "--episodes", "2", "--workers", "1", "--dataset-id", FAILED]) == 0
    out, err = capsys.readouterr()
    summary = json.loads(out)
    (kind,) = summary["failures"]
    assert kind.startswith("plan infeasible: the plate cannot overhang u* = N m")
    assert summary["failures"][kind] == 2 and summary["expert_success_rate"] == 0.0
    assert "expert success: 0 of 2 episodes (0 %)" in err and f"  2 x {kind}" in err
    assert "warning: expert success 0 % is below 80 %" in err


def test_train_bc_only_success_is_a_flag(failed, tmp_path, capsys) -> None:
    out = str(tmp_path / "bc.zip")
    assert main(["train-bc", FAILED, "--out", out, "--steps", "2"]) == 2
    err = capsys.readouterr().err
    assert "no successful episode" in err and "--no-only-success" in err
    assert main(["train-bc", FAILED, "--out", out, "--steps", "2", "--no-only-success"]) == 0
    stats = json.loads(capsys.readouterr().out)
    assert stats["only_success"] is False and stats["episodes"] == 2 and stats["frames"] == 2


def test_demonstrations_keep_dagger_rollouts_and_all_episodes_on_request(failed) -> None:
    from agents.learned.data import load_demonstrations

    dataset = load(FAILED)
    with pytest.raises(ValueError, match="2 of 2 were failures"):
        load_demonstrations(dataset)
    assert load_demonstrations(dataset, only_success=False).episodes == 2
    episodes = list(read_episodes(dataset))
    episodes[1].record = {**episodes[1].record, "dagger_round": 1}
    env = dataset.recover_environment()
    try:
        mixed = build_dataset("test/tiny-dagger-v0", episodes, env, {}, algorithm_name="test")
    finally:
        env.close()
    demos = load_demonstrations(mixed)
    assert demos.episodes == 1 and demos.skipped == 1 and demos.seeds == [1]
    assert np.isfinite(demos.inputs).all()


def test_train_dp_takes_only_success(failed, tmp_path, capsys) -> None:
    args = ["train-dp", FAILED, "--out", str(tmp_path / "dp"), "--iterations", "2"]
    args += ["--log-every", "1", "--val-episodes", "0", "--channels", "8", "16"]
    assert main(args) == 2
    assert "were failures" in capsys.readouterr().err
    assert main([*args, "--no-only-success"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["demonstrations"]["only_success"] is False
    assert summary["demonstrations"]["episodes"] == 2
