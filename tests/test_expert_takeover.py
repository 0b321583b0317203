"""The expert takes over from any state a learner can reach (what DAgger's labels need): a
fresh PlannerAgent handed the observation of a state in the middle of an expert episode (the
episode replayed exactly to that step) finishes the task from there."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import shapely
from shapely.ops import nearest_points

import slide_gym  # noqa: F401 - registers the environments
from agents.params import ExpertParams
from agents.planner_agent import PlannerAgent
from agents.record import ExpertReport
from slide_gym.planning.ik import IKTarget, solve_ik
from slide_gym.robot.kinematics import fingertip_chain

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


SLID_ON = "took over with the fingertip on the plate: slid on"


def _mid_slide(infos: list, phases: list, which: str) -> int:
    """Steps replayed to a state mid-slide (the fingertip pressed, the plate not graspable):
    ``"early"`` 8 steps into the slide, ``"over"`` the first with the plate part over the
    edge."""
    if which == "early":
        k = _first(infos, phases, "slide") + 8
    else:
        k = _first(infos, phases, "slide", lambda i: i["overhang_m"] > 0 and not i["graspable"])
    assert phases[k - 1] == phases[k] == "slide" and not infos[k - 1]["graspable"]
    return k


def test_from_a_fingertip_still_pressing_down_it_presses_and_slides_on(episode):
    """Just touched, the fingertip is still above the contact band (by more than the
    planner's start tolerance, less than the re-seat tolerance): the slide's first leg
    presses it into the band, and the slide goes on from there."""
    actions, infos, phases = episode
    k = _first(infos, phases, "press", lambda i: i["touching_robot"]) + 5
    info, events, failure = _take_over(GRASP, actions, k)
    assert failure is None and info["is_success"]
    assert events[0] == SLID_ON


@pytest.mark.parametrize("env_id", ["SlideGym/TopSlide-v0", GRASP])
@pytest.mark.parametrize("which", ["early", "over"])
def test_mid_slide_it_slides_on(episode, env_id, which):
    actions, infos, phases = episode
    info, events, failure = _take_over(env_id, actions, _mid_slide(infos, phases, which))
    assert failure is None and info["is_success"], events
    assert events[0] == SLID_ON
    assert not any("raised" in e for e in events)


def _first_actions(
    obs: dict, n: int = 40, params: ExpertParams | None = None
) -> tuple[np.ndarray, list[str]]:
    """A fresh expert's first ``n`` actions for the same observation (no env: its plan and
    open-loop targets only), and its events."""
    agent = PlannerAgent("regions", 60.0, seed=SEED, params=params)
    try:
        acts = [agent.predict(obs, episode_start=np.array([t == 0]))[0] for t in range(n)]
        return np.stack(acts), list(agent.expert(0).report.events)
    finally:
        agent.close()


def _state(actions: list, k: int) -> dict:
    """The grasp env's observation after ``k`` of the expert's actions."""
    env = gym.make(GRASP)
    try:
        obs, _ = env.reset(seed=SEED)
        for action in actions[:k]:
            obs, *_ = env.step(action)
        return obs
    finally:
        env.close()


def test_slide_on_is_deterministic(episode):
    actions, infos, phases = episode
    obs = _state(actions, _mid_slide(infos, phases, "over"))
    (a, events), (b, _) = _first_actions(obs), _first_actions(obs)
    assert events == [SLID_ON]
    np.testing.assert_array_equal(a, b)


def _tilted(obs: dict) -> dict:
    """``obs`` with the wrist tilted 0.4 rad away from the sliding constraints."""
    tilt = np.array([0, 0, 0, 0, 0, 0.4, 0], dtype=np.float32)
    return {**obs, "arm_qpos": obs["arm_qpos"] + tilt}


def test_pressed_off_the_manifold_it_slides_straight_on(episode):
    """An arm whose wrist is tilted away from the sliding constraints cannot start a planned
    slide; with the plate part over the edge, the fingertip drags it straight on instead."""
    actions, infos, phases = episode
    obs = _tilted(_state(actions, _mid_slide(infos, phases, "over")))
    _, events = _first_actions(obs, 1)
    assert events[0] == "took over with the fingertip on the plate: slid straight on"
    assert events[1].startswith("no planned slide on (") and "start configuration" in events[1]


def test_pressed_where_no_slide_on_is_found_it_raises(episode):
    """Early in the slide the tilted wrist's straight drag would hit the table: it rises."""
    actions, infos, phases = episode
    obs = _tilted(_state(actions, _mid_slide(infos, phases, "early")))
    _, events = _first_actions(obs, 1)
    assert events[0].startswith("no slide on from here (")
    assert "straight slide on (the straight drag would collide)" in events[0]
    assert events[-1] == "took over with the fingertip on the plate: raised it"


