"""The expert's per-plate planner settings and its speed profile."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from agents.episode import run_episode
from agents.params import (
    EXPERT_SLIDE_PARAMS,
    THIN_PLATE,
    THIN_PLATE_MAX_ROTATION,
    ExpertParams,
    expert_params,
    is_small_plate,
    plate_grasp_u_star,
    plate_slide_params,
    relaxed_slide_params,
    thin_plate_slide_params,
)
from agents.trajectory import Segment, time_segment
from slide_gym.planning.params import SlideParams
from slide_gym.robot.model import MIN_CONTACT_SIZE


def test_large_plates_get_the_full_margins_and_goal_band() -> None:
    sp = plate_slide_params(EXPERT_SLIDE_PARAMS, ExpertParams(), circumradius=0.10)
    assert sp.u_star == EXPERT_SLIDE_PARAMS.u_star
    assert sp.centroid_margin == EXPERT_SLIDE_PARAMS.centroid_margin
    assert sp.goal_band_width == EXPERT_SLIDE_PARAMS.goal_band_width
    assert sp.goal_sampling == EXPERT_SLIDE_PARAMS.goal_sampling == "band"
    assert plate_grasp_u_star(ExpertParams(), sp) == ExpertParams().grasp_u_star


@pytest.mark.parametrize("radius", [0.025, 0.033, 0.045])
def test_small_plates_plan_less_overhang_in_a_narrower_goal_band(radius: float) -> None:
    sp = plate_slide_params(EXPERT_SLIDE_PARAMS, ExpertParams(), circumradius=radius)
    p = ExpertParams()
    assert p.pinch_u_star + 0.002 <= sp.u_star < EXPERT_SLIDE_PARAMS.u_star
    small = is_small_plate(EXPERT_SLIDE_PARAMS, p, radius)
    assert p.pinch_u_star <= plate_grasp_u_star(p, sp, small) <= min(p.grasp_u_star, sp.u_star)
    assert sp.u_star + sp.centroid_margin <= radius
    assert sp.tip_edge_margin + 0.01 <= sp.goal_band_width < EXPERT_SLIDE_PARAMS.goal_band_width


@pytest.mark.parametrize(
    ("radius", "sampling"), [(0.025, "plate"), (0.037, "plate"), (0.05, "band")]
)
def test_plates_without_room_for_the_full_margin_draw_plate_first_goals(
    radius: float, sampling: str
) -> None:
    """Half-scale catalog plates (circumradius 2.5-3.7 cm) get plate-first goal roots; the
    smallest full-scale one (the 5 cm circle) keeps the band the margins were tuned with."""
    sp = plate_slide_params(EXPERT_SLIDE_PARAMS, ExpertParams(), circumradius=radius)
    assert sp.goal_sampling == sampling
    assert is_small_plate(EXPERT_SLIDE_PARAMS, ExpertParams(), radius) == (sampling == "plate")


def test_a_half_scale_circle_is_planned_below_u_star_and_grasped_from_the_measured_pinch() -> None:
    p = ExpertParams()
    sp = plate_slide_params(EXPERT_SLIDE_PARAMS, p, circumradius=0.025)
    assert sp.u_star < MIN_CONTACT_SIZE and sp.u_star + sp.centroid_margin <= 0.025
    assert plate_grasp_u_star(p, sp, small=True) == pytest.approx(p.pinch_u_star)


@pytest.mark.parametrize("planned", [0.021, 0.024])
def test_small_plates_are_grasped_from_the_measured_pinch_whatever_their_plan(
    planned: float,
) -> None:
    """A half-scale plate planned to 2.4 cm that lands 3 mm short is grasped, not slid again."""
    p = ExpertParams()
    sp = plate_slide_params(EXPERT_SLIDE_PARAMS, p, circumradius=0.033)
    sp = dataclasses.replace(sp, u_star=planned)
    assert plate_grasp_u_star(p, sp, small=True) == pytest.approx(p.pinch_u_star)
    assert plate_grasp_u_star(p, sp) == p.grasp_u_star


def test_thin_plates_are_turned_less_by_the_strict_plan_only() -> None:
    shim = thin_plate_slide_params(EXPERT_SLIDE_PARAMS, thickness=0.0005)
    assert shim.max_rotation == THIN_PLATE_MAX_ROTATION < EXPERT_SLIDE_PARAMS.max_rotation
    assert thin_plate_slide_params(EXPERT_SLIDE_PARAMS, THIN_PLATE) == EXPERT_SLIDE_PARAMS
    assert relaxed_slide_params(shim).max_rotation > 1.5  # the fallbacks may still turn it


def test_ramped_legs_start_and_stop_gently_and_arrive() -> None:
    q = np.zeros((2, 7))
    q[1, 0] = 1.0  # 1 rad at 1 rad/s: 1 s at full speed
    flat = time_segment(Segment("a", q, 1.0), 0.05)
    ramped = time_segment(Segment("a", q, 1.0, ramp_s=0.4), 0.05)
    assert len(ramped) == len(flat) + 8  # the ramp adds its own length (0.4 s)
    np.testing.assert_allclose(ramped[-1], q[1])
    steps = np.diff(np.r_[0.0, ramped[:, 0]])
    assert steps[0] < 0.25 * steps.max() and steps[-1] < 0.25 * steps.max()
    assert steps.max() <= 0.05 + 1e-12  # never faster than the joint speed


def test_stop_overhang_is_off_by_default_and_checked() -> None:
    assert ExpertParams().stop_overhang is None
    assert ExpertParams(stop_overhang=0.03).stop_overhang == 0.03
    for bad in (0.0, -0.01, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="stop_overhang"):
            ExpertParams(stop_overhang=bad)


def test_nearest_goal_edge_is_a_switch_off_by_default() -> None:
    assert ExpertParams().nearest_goal_edge is False
    assert expert_params({"nearest_goal_edge": 1.0}).nearest_goal_edge is True
    with pytest.raises(ValueError, match="nearest_goal_edge must be True or False"):
        expert_params({"nearest_goal_edge": 2.0})
    with pytest.raises(ValueError, match="goal_edge must be one of any, nearest"):
        SlideParams(goal_edge="far")


def test_straight_slide_on_is_a_switch_off_by_default() -> None:
    """The command line hands 1 or 0 (``--expert-param straight_slide_on=1``)."""
    assert ExpertParams().straight_slide_on is False
    assert expert_params({"straight_slide_on": 1.0}).straight_slide_on is True
    assert expert_params({"straight_slide_on": 0.0}).straight_slide_on is False
    assert expert_params({"max_replans": 3.0}).max_replans == 3  # counts stay integers
    with pytest.raises(ValueError, match="straight_slide_on must be True or False"):
        expert_params({"straight_slide_on": 0.5})


def test_a_slide_with_a_stop_overhang_ends_early_and_still_succeeds() -> None:
    """Seed 3's plan slides the square 38 steps past 3.5 cm of overhang (ee_delta); with
    the stop the slide ends there, the plate is left graspable, and the episode is shorter."""
    from agents.episode import run_episode
    from agents.params import expert_params

    def run(stop: float | None):
        return run_episode(
            "square",
            "square",
            seed=3,
            env_id="SlideGym/TopSlide-v0",
            control_mode="ee_delta",
            params=expert_params({"stop_overhang": stop}),
        )

    plain, stopped = run(None), run(0.035)
    assert plain.success and stopped.success
    assert any("slide stopped" in e for e in stopped.expert.events)
    assert not any("slide stopped" in e for e in plain.expert.events)
    assert stopped.steps < plain.steps


@pytest.mark.slow
def test_a_nearest_edge_with_no_goal_falls_back_to_any_edge(monkeypatch, plan_budget) -> None:
    """Where the reachable stretch nearest the plate admits no goal, the expert's plan is
    answered infeasible there and the same attempt runs again toward any edge."""
    import slide_gym.planning.problem as problem

    monkeypatch.setattr(problem, "nearest_stretches", lambda stretches, point: [])
    record = run_episode(
        "square",
        "square",
        seed=0,
        env_id="SlideGym/TopSlide-v0",
        time_budget=plan_budget,
        params=ExpertParams(nearest_goal_edge=True),
    ).to_json_dict()
    events = record["events"]
    assert events[0].startswith("strict plan: infeasible: no stretch of the table edge"), events
    assert record["planned"] and record["success"], events
    assert not any(e.startswith("strict (any edge) plan") for e in events), events
