"""Environment API, determinism, bounds and bad-input tests."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import slide_gym
from agents.scripted import ScriptedSlider
from slide_gym.envs.top_slide import TopSlideEnv

INFO_KEYS = {
    "is_success",
    "overhang_m",
    "graspable",
    "lift_m",
    "clearance_m",
    "lift_held_s",
    "touching_robot",
    "touching_table",
    "pinched",
    "fell_off",
    "object_pose_2d",
    "object",
    "table",
    "reward_terms",
    "randomization",
}


@pytest.mark.parametrize("env_id", slide_gym.ENV_IDS)
def test_check_env(env_id: str) -> None:
    env = gym.make(env_id, object="L", table="square")
    try:
        check_env(env.unwrapped, skip_render_check=True)
    finally:
        env.close()


def test_env_ids_registered() -> None:
    assert len(slide_gym.ENV_IDS) == 10
    for env_id in slide_gym.ENV_IDS:
        assert env_id in gym.registry
        assert isinstance(gym.registry[env_id].entry_point, str)
        assert gym.registry[env_id].kwargs["version"] == int(env_id[-1])
    assert slide_gym.EXPERT_ENV_ID == "SlideGym/TopSlideGrasp-v1"


def _rollout(env: TopSlideEnv, seed: int, n: int) -> tuple[list[dict], list[dict]]:
    obs, info = env.reset(seed=seed)
    policy = ScriptedSlider(env)
    observations, infos = [obs], [info]
    for _ in range(n):
        obs, _, terminated, truncated, info = env.step(policy.act(obs))
        observations.append(obs)
        infos.append(info)
        if terminated or truncated:
            break
    return observations, infos


def test_determinism_fresh_and_reused_env_with_contact() -> None:
    fresh = TopSlideEnv(object="square", table="square")
    reused = TopSlideEnv(object="square", table="square")
    try:
        _rollout(reused, seed=3, n=20)  # dirty the reused env's world first
        obs_a, infos_a = _rollout(fresh, seed=11, n=70)
        obs_b, infos_b = _rollout(reused, seed=11, n=70)
    finally:
        fresh.close()
        reused.close()
    assert len(obs_a) == len(obs_b) > 50
    assert any(i["touching_robot"] for i in infos_a), "the rollout never touched the object"
    for a, b in zip(obs_a, obs_b, strict=True):
        for key in a:
            np.testing.assert_array_equal(a[key], b[key], err_msg=key)


def test_reset_seed_gives_same_start_and_different_seeds_differ() -> None:
    env = TopSlideEnv(object="random", table="random")
    try:
        o1, _ = env.reset(seed=5)
        o2, _ = env.reset(seed=5)
        o3, _ = env.reset(seed=6)
    finally:
        env.close()
    np.testing.assert_array_equal(o1["object_pose"], o2["object_pose"])
    assert not np.array_equal(o1["object_pose"], o3["object_pose"])


def test_observations_in_bounds_and_info_keys() -> None:
    env = TopSlideEnv(object="crescent", table="round", goal="grasp", reward_type="dense")
    rng = np.random.default_rng(0)
    try:
        obs, info = env.reset(seed=0)
        assert set(info) == INFO_KEYS and type(info["is_success"]) is bool
        assert info["is_success"] is False and info["graspable"] is False
        for _ in range(30):
            assert env.observation_space.contains(obs)
            obs, reward, _, _, info = env.step(rng.uniform(-1, 1, 8).astype(np.float32))
            assert set(info) == INFO_KEYS and type(info["is_success"]) is bool
            assert isinstance(reward, float) and 0.0 <= reward <= 1.0  # shaping only
            assert reward == pytest.approx(sum(info["reward_terms"].values()))
    finally:
        env.close()


def test_start_pose_is_on_table_and_not_graspable() -> None:
    env = TopSlideEnv(object="random", table="random")
    try:
        for seed in range(10):
            _, info = env.reset(seed=seed)
            assert info["overhang_m"] == 0.0
            assert not info["touching_robot"]
            assert abs(info["lift_m"]) < 0.005
            assert info["touching_table"] and abs(info["clearance_m"]) < 0.002
    finally:
        env.close()


def test_given_object_pose_is_used() -> None:
    env = TopSlideEnv(object="square", table="square")
    try:
        obs, info = env.reset(options={"object_pose": (0.6, 0.05, 0.3)})
    finally:
        env.close()
    x, y, yaw = info["object_pose_2d"]
    assert abs(x - 0.6) < 2e-3 and abs(y - 0.05) < 2e-3 and abs(yaw - 0.3) < 1e-2


def test_rgb_render() -> None:
    env = TopSlideEnv(object="A", table="triangle", render_mode="rgb_array")
    try:
        env.reset(seed=0)
        frame = env.render()
    finally:
        env.close()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    assert frame.std() > 5  # not a blank image


@pytest.mark.parametrize("mode", ["sync", "async"])
def test_make_vec(mode: str) -> None:
    envs = gym.make_vec(
        "SlideGym/TopSlide-v0", num_envs=2, vectorization_mode=mode, object="square", table="square"
    )
    try:
        obs, infos = envs.reset(seed=0)
        assert obs["arm_qpos"].shape == (2, 7)
        obs, rewards, term, trunc, infos = envs.step(envs.action_space.sample())
        assert rewards.shape == (2,)
    finally:
        envs.close()


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"object": "banana"}, "square"),
        ({"table": "kitchen"}, "round"),
        ({"scale": 0.0}, "scale"),
        ({"scale": float("nan")}, "scale"),
        ({"goal": "fly"}, "goal"),
        ({"reward_type": "shaped"}, "reward_type"),
        ({"control_hz": 7.0}, "multiple"),
        ({"render_mode": "window"}, "render_mode"),
        ({"scale": 8.0}, "larger|fit"),
    ],
)
def test_bad_constructor_arguments(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        TopSlideEnv(**kwargs)


@pytest.mark.parametrize(
    ("pose", "match"),
    [
        ((0.6, 0.24, 0.0), "off table"),  # overhangs the +y edge
        ((2.0, 0.0, 0.0), "off table"),
        ((0.6, float("nan"), 0.0), "finite"),
        ((0.6, 0.0), "3"),
        ("abc", "3"),
    ],
)
def test_bad_reset_pose(pose: object, match: str) -> None:
    env = TopSlideEnv(object="square", table="square")
    try:
        with pytest.raises(ValueError, match=match):
            env.reset(options={"object_pose": pose})
    finally:
        env.close()


def test_bad_action_and_unknown_option() -> None:
    env = TopSlideEnv()
    try:
        with pytest.raises(ValueError, match="unknown reset options"):
            env.reset(options={"teleport": True})
        env.reset(seed=0)
        with pytest.raises(ValueError, match="8 finite"):
            env.step(np.full(8, np.nan))
    finally:
        env.close()


def test_grasp_success_needs_a_lift_held_for_a_second(monkeypatch: pytest.MonkeyPatch) -> None:
    env = TopSlideEnv(object="square", table="square", goal="grasp")
    try:
        env.reset(seed=0)
        # Stand in for the physics of a grasp: the task says when the plate is held up.
        held = iter([True] * 10 + [False] + [True] * 25)
        monkeypatch.setattr(env.task, "lifted", lambda s: next(held))
        hold = round(env.task.params.lift_hold_s / env.dt)  # 20 control steps at 20 Hz
        results = [env.step(np.zeros(8, np.float32)) for _ in range(11 + hold)]
        infos = [r[4] for r in results]
        assert not any(i["is_success"] for i in infos[: 10 + hold])  # the drop restarted the count
        assert infos[-1]["is_success"] and results[-1][2]  # held for 1 s: success terminates
        assert infos[-1]["lift_held_s"] == pytest.approx(env.task.params.lift_hold_s)
        assert infos[10]["lift_held_s"] == 0.0
    finally:
        env.close()


def test_a_plate_touching_the_table_is_not_lifted() -> None:
    env = TopSlideEnv(object="square", table="square", goal="grasp")
    try:
        env.reset(seed=0)
        s = env.unwrapped._state
        up = dataclasses.replace(
            s, clearance_m=0.06, touching_finger_a=True, touching_finger_b=True
        )
        assert env.task.lifted(dataclasses.replace(up, touching_table=False))
        assert not env.task.lifted(up)  # still touching the table (the reset state)
        assert not env.task.lifted(dataclasses.replace(up, touching_table=False, clearance_m=0.04))
        assert not env.task.lifted(
            dataclasses.replace(up, touching_table=False, touching_finger_b=False)
        )
    finally:
        env.close()


def test_task_params_as_a_dict_and_unknown_fields():
    """gym.make passes JSON-friendly kwargs: a dict of TaskParams fields works, a wrong field
    is a ValueError that names the allowed ones (not an AttributeError from inside reset)."""
    from slide_gym import TaskParams

    env = gym.make("SlideGym/TopSlide-v0", task_params={"table_friction": 0.2})
    try:
        env.reset(seed=0)
        assert env.unwrapped.task.params == TaskParams(table_friction=0.2)
    finally:
        env.close()
    with pytest.raises(ValueError, match="allowed: u_star"):
        gym.make("SlideGym/TopSlide-v0", task_params={"table_frction": 0.2})
