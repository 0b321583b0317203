"""The expert taking over a fingertip already pressed on the plate (what DAgger's labels need
mid-slide): slide on from the pressed arm, or lift off a plate that is already graspable.

A slide on is planned first (:func:`slide_on`); where the planner finds none from the
pressed arm, the fingertip drags the plate along a straight line toward the table edge that
needs the shortest drag (:func:`slide_straight_on`): a learner pressed on a plate is most
often sliding it toward that edge already, and raising the fingertip to start over undoes
its progress.

Both start from the commanded arm with the contact tracker's correction restored
(:meth:`agents.tracking.ContactTracker.adopt`): the plan's fingertip is the measured one, and
the first tracked target is the command itself, so nothing jumps. What follows (pull back,
lift off, the pose check, grasp or replan) is what follows a planned slide.
"""

from __future__ import annotations

import dataclasses
import time
from typing import TYPE_CHECKING

import numpy as np
import shapely

from agents.tracking import cartesian_line
from slide_gym.geometry import overhang, transform_polygon
from slide_gym.planning.api import TopSlidePlanner, TopSlideProblem
from slide_gym.planning.result import PlanStatus

if TYPE_CHECKING:
    from agents.expert import SlideGraspExpert

SLIDE_ON_SEED = 11
"""Mixed into the seed of a slide-on plan (its numbers differ from a first plan's)."""
RESEAT_TOLERANCE = (0.03, 0.3)
"""(m, rad): a pressed arm off the contact manifold by at most this much (a learner's
fingertip rolled or pitched away from the planner's) is re-seated onto it by the slide's first
leg; farther off, the expert raises the fingertip instead."""

STRAIGHT_OVERSHOOT = 0.01
"""m: a straight slide on aims this far past the overhang it needs (``stop_overhang`` or the
grasp threshold); with ``stop_overhang`` set, the measured overhang ends it there."""
TIP_ON_TABLE = 0.01
"""m: where a straight slide on ends, the fingertip must lie this far inside the table edge
(pressing the overhanging part would tip the plate)."""


def _seed_key(expert: SlideGraspExpert, pose: np.ndarray, k: int) -> list[int]:
    key = [expert.seed, SLIDE_ON_SEED, k]
    return key + list(np.round(pose * 1e4).astype(np.int64) % 2**32)


def slide_on(expert: SlideGraspExpert, obs: dict[str, np.ndarray]) -> str | None:
    """Plan a slide from the pressed arm (the planner's fixed start) and queue only the slide;
    None if queued, else why not (nothing queued). Each attempt (strict margins, then relaxed)
    runs at most ``ExpertParams.strict_plan_iterations`` search iterations."""
    assert expert.obj is not None and expert.table is not None and expert.q_cmd is not None
    if expert.planner_name != "regions":
        return f"a fixed start needs the regions planner, not {expert.planner_name!r}"
    pose = expert._object_pose(obs)
    q_start = expert.tracker.adopt(expert.q_cmd, obs)
    why = "no plan"
    for k, (name, params) in enumerate(expert._slide_params()):
        budget = expert._budget_left()
        if budget <= 0.05:
            return "planning budget used up"
        params = dataclasses.replace(params, max_iterations=expert.params.strict_plan_iterations)
        try:
            problem = TopSlideProblem(expert.obj, expert.table, pose, params, allow_overhang=True)
        except ValueError as exc:
            return f"cannot plan from the object's pose: {exc}"
        rng = np.random.default_rng(np.random.SeedSequence(_seed_key(expert, pose, k)))
        planner = TopSlidePlanner(
            problem, "regions", rng, start_config=q_start, start_tolerance=RESEAT_TOLERANCE
        )
        t0 = time.perf_counter()
        result = planner.solve(budget)
        expert.report.planning_time_s += time.perf_counter() - t0
        if result.solved:
            expert.use_plan(planner, result, pose)
            path = result.path
            if np.abs(result.start_config - q_start).max() > 1e-6:
                path = np.vstack([q_start, path])  # the first leg re-seats the fingertip
            expert.queue_slide(q_start, path, pose)
            return None
        planner.close()
        why = f"{name} plan: {result.status.value}: {result.reason}"
        if result.status is PlanStatus.TIMEOUT:
            break
    return why