def test_straight_slide_on_first_when_asked(episode):
    """``straight_slide_on``: the straight drag comes first (no planned slide is tried), the
    same for the same state."""
    actions, infos, phases = episode
    obs = _state(actions, _mid_slide(infos, phases, "over"))
    params = ExpertParams(straight_slide_on=True)
    a, events = _first_actions(obs, 40, params)
    assert events == ["took over with the fingertip on the plate: slid straight on"]
    b, _ = _first_actions(obs, 40, params)
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("which", ["early", "over"])
def test_without_a_planned_slide_on_the_straight_one_succeeds(episode, which, monkeypatch):
    """The straight slide on alone (the planner's slide on refused) finishes the slide."""
    monkeypatch.setattr("agents.expert.slide_on", lambda expert, obs: "refused by the test")
    actions, infos, phases = episode
    k = _mid_slide(infos, phases, which)
    info, events, failure = _take_over("SlideGym/TopSlide-v0", actions, k)
    assert failure is None and info["is_success"], events
    assert events[:2] == [
        "took over with the fingertip on the plate: slid straight on",
        "no planned slide on (refused by the test)",
    ]


def _from_the_fingertip_at(episode, where) -> tuple[dict, ExpertReport]:
    """Reset with the arm in the press pose moved to put the fingertip at ``where(obs, tip)``
    (as a learner leaves it); a fresh expert's last info and report."""
    actions, _, phases = episode
    press = _state(actions, phases.index("press"))
    chain = fingertip_chain()
    q_press = np.asarray(press["arm_qpos"], dtype=float)
    tip = chain.forward(q_press[None])[0]
    target = IKTarget(where(press, tip[:3, 3]), tip[:3, :3])
    arm = solve_ik(chain, target, np.random.default_rng(0), q_press[None])
    assert arm is not None
    env = gym.make(GRASP)
    try:
        obs, _ = env.reset(seed=SEED, options={"arm_qpos": arm.tolist()})
        agent = PlannerAgent("regions", 60.0, seed=SEED)
        info = _finish(env, agent, obs)
        report = agent.expert(0).report
        agent.close()
        return info, report
    finally:
        env.close()


LOW = "took over with the fingertip low over the table: planning"


def test_low_beside_the_plate_it_approaches_from_there(episode):
    """1.5 cm over the table, 2.5 cm beside the plate (a learner that missed it): no raise
    first, the approach goes from there, and the plate is lifted."""

    def beside(obs: dict, tip: np.ndarray) -> np.ndarray:
        return np.array([tip[0], tip[1] + 0.075, float(obs["table_height"][0]) + 0.015])

    info, report = _from_the_fingertip_at(episode, beside)
    assert report.gave_up is None and info["is_success"], report.events
    assert report.events[0] == LOW
    assert not any("raise" in e or "approach via" in e for e in report.events)


def test_low_past_the_table_edge_it_rises_where_no_approach_is_found(episode):
    """3 cm below the table top, 3 cm past its edge (a learner that followed the plate over
    it): no approach from there, so the fingertip rises first, and the plate is lifted."""

    def below(obs: dict, tip: np.ndarray) -> np.ndarray:
        table = shapely.Polygon(np.asarray(obs["table_outline"]).reshape(-1, 2))
        plate = shapely.Point(obs["object_pose"][:2])
        edge = np.asarray(nearest_points(table.exterior, plate)[0].coords[0])
        out = (edge - obs["object_pose"][:2]) / np.linalg.norm(edge - obs["object_pose"][:2])
        return np.array([*(edge + 0.03 * out), float(obs["table_height"][0]) - 0.03])

    info, report = _from_the_fingertip_at(episode, below)
    assert report.gave_up is None and info["is_success"], report.events
    assert report.events[0] == LOW
    assert report.events[1].startswith("no collision-free approach")
    assert report.events[1].endswith(": raised the fingertip")


def test_pressed_on_a_graspable_plate_it_lifts_off_and_grasps(episode):
    actions, infos, phases = episode
    k = _first(infos, phases, "slide", lambda i: i["graspable"]) + 4
    info, events, failure = _take_over(GRASP, actions, k)
    assert failure is None and info["is_success"]
    assert events[0] == "took over with the fingertip on the plate: lifted it off"
    assert events[1].startswith("lifted off: overhang")  # as it lay, no new slide


def test_from_a_graspable_plate_it_grasps_at_once(episode):
    actions, infos, phases = episode
    k = _first(infos, phases, "transfer") - 1  # lifted off, the fingertip up
    assert phases[k - 1] == "lift_off" and infos[k - 1]["graspable"]
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
