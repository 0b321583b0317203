"""Same seed, same plan and same episode on any machine: nothing but giving up depends on the
clock. Each case runs twice, once with ``time.perf_counter`` running 20 times fast (as if the
machine were 20 times slower), under a budget that the slow run does not use up."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import slide_gym  # noqa: F401 - registers the environments
from agents.planner_agent import PlannerAgent
from slide_gym.geometry import get_object, get_table
from slide_gym.planning.api import SlideParams, TopSlidePlanner, TopSlideProblem
from slide_gym.planning.result import OutOfTime, PlanStatus, SearchParams
from slide_gym.planning.runner import seeded_generators
from slide_gym.planning.search import SearchFunctions
from slide_gym.planning.smoothing import shortcut_path
from slide_gym.task import TaskParams, sample_start_pose

SLOWDOWN = 20.0
BUDGET = 1e6
"""Seconds of the (slowed) clock: far beyond anything these cases use even on a loaded
machine (they plan in well under a second of real time), so neither run ever gives up."""


def _plan(seed: int):
    """The ``slide-gym bench plan`` query for the circle on the square table, ``seed``: its
    pair validation needs the fallback transfer planner for seed 0."""
    shape, table = get_object("circle"), get_table("square")
    pose_rng, plan_rng = seeded_generators(seed)
    pose = sample_start_pose(shape, table, pose_rng, TaskParams().start_margin)
    problem = TopSlideProblem(shape, table, pose, SlideParams(dz=(0.005, 0.025)))
    with TopSlidePlanner(problem, "regions", plan_rng) as planner:
        return planner.solve(BUDGET)


def test_plan_is_the_same_with_a_slow_clock(slow_clock):
    fast = _plan(0)
    assert fast.solved, fast.reason
    assert fast.extra["validator_counts"]["fallback"] >= 1  # the formerly time-capped part ran
    slow_clock(SLOWDOWN)
    slow = _plan(0)
    assert slow.solved, slow.reason
    np.testing.assert_array_equal(slow.path, fast.path)
    assert slow.stats.counts() == fast.stats.counts()
    assert slow.extra["validator_counts"] == fast.extra["validator_counts"]
    for key in ("object_goal_pose", "grasp_config", "transfer_path", "region_draws"):
        assert slow.extra[key] == fast.extra[key], key


def _episode(obj: str, table: str, seed: int) -> tuple[np.ndarray, list[float], list[str]]:
    env = gym.make("SlideGym/TopSlideGrasp-v0", object=obj, table=table)
    agent = PlannerAgent("regions", BUDGET, seed=seed)
    actions = []
    try:
        obs, info = env.reset(seed=seed)
        done, k = False, 0
        while not done:
            action, _ = agent.predict(obs, episode_start=np.array([k == 0]))
            actions.append(action)
            obs, _, terminated, truncated, info = env.step(action)
            done, k = terminated or truncated, k + 1
        expert = agent.expert(0)
        assert expert is not None
        events = list(expert.report.events)
    finally:
        agent.close()
        env.close()
    return np.array(actions), list(info["object_pose_2d"]), events


@pytest.mark.slow
def test_expert_episode_is_the_same_with_a_slow_clock(slow_clock):
    # The circle, seed 1: its plan's pair validation uses the fallback transfer planner and
    # the slid plate is pulled back and re-aimed at; under the former wall-clock caps a
    # 20-times slower clock turned this lifted plate into three failed replans.
    actions, final, events = _episode("circle", "square", 1)
    slow_clock(SLOWDOWN)
    slow_actions, slow_final, slow_events = _episode("circle", "square", 1)
    assert slow_events == events
    np.testing.assert_array_equal(slow_actions, actions)
    assert slow_final == final


def _free_line() -> SearchFunctions:
    return SearchFunctions(
        sample_config=lambda rng: rng.uniform(-1.0, 1.0, 2),
        project=lambda q, near: q,
        collides=lambda q: False,
    )


def test_shortcuts_give_up_at_the_deadline_rather_than_stop_early():
    zigzag = np.array([[0.0, 0.0], [0.5, 0.4], [1.0, 0.0], [1.5, 0.4], [2.0, 0.0]])
    params = SearchParams(step_size=0.1)
    rng = np.random.default_rng(0)
    with pytest.raises(OutOfTime):
        shortcut_path(zigzag, _free_line(), params, rng, attempts=10, deadline=-math.inf)
    out = shortcut_path(zigzag, _free_line(), params, np.random.default_rng(0), attempts=10)
    assert out[0].tolist() == zigzag[0].tolist() and out[-1].tolist() == zigzag[-1].tolist()


def test_iteration_capped_plan_stops_at_the_cap_with_its_own_status():
    shape, table = get_object("square"), get_table("square")
    params = SlideParams(max_iterations=1, max_rotation=1e-12)  # no pair can ever be valid
    problem = TopSlideProblem(shape, table, (0.6, 0.0, 0.0), params)
    with TopSlidePlanner(problem, "regions", seed=0) as planner:
        res = planner.solve_until(math.inf)
    assert res.status is PlanStatus.ITERATION_LIMIT and "iteration limit" in res.reason
    assert res.stats.iterations == 1 and res.path is None
    assert res.extra["parameters"]["max_iterations"] == 1
    with pytest.raises(ValueError, match="max_iterations"):
        SlideParams(max_iterations=0)