def lift_off_pressed(expert: SlideGraspExpert, obs: dict[str, np.ndarray]) -> str | None:
    """A plate already graspable under a pressed fingertip: pull back (if its centroid is at
    the edge) and lift off as after a slide, then grasp it as it lies (or replan). None if
    queued, else why not."""
    assert expert.obj is not None and expert.table is not None and expert.q_cmd is not None
    pose = expert._object_pose(obs)
    try:
        params = expert._slide_params()[0][1]
        problem = TopSlideProblem(expert.obj, expert.table, pose, params, allow_overhang=True)
    except ValueError as exc:
        return f"cannot plan from the object's pose: {exc}"
    q_now = expert.tracker.adopt(expert.q_cmd, obs)
    rng = np.random.default_rng(np.random.SeedSequence(_seed_key(expert, pose, 7)))
    if expert.planner is not None:
        expert.planner.close()
    expert.planner = TopSlidePlanner(problem, expert.planner_name, rng)
    expert.predicted, expert.grasp_seed = pose, None  # nothing planned: it lies where it lies
    expert.q_slide_end = q_now
    expert._pull_back_or_lift_off(obs)
    return None


def straight_drag(
    plate: shapely.Polygon,
    table: shapely.Polygon,
    tip_xy: np.ndarray,
    target_u: float,
    centroid_margin: float,
) -> np.ndarray | None:
    """The shortest planar drag ``(dx, dy)`` along a table edge's outward normal that leaves
    ``plate`` overhanging by ``target_u`` with its centroid ``centroid_margin`` inside the
    table and the fingertip at ``tip_xy`` (moved with it) :data:`TIP_ON_TABLE` inside; None
    if no edge allows one.

    Along an edge's normal ``n`` the overhang past that edge grows exactly as the drag, so
    each edge's drag is ``target_u`` minus how far the plate already sticks out past it."""
    coords = shapely.get_coordinates(table.exterior)
    plate_xy = shapely.get_coordinates(plate.exterior)
    inner = table.buffer(-centroid_margin)
    tip_inner = table.buffer(-TIP_ON_TABLE)
    best: np.ndarray | None = None
    for a, b in zip(coords[:-1], coords[1:], strict=True):
        length = float(np.hypot(*(b - a)))
        if length < 1e-9:
            continue
        normal = np.array([b[1] - a[1], a[0] - b[0]]) / length  # outward: CCW exterior ring
        drag = target_u - float(((plate_xy - a) @ normal).max())
        if drag <= 0.0 or (best is not None and drag >= float(np.linalg.norm(best))):
            continue
        shift = drag * normal
        moved = shapely.affinity.translate(plate, *shift)
        if not overhang(moved, table).u >= target_u - 1e-4:
            continue
        if not inner.contains(moved.centroid):
            continue
        if not tip_inner.contains(shapely.Point(*(np.asarray(tip_xy) + shift))):
            continue
        best = shift
    return best


def slide_straight_on(expert: SlideGraspExpert, obs: dict[str, np.ndarray]) -> str | None:
    """Queue a straight slide from the pressed arm (:func:`straight_drag`), orientation kept;
    None if queued, else why not (nothing queued). What follows a slide follows."""
    assert expert.obj is not None and expert.table is not None and expert.q_cmd is not None
    pose = expert._object_pose(obs)
    placed = transform_polygon(expert.obj.polygon, *pose)
    stop = expert.params.stop_overhang
    target_u = max(stop or 0.0, expert.grasp_u_star) + STRAIGHT_OVERSHOOT
    tip_xy = np.asarray(obs["fingertip_pose"][:2], dtype=float)
    shift = straight_drag(placed, expert.table.polygon, tip_xy, target_u, expert.centroid_margin)
    if shift is None:
        return f"no straight drag to {target_u:.3f} m of overhang keeps the plate on the table"
    try:
        params = expert._slide_params()[0][1]
        problem = TopSlideProblem(expert.obj, expert.table, pose, params, allow_overhang=True)
    except ValueError as exc:
        return f"cannot plan from the object's pose: {exc}"
    q_start = expert.tracker.adopt(expert.q_cmd, obs)
    line = cartesian_line(expert.tip, q_start, np.r_[shift, 0.0], expert.rng)
    if line is None:
        return "the straight drag leaves the arm's reachable set"
    rng = np.random.default_rng(np.random.SeedSequence(_seed_key(expert, pose, 9)))
    planner = TopSlidePlanner(problem, expert.planner_name, rng)
    if not planner.route_free(line, None, mode="sliding"):
        planner.close()
        return "the straight drag would collide"
    if expert.planner is not None:
        expert.planner.close()
    expert.planner, expert.object_start = planner, pose
    expert.predicted = np.r_[pose[:2] + shift, pose[2]]
    expert.grasp_seed = None
    expert.queue_slide(q_start, line, pose)
    return None
