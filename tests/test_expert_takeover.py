"""The expert takes over from any state a learner can reach (what DAgger's labels need): a
fresh PlannerAgent handed the observation of a state in the middle of an expert episode (the
episode replayed exactly to that step) finishes the task from there."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import slide_gym  # noqa: F401 - registers the environments
from agents.planner_agent import PlannerAgent

pytestmark = pytest.mark.slow
GRASP = "SlideGym/TopSlideGrasp-v0"
SEED = 3


@pytest.fixture(scope="module")
def episode():
    """The expert's actions, infos and phases in the grasp env, square on square, seed 3."""
    env = gym.make(GRASP)
    obs, _ = env.reset(seed=SEED)
    agent = PlannerAgent("regions", 60.0, seed=SEED)
    actions, infos, phases, done = [], [], [], False
    while not done:
        action, _ = agent.predict(obs, episode_start=np.array([not actions]))
        obs, _, term, trunc, info = env.step(action)
        actions.append(action)
        infos.append(info)
        phases.append(agent.expert(0).phase)
        done = term or trunc
    agent.close()
    env.close()
    assert info["is_success"]
    return actions, infos, phases


def _finish(env: gym.Env, agent: PlannerAgent, obs: dict) -> dict:
    """Let ``agent`` act from ``obs`` (its first observation) to the episode's end; the last
    info."""
    n, done = 0, False
    while not done:
        action, _ = agent.predict(obs, episode_start=np.array([n == 0]))
        obs, _, term, trunc, info = env.step(action)
        n, done = n + 1, term or trunc
    return info


def _take_over(env_id: str, actions: list, k: int) -> tuple[dict, list[str], str | None]:
    """Replay ``k`` expert actions, then let a fresh expert finish; its last info, events and
    failure."""
    env = gym.make(env_id)
    try:
        obs, _ = env.reset(seed=SEED)
        for action in actions[:k]:
            obs, *_ = env.step(action)
        fresh = PlannerAgent("regions", 60.0, seed=SEED)
        info = _finish(env, fresh, obs)
        expert = fresh.expert(0)
        events, failure = list(expert.report.events), expert.report.gave_up
        fresh.close()
        return info, events, failure
    finally:
        env.close()


def _first(infos: list, phases: list, phase: str, test=lambda i: True) -> int:
    """Steps replayed to reach the first state of ``phase`` that passes ``test``."""
    pairs = enumerate(zip(infos, phases, strict=True))
    return next(t + 1 for t, (i, p) in pairs if p == phase and test(i))


def test_from_a_fingertip_pressed_on_the_plate(episode):
    actions, infos, phases = episode
    k = _first(infos, phases, "press", lambda i: i["touching_robot"]) + 5  # pressed in
    info, events, failure = _take_over(GRASP, actions, k)
    assert failure is None and info["is_success"]
    assert events[0] == "took over with the fingertip on the plate: raised it"


@pytest.mark.parametrize("env_id", ["SlideGym/TopSlide-v0", GRASP])
def test_from_a_plate_part_over_the_edge_not_yet_graspable(episode, env_id):
    actions, infos, phases = episode
    k = _first(infos, phases, "slide", lambda i: i["overhang_m"] > 0 and not i["graspable"])
    info, _, failure = _take_over(env_id, actions, k)
    assert failure is None and info["is_success"]


def test_from_a_graspable_plate_it_grasps_at_once(episode):
    actions, infos, phases = episode
    k = _first(infos, phases, "lift_off", lambda i: i["graspable"] and not i["touching_robot"])
    info, events, failure = _take_over(GRASP, actions, k)
    assert failure is None and info["is_success"]
    assert "took over with the plate graspable: grasping it" in events
    assert not any(e.startswith("slid:") for e in events)  # no new slide was planned


def test_from_the_plate_in_the_hand_it_lifts_and_holds(episode):
    actions, infos, phases = episode
    k = _first(infos, phases, "lift", lambda i: i["lift_m"] > 0.02)
    info, events, failure = _take_over(GRASP, actions, k)
    assert failure is None and info["is_success"]
    assert events[0].startswith("took over with the plate in the hand")


def test_from_another_arm_pose_within_the_limits():
    """A reset with the arm elsewhere (as a learner may leave it before touching anything)."""
    env = gym.make("SlideGym/TopSlide-v0")
    try:
        arm = [0.3, -0.6, 0.2, 1.9, -0.3, 0.4, 0.2]
        obs, _ = env.reset(seed=SEED, options={"arm_qpos": arm})
        agent = PlannerAgent("regions", 60.0, seed=SEED)
        info = _finish(env, agent, obs)
        assert agent.expert(0).report.gave_up is None and info["is_success"]
        agent.close()
    finally:
        env.close()
