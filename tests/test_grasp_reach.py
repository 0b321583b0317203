"""Where a side grasp is reachable along a table's outline (slide_gym.planning.grasp_reach)."""

from __future__ import annotations

import numpy as np
import shapely

from slide_gym.geometry import get_table, overhang, transform_polygon
from slide_gym.planning.api import TopSlideProblem
from slide_gym.planning.grasp_reach import _stretches, nearest_stretches, reachable_stretches
from slide_gym.planning.params import SlideParams
from slide_gym.planning.plate_goals import PlateGoalPoses
from slide_gym.task import scene_object

TRIANGLE = get_table("triangle")  # corners (0.35, -0.32), (0.35, 0.32), (0.85, 0)


def test_triangle_table_is_graspable_only_at_the_ends_of_its_near_edge() -> None:
    stretches = reachable_stretches(TRIANGLE.polygon, TRIANGLE.height + 0.001, 0.005)
    assert stretches, "the near edge's ends are reachable"
    for p, q, n in stretches:
        # the slanted edges would need the hand to point back at the robot: none kept
        np.testing.assert_allclose(n, [-1.0, 0.0], atol=1e-9)
        assert p[0] == q[0] == 0.35
        # the middle of the near edge is too close to the arm's base
        assert min(abs(p[1]), abs(q[1])) > 0.08
    lengths = [np.linalg.norm(q - p) for p, q, _ in stretches]
    assert 0.1 < sum(lengths) < 0.4


def test_the_reach_map_is_the_same_on_every_computation() -> None:
    table = get_table("square").polygon
    moved = shapely.affinity.translate(table, 0.01)  # a new outline: computed afresh
    first = reachable_stretches(moved, 0.001, 0.005)
    _stretches.cache_clear()  # computed again, not read back from the cache
    again = reachable_stretches(moved, 0.001, 0.005)
    assert len(first) == len(again) > 0
    for a, b in zip(first, again, strict=True):
        for x, y in zip(a, b, strict=True):
            np.testing.assert_array_equal(x, y)


def test_plate_goals_aim_only_at_reachable_stretches() -> None:
    plate = scene_object("square", TRIANGLE, scale=0.5)
    problem = TopSlideProblem(plate, TRIANGLE, [0.5, 0.0, 0.0])
    p = problem.params
    poses = PlateGoalPoses(
        plate.polygon,
        TRIANGLE.polygon,
        problem.goal_band,
        p.u_star,
        p.centroid_margin,
        stretches=problem.grasp_stretches,
    )
    rng = np.random.default_rng(0)
    drawn = [poses.sample(rng) for _ in range(200)]
    kept = [pose for pose in drawn if pose is not None]
    assert len(kept) > 50
    for pose in kept:
        ov = overhang(transform_polygon(plate.polygon, *pose), TRIANGLE.polygon)
        assert ov.u >= p.u_star
        (x0, _), (x1, _) = np.asarray(ov.edge)
        assert x0 == x1 == 0.35, "the plate overhangs the near edge, where grasps reach"


def test_nearest_goal_edge_keeps_the_reachable_corner_on_the_plates_side() -> None:
    """The square table's side grasps reach two corners near the robot (each an edge stretch
    and a piece of the near edge); ``goal_edge="nearest"`` keeps the one on the plate's side,
    so goal poses and the goal band lie there alone."""
    square = get_table("square")
    every = reachable_stretches(square.polygon, square.height + 0.001, 0.005)
    assert len(every) == 4
    for y in (0.1, -0.1, 0.01):
        kept = nearest_stretches(every, np.array([0.6, y]))
        assert len(kept) == 2, "one corner: the side edge's stretch and the near edge's"
        assert all(np.sign(p[1]) == np.sign(q[1]) == np.sign(y) for p, q, _ in kept)
        problem = TopSlideProblem(
            "square", "square", [0.6, y, 0.3], SlideParams(goal_edge="nearest")
        )
        xmin, ymin, xmax, ymax = problem.goal_band.bounds
        assert (ymin > 0.0) if y > 0 else (ymax < 0.0)
    assert nearest_stretches([], np.zeros(2)) == []
    default = TopSlideProblem("square", "square", [0.6, 0.1, 0.3])
    assert len(default.grasp_stretches) == 4, "the paper's default: every reachable stretch"
