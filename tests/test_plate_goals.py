"""Goal roots that know the plate's size (slide_gym.planning.plate_goals)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import shapely

from slide_gym.geometry import (
    get_table,
    overhang,
    transform_points,
    transform_polygon,
    wrap_angle,
)
from slide_gym.planning.api import SlideParams, TopSlidePlanner, TopSlideProblem, goal_band
from slide_gym.planning.plate_goals import PlateGoalPoses
from slide_gym.task import scene_object

TABLE = get_table("square")
U_STAR = SlideParams().u_star
HALF_SQUARE = scene_object("square", TABLE, scale=0.5)


def poses_for(plate: shapely.Polygon, margin: float = 0.0) -> PlateGoalPoses:
    band = goal_band(TABLE.polygon, 0.05, TABLE.height + 0.001)
    return PlateGoalPoses(plate, TABLE.polygon, band, U_STAR, margin)


def draws(sampler: PlateGoalPoses, seed: int, n: int, **kw) -> list[np.ndarray | None]:
    rng = np.random.default_rng(seed)
    return [sampler.sample(rng, **kw) for _ in range(n)]


@pytest.mark.parametrize("margin", [0.0, 0.004])
def test_small_plate_goal_poses_overhang_u_star_with_the_centroid_on_the_table(margin):
    plate = HALF_SQUARE.polygon
    reach = max(np.linalg.norm(shapely.get_coordinates(plate), axis=1))
    assert reach < 2 * U_STAR  # small: u* is most of its reach past the centroid
    got = [p for p in draws(poses_for(plate, margin), 0, 200) if p is not None]
    assert len(got) >= 150
    for pose in got:
        placed = transform_polygon(plate, *pose)
        ov = overhang(placed, TABLE.polygon)
        assert ov.u >= U_STAR and ov.centroid_inside
        assert TABLE.polygon.exterior.distance(placed.centroid) >= margin
    # The plate's far corners face the edge: the centroid is at most reach - u* inside.
    inside = [TABLE.polygon.exterior.distance(transform_polygon(plate, *p).centroid) for p in got]
    assert max(inside) <= reach - U_STAR + 1e-9


def test_goal_poses_respect_the_rotation_limit_and_are_deterministic():
    sampler = poses_for(HALF_SQUARE.polygon)
    a = draws(sampler, 7, 60, start_yaw=0.5, max_rotation=0.3)
    b = draws(sampler, 7, 60, start_yaw=0.5, max_rotation=0.3)
    assert all((p is None and q is None) or np.array_equal(p, q) for p, q in zip(a, b, strict=True))
    got = [p for p in a if p is not None]
    assert len(got) >= 20
    assert all(abs(wrap_angle(p[2] - 0.5)) <= 0.3 + 1e-9 for p in got)
    assert any(not np.array_equal(p, q) for p, q in zip(got[:-1], got[1:], strict=True))


def test_goal_poses_keep_the_start_contact_inside_the_edge():
    """A contact on the plate's outer half would lie past the edge for most directions: the
    draw keeps it ``contact_margin`` inside (where the fingertip may press)."""
    plate = scene_object("circle", TABLE, scale=0.5).polygon
    band = goal_band(TABLE.polygon, 0.05, TABLE.height + 0.001)
    margin = 0.01
    sampler = PlateGoalPoses(plate, TABLE.polygon, band, 0.0195, 0.005, contact_margin=margin)
    contact = np.array([0.012, 0.004])
    got = [p for p in draws(sampler, 0, 100, contact=contact) if p is not None]
    assert len(got) >= 80
    for pose in got:
        (point,) = transform_points(contact[None], *pose)
        assert TABLE.polygon.contains(shapely.Point(point))
        assert TABLE.polygon.exterior.distance(shapely.Point(point)) >= margin - 1e-9
        assert overhang(transform_polygon(plate, *pose), TABLE.polygon).u >= 0.0195
    # without the contact, many draws put it past the edge or within the margin
    free = [p for p in draws(sampler, 0, 100) if p is not None]
    near = [
        TABLE.polygon.exterior.distance(shapely.Point(transform_points(contact[None], *p)[0]))
        < margin
        or not TABLE.polygon.contains(shapely.Point(transform_points(contact[None], *p)[0]))
        for p in free
    ]
    assert sum(near) >= 0.3 * len(free)


def test_a_plate_that_cannot_reach_u_star_past_its_centroid_gets_no_goal_pose():
    tiny = shapely.box(-0.015, -0.015, 0.015, 0.015)  # reaches 21 mm at a corner
    assert all(p is None for p in draws(poses_for(tiny, margin=0.002), 0, 30))


def slid_overhangs(params: SlideParams, n: int) -> tuple[int, int]:
    """Goal roots drawn for the latest start root of a half-scale square, and how many of
    them slide the plate to u* of overhang with its centroid on the table (Eq. 2)."""
    problem = TopSlideProblem(HALF_SQUARE, TABLE, (0.6, 0.05, 0.4), params)
    rng = np.random.default_rng(3)
    with TopSlidePlanner(problem, seed=3) as planner:
        q_s = None
        while q_s is None:
            q_s = planner.start_region.sample(rng)
        goals = [planner.goal_region.sample(rng) for _ in range(n)]
        goals = [q for q in goals if q is not None]
        ok = 0
        for q_g in goals:
            pose = planner.validator.object_goal(q_s, q_g)
            placed = transform_polygon(HALF_SQUARE.polygon, *pose)
            ok += overhang(placed, TABLE.polygon).graspable(params.u_star)
    return len(goals), ok


def test_plate_goal_roots_slide_a_small_plate_to_an_overhang_and_band_roots_seldom_do():
    n_plate, ok_plate = slid_overhangs(SlideParams(), 30)
    n_band, ok_band = slid_overhangs(dataclasses.replace(SlideParams(), goal_sampling="band"), 30)
    assert n_plate >= 10 and ok_plate == n_plate  # every root of the region, by Eq. 2
    assert n_band >= 10 and ok_band <= 0.5 * n_band


def test_goal_sampling_is_checked():
    with pytest.raises(ValueError, match="goal_sampling must be one of plate, band"):
        SlideParams(goal_sampling="edge")
