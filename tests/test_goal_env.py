"""The goal-conditioned slide ``SlideGym/TopSlideGoal-v0``: spaces, goals, reward, and HER."""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest

import slide_gym
from slide_gym.envs.goal import TopSlideGoalEnv, goal_vector
from slide_gym.geometry import get_object, get_table, overhang, transform_polygon
from slide_gym.task import REACH_MAX, REACH_MIN, TaskParams

GOAL_ID = "SlideGym/TopSlideGoal-v0"


@pytest.fixture
def env():
    e = TopSlideGoalEnv()
    yield e
    e.close()


def test_registered_with_the_slide_time_limit() -> None:
    assert GOAL_ID in slide_gym.ENV_IDS
    assert gym.registry[GOAL_ID].max_episode_steps == 800


def test_spaces_and_sb3_check_env(env: TopSlideGoalEnv) -> None:
    check_env = pytest.importorskip("stable_baselines3.common.env_checker").check_env
    obs, info = env.reset(seed=0)
    assert set(obs) == {"observation", "achieved_goal", "desired_goal"}
    assert env.observation_space.contains(obs)
    assert obs["achieved_goal"].shape == obs["desired_goal"].shape == (4,)
    assert type(info["is_success"]) is bool and not info["is_success"]
    for _ in range(5):
        obs, reward, _, _, info = env.step(env.action_space.sample())
        assert env.observation_space.contains(obs)
        assert reward == -1.0 and info["reward_terms"] == {"goal": -1.0}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env)


def test_goals_are_graspable_and_reproducible(env: TopSlideGoalEnv) -> None:
    goals = [env.reset(seed=s)[1]["goal_pose"] for s in (3, 3, 4)]
    assert goals[0] == goals[1] and goals[0] != goals[2]
    obj, table, u_star = get_object("square"), get_table("square"), TaskParams().u_star
    for seed in range(10):
        obs, info = env.reset(seed=seed)
        x, y, yaw = info["goal_pose"]
        np.testing.assert_allclose(obs["desired_goal"], goal_vector((x, y, yaw)))
        over = overhang(transform_polygon(obj.polygon, x, y, yaw), table.polygon)
        assert over.graspable(u_star) and over.u <= u_star + 0.025 + 1e-9
        assert REACH_MIN <= math.hypot(x, y) <= REACH_MAX


def test_every_admitted_generated_plate_gets_a_graspable_goal() -> None:
    from slide_gym.envs.goal import GOAL_CENTROID_MARGIN, GOAL_EXTRA_OVERHANG
    from slide_gym.geometry import ObjectShape

    env = TopSlideGoalEnv(object="procedural")
    u_star, small = TaskParams().u_star, 0
    try:
        for seed in range(20):
            _, info = env.reset(seed=seed)
            obj: ObjectShape = env.task.object
            x, y, yaw = info["goal_pose"]
            over = overhang(transform_polygon(obj.polygon, x, y, yaw), env.task.table.polygon)
            assert over.graspable(u_star), seed
            small += obj.circumradius < u_star + GOAL_EXTRA_OVERHANG[1] + GOAL_CENTROID_MARGIN
    finally:
        env.close()
    assert small >= 1  # a plate too small for the uniform draw was among them


def test_compute_reward_is_vectorised_and_matches_step(env: TopSlideGoalEnv) -> None:
    obs, _ = env.reset(seed=0)
    obs, reward, _, _, info = env.step(env.action_space.sample())
    assert env.compute_reward(obs["achieved_goal"], obs["desired_goal"], info) == reward
    a = np.repeat(obs["achieved_goal"][None], 5, axis=0)
    d = a.copy()
    d[1, 0] += 0.019  # within 2 cm
    d[2, 1] += 0.021  # beyond
    d[3, 2:] = goal_vector((0, 0, math.atan2(a[3, 3], a[3, 2]) + 0.29))[2:]  # within 0.3 rad
    d[4, 2:] = goal_vector((0, 0, math.atan2(a[4, 3], a[4, 2]) - 0.31))[2:]  # beyond
    r = env.compute_reward(a, d, [info] * 5)
    assert r.shape == (5,) and r.dtype == np.float32
    np.testing.assert_array_equal(r, [0, 0, -1, 0, -1])
    assert env.compute_reward(a[None], d[None], None).shape == (1, 5)


def test_success_when_the_plate_is_at_the_goal(env: TopSlideGoalEnv) -> None:
    start = (0.6, 0.05, 0.3)
    obs, info = env.reset(seed=0, options={"object_pose": start, "goal": start})
    np.testing.assert_allclose(obs["achieved_goal"], obs["desired_goal"], atol=2e-3)
    assert info["is_success"] and info["goal_distance_m"] < 2e-3
    obs, reward, terminated, _, info = env.step(np.r_[np.zeros(7), -1.0].astype(np.float32))
    assert reward == 0.0 and terminated and info["is_success"]
    with pytest.raises(ValueError, match="goal"):
        env.reset(options={"goal": (0.6, float("nan"), 0.0)})


def test_sac_with_her_runs() -> None:
    """A few hundred steps of SB3's SAC with HER (relabelling through compute_reward)."""
    sb3 = pytest.importorskip("stable_baselines3")
    pytest.importorskip("torch").set_num_threads(1)
    env = gym.make(GOAL_ID, max_episode_steps=50)
    try:
        model = sb3.SAC(
            "MultiInputPolicy",
            env,
            replay_buffer_class=sb3.HerReplayBuffer,
            replay_buffer_kwargs={"n_sampled_goal": 4, "goal_selection_strategy": "future"},
            learning_starts=100,
            batch_size=64,
            buffer_size=1000,
            policy_kwargs={"net_arch": [64, 64]},
            seed=0,
            device="cpu",
        )
        model.learn(300)
        assert model.num_timesteps == 300 and model.replay_buffer.size() > 0
    finally:
        env.close()
