"""The expert never executes a route its collision checker rejected: when neither the direct
approach nor the one via a raised pose is free, it plans a joint route (``plan_route``) or
fails with a reason."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import slide_gym  # noqa: F401 - registers the environments
from agents.expert import SlideGraspExpert
from agents.planner_agent import PlannerAgent
from slide_gym.planning.api import SlideParams, TopSlidePlanner, TopSlideProblem
from slide_gym.robot.model import READY_ARM_Q


@pytest.fixture
def blocked_straight_approaches(monkeypatch):
    """Every approach route the expert checks (full mode, plate placed) is reported blocked;
    the segments it queues are recorded, and so is each route ``plan_route`` returns."""
    real_route_free = TopSlidePlanner.route_free
    real_plan_route = TopSlidePlanner.plan_route
    seen = {"rejected": 0, "segments": [], "planned": []}

    def route_free(self, route, object_pose=None, resolution=0.02, mode="full"):
        if object_pose is not None and mode == "full":
            seen["rejected"] += 1
            return False
        return real_route_free(self, route, object_pose, resolution, mode)

    def plan_route(self, *args, **kwargs):
        route, why = real_plan_route(self, *args, **kwargs)
        seen["planned"].append((self, route, args, why))
        return route, why

    real_push = SlideGraspExpert._push

    def push(self, segment, chain, track=False):
        seen["segments"].append(segment)
        return real_push(self, segment, chain, track)

    monkeypatch.setattr(TopSlidePlanner, "route_free", route_free)
    monkeypatch.setattr(TopSlidePlanner, "plan_route", plan_route)
    monkeypatch.setattr(SlideGraspExpert, "_push", push)
    return seen, real_route_free


def _first_action(plan_budget: float):
    env = gym.make("SlideGym/TopSlideGrasp-v0", object="E", table="square")
    agent = PlannerAgent("regions", plan_budget, seed=0)
    obs, _ = env.reset(seed=0)
    action, _ = agent.predict(obs, episode_start=np.array([True]))
    expert = agent.expert(0)
    return env, agent, expert, action


def test_blocked_approach_takes_a_planned_collision_free_route(
    blocked_straight_approaches, plan_budget
):
    seen, real_route_free = blocked_straight_approaches
    env, agent, expert, _ = _first_action(plan_budget)
    try:
        assert expert.phase == "approach", expert.report.gave_up
        assert seen["rejected"] >= 2  # the direct and the raised routes were both refused
        assert any("planned route" in e for e in expert.report.events)
        ((planner, route, args, why),) = seen["planned"]
        assert route is not None, why
        pose = args[2]
        assert real_route_free(planner, route, pose)  # free by the real checker
        approach = [s for s in seen["segments"] if s.name == "approach"]
        assert len(approach) == 1
        np.testing.assert_array_equal(approach[0].waypoints, route)
    finally:
        agent.close()
        env.close()


def test_no_free_approach_fails_with_a_reason(blocked_straight_approaches, monkeypatch):
    seen, _ = blocked_straight_approaches
    monkeypatch.setattr(
        TopSlidePlanner, "plan_route", lambda self, *a, **k: (None, "stub: no route")
    )
    env, agent, expert, action = _first_action(60.0)
    try:
        assert expert.phase == "failed"
        assert "no collision-free approach" in expert.report.gave_up
        assert "stub: no route" in expert.report.gave_up
        assert not [s for s in seen["segments"] if s.name == "approach"]
        assert np.all(action[:7] == 0.0)  # the arm holds still
    finally:
        agent.close()
        env.close()


def test_plan_route_finds_a_free_route_or_says_why():
    problem = TopSlideProblem("E", "square", (0.6, 0.0, 0.3), SlideParams())
    with TopSlidePlanner(problem, "regions", seed=0) as planner:
        goal = READY_ARM_Q + np.array([0.6, 0.2, 0.0, -0.3, 0.0, 0.3, 0.0])
        route, why = planner.plan_route(READY_ARM_Q, goal, (0.6, 0.0, 0.3), max_iterations=200)
        assert why is None and route is not None
        np.testing.assert_array_equal(route[0], READY_ARM_Q)
        np.testing.assert_array_equal(route[-1], goal)
        assert planner.route_free(route, (0.6, 0.0, 0.3))
        again, _ = planner.plan_route(READY_ARM_Q, goal, (0.6, 0.0, 0.3), max_iterations=200)
        assert again is not None
        inside = READY_ARM_Q.copy()
        inside[1] = 1.9  # shoulder pitched forward: the hand is deep in the table
        assert planner.checker.collides(inside, "full")
        none, why = planner.plan_route(READY_ARM_Q, inside, None, max_iterations=50)
        assert none is None and "in collision" in why
        with pytest.raises(ValueError, match="time_budget"):
            planner.plan_route(READY_ARM_Q, goal, None, time_budget=0.0)
