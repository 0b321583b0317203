"""Planner options the expert relies on: shortcutting, press-point filters, plate-turn limit,
replanning from an overhanging pose, parameters as JSON."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import shapely

from slide_gym.geometry import get_object, get_table
from slide_gym.planning.api import SlideParams, TopSlideProblem
from slide_gym.planning.result import SearchParams
from slide_gym.planning.search import SearchFunctions
from slide_gym.planning.smoothing import path_length, shortcut_path
from slide_gym.robot.kinematics import fingertip_chain


def _free_space(blocked: shapely.Geometry | None = None) -> SearchFunctions:
    def collides(q: np.ndarray) -> bool:
        return blocked is not None and blocked.contains(shapely.Point(q))

    return SearchFunctions(
        sample_config=lambda rng: rng.uniform(-1, 1, 2),
        project=lambda q, near: q,
        collides=collides,
    )


def test_shortcut_shortens_a_zigzag_and_keeps_its_ends():
    zigzag = np.array([[0, 0], [0.2, 0.5], [0.4, -0.5], [0.6, 0.5], [0.8, -0.5], [1, 0]], float)
    params = SearchParams(step_size=0.05)
    out = shortcut_path(zigzag, _free_space(), params, np.random.default_rng(0), attempts=30)
    w = np.ones(2)
    assert path_length(out, w) < 0.5 * path_length(zigzag, w)
    np.testing.assert_array_equal(out[0], zigzag[0])
    np.testing.assert_array_equal(out[-1], zigzag[-1])
    again = shortcut_path(zigzag, _free_space(), params, np.random.default_rng(0), attempts=30)
    np.testing.assert_array_equal(out, again)


def test_shortcut_never_crosses_an_obstacle():
    wall = shapely.box(0.45, -0.3, 0.55, 2.0)
    around = np.array([[0, 0], [0.5, -0.5], [1, 0]], float)
    params = SearchParams(step_size=0.02)
    out = shortcut_path(around, _free_space(wall), params, np.random.default_rng(1), attempts=30)
    assert not any(wall.contains(shapely.Point(q)) for q in out)
    dense = np.concatenate([np.linspace(a, b, 20) for a, b in zip(out[:-1], out[1:], strict=True)])
    assert not any(wall.contains(shapely.Point(q)) for q in dense)


@pytest.mark.parametrize(
    ("field", "value"),
    [("press_edge_margin", -0.01), ("max_rotation", 0.0), ("shortcut_attempts", -1),
     ("centroid_margin", math.nan), ("press_radius", 0.0), ("tip_edge_margin", -0.01)],
)  # fmt: skip
def test_new_slide_params_are_validated(field, value):
    with pytest.raises(ValueError, match=field):
        SlideParams(**{field: value})


def test_params_serialise_to_strict_json():
    text = json.dumps(SlideParams().as_dict(), allow_nan=False)
    assert json.loads(text)["max_rotation"] is None


def test_press_points_keep_off_the_edges_and_near_the_centroid():
    obj, table = get_object("L"), get_table("square")
    pose = (0.6, 0.0, 0.4)
    near = TopSlideProblem(
        obj, table, pose, SlideParams(press_edge_margin=0.008, press_radius=0.015)
    )
    every = TopSlideProblem(obj, table, pose)
    assert 0 < len(near.start_points) < len(every.start_points)
    placed = shapely.affinity.rotate(obj.polygon, pose[2], origin=(0, 0), use_radians=True)
    placed = shapely.affinity.translate(placed, pose[0], pose[1])
    inset = shapely.distance(placed.boundary, shapely.points(near.start_points[:, :2]))
    assert inset.min() >= 0.008 - 1e-9


def test_replanning_accepts_an_overhanging_plate_but_presses_over_the_table():
    obj, table = get_object("square"), get_table("square")
    hanging = (0.83, 0.0, 0.0)  # 3 cm over the x = 0.85 edge, centroid on the table
    with pytest.raises(ValueError, match="fully on the table"):
        TopSlideProblem(obj, table, hanging)
    problem = TopSlideProblem(obj, table, hanging, allow_overhang=True)
    assert shapely.contains_xy(table.polygon, *problem.start_points[:, :2].T).all()
    with pytest.raises(ValueError, match="centroid off the table"):
        TopSlideProblem(obj, table, (0.87, 0.0, 0.0), allow_overhang=True)


def test_plate_turn_limit_holds_in_solutions(solve_top_slide):
    params = SlideParams(max_rotation=0.3)
    result = solve_top_slide("square", "square", (0.62, 0.05, 0.3), params, "regions", 0)
    assert result.solved, result.reason
    turn = result.extra["object_goal_pose"][2] - 0.3
    assert abs((turn + math.pi) % (2 * math.pi) - math.pi) <= 0.3 + 1e-9


def test_tip_edge_margin_keeps_contacts_and_goals_inside_the_edge(solve_top_slide):
    obj, table = get_object("square"), get_table("square")
    pose = (0.62, 0.05, 0.3)
    problem = TopSlideProblem(obj, table, pose, SlideParams(tip_edge_margin=0.02))
    assert problem.contact_area.equals(table.polygon.buffer(-0.02))
    assert problem.goal_band.difference(problem.contact_area).area < 1e-12
    with pytest.raises(ValueError, match="tip_edge_margin"):
        TopSlideProblem(obj, table, pose, SlideParams(tip_edge_margin=1.0))
    result = solve_top_slide("square", "square", pose, SlideParams(tip_edge_margin=0.02))
    assert result.solved, result.reason
    tips = fingertip_chain().forward(np.asarray(result.path))
    inside = table.polygon.exterior.distance(shapely.points(tips[:, :2, 3]))
    assert inside.min() >= 0.02 - 1e-3  # the dense path's contacts, within the tolerance


def test_cbirrt_restarts_with_a_new_pair_after_its_period(plan_budget: float) -> None:
    """L on the square table, seed 9, goals from the paper's band C_g: the first validated
    pair needs 8 search iterations. With a period of 5, cbirrt leaves that pair and draws
    others; cbirrt-norestart keeps it."""
    from slide_gym.planning.runner import make_params, plan_once

    band = SlideParams(goal_sampling="band")
    kw = {"seed": 9, "time_budget": plan_budget, "params": band}
    kept = plan_once("L", "square", planner="cbirrt-norestart", **kw)
    assert kept["status"] == "solved" and kept["stats"]["restarts"] == 0
    assert kept["stats"]["iterations"] > 5
    params = make_params(restart_iterations=5, base=band)
    kw = {"seed": 9, "planner": "cbirrt", "time_budget": plan_budget, "params": params}
    restarted = plan_once("L", "square", **kw)
    assert restarted["stats"]["restarts"] >= 1
    assert restarted["parameters"]["restart_iterations"] == 5
    again = plan_once("L", "square", **kw)
    for key in ("status", "start_config", "goal_config", "path"):
        assert again[key] == restarted[key]
    assert again["stats"]["iterations"] == restarted["stats"]["iterations"]
