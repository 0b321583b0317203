"""The expert taking over a fingertip already pressed on the plate (what DAgger's labels need
mid-slide): slide on from the pressed arm, or lift off a plate that is already graspable.

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
