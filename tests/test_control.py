"""Control modes: action spaces, bad input, the ``ee_delta`` controller, and the expert in both."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import slide_gym  # noqa: F401 - registers the environments
from agents.ee_actions import EEActions
from agents.episode import run_episode
from agents.planner_agent import PlannerAgent
from slide_gym.envs.control import (
    CONTROL_MODES,
    EEDeltaControl,
    make_control,
    rotation_matrix,
    rotation_vector,
)
from slide_gym.envs.top_slide import TopSlideEnv
from slide_gym.robot.model import ARM_LOWER, ARM_UPPER, READY_ARM_Q

OPEN = -1.0  # hand command entry: open


def _ee(position=(0.0, 0.0, 0.0), rotation=(0.0, 0.0, 0.0)) -> np.ndarray:
    return np.array([*position, *rotation, OPEN], dtype=np.float32)


def _rotation(quat_xyzw: np.ndarray) -> np.ndarray:
    x, y, z, w = np.asarray(quat_xyzw, dtype=float) / np.linalg.norm(quat_xyzw)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


@pytest.mark.parametrize(("mode", "width"), [("joint_delta", 8), ("ee_delta", 7)])
def test_action_space_per_mode(mode: str, width: int) -> None:
    assert mode in CONTROL_MODES
    assert make_control(mode, 0.05).action_space.shape == (width,)
    env = TopSlideEnv(control_mode=mode)
    try:
        assert env.action_space.shape == (width,) and env.action_space.dtype == np.float32
        assert env.action_space.low.min() == -1.0 and env.action_space.high.max() == 1.0
    finally:
        env.close()


def test_check_env_in_ee_delta_mode() -> None:
    env = gym.make("SlideGym/TopSlide-v0", object="L", table="square", control_mode="ee_delta")
    try:
        check_env(env.unwrapped, skip_render_check=True)
    finally:
        env.close()


def test_bad_mode_and_step_sizes() -> None:
    for make in (
        lambda: make_control("torque", 0.05),
        lambda: TopSlideEnv(control_mode="torque"),
        lambda: PlannerAgent(control_mode="torque"),
    ):
        with pytest.raises(ValueError, match="control_mode must be one of joint_delta, ee_delta"):
            make()
    for name in ("max_tip_step", "max_rot_step"):
        for bad in (0.0, -0.01, float("nan"), True):
            with pytest.raises(ValueError, match=f"{name} must be a positive number"):
                make_control("ee_delta", 0.05, **{name: bad})
        with pytest.raises(ValueError, match=name):
            TopSlideEnv(control_mode="ee_delta", **{name: 0.0})
    with pytest.raises(ValueError, match="max_joint_step must be a positive number"):
        EEDeltaControl(0.0)


def test_bad_action_in_ee_delta_mode() -> None:
    env = TopSlideEnv(control_mode="ee_delta")
    try:
        env.reset(seed=0)
        for bad in (np.full(7, np.nan), np.zeros(8), np.zeros(6)):
            with pytest.raises(ValueError, match="action must be 7 finite numbers"):
                env.step(bad)
    finally:
        env.close()


def test_rotation_vector_inverts_rotation_matrix() -> None:
    rng = np.random.default_rng(0)
    for v in [*rng.normal(size=(20, 3)), np.array([0.0, 0.0, np.pi - 1e-9]), np.zeros(3)]:
        v = v * min(1.0, (np.pi - 1e-9) / max(np.linalg.norm(v), 1e-12))  # angle up to pi
        np.testing.assert_allclose(rotation_vector(rotation_matrix(v)), v, atol=1e-7)


def test_controller_moves_the_target_pose_by_the_commanded_increment() -> None:
    c = EEDeltaControl(0.05, max_tip_step=0.01, max_rot_step=0.05)
    c.reset(READY_ARM_Q)
    start = c.chain.forward(c.target)
    for _ in range(3):
        c.apply(_ee(position=(1.0, -0.5, 0.0), rotation=(0.0, 0.0, 1.0)))
    reached = c.chain.forward(c.target)
    np.testing.assert_allclose(reached[:3, 3] - start[:3, 3], [0.03, -0.015, 0.0], atol=1e-4)
    turn = rotation_vector(reached[:3, :3] @ start[:3, :3].T)
    np.testing.assert_allclose(turn, [0.0, 0.0, 0.15], atol=1e-3)


def test_ee_delta_moves_the_real_fingertip_and_holds_its_orientation() -> None:
    env = TopSlideEnv(control_mode="ee_delta")
    try:
        obs, _ = env.reset(seed=0)
        start = obs["fingertip_pose"].astype(float)
        obs, *_ = env.step(_ee(position=(1.0, 0.0, 0.0)))  # +1 cm in x
        for _ in range(4):
            obs, *_ = env.step(_ee())
        tip = obs["fingertip_pose"].astype(float)
        np.testing.assert_allclose(tip[:3] - start[:3], [0.01, 0.0, 0.0], atol=0.002)
        turn = rotation_vector(_rotation(tip[3:]) @ _rotation(start[3:]).T)
        assert np.linalg.norm(turn) < 0.01
        for _ in range(4):  # yaw: 4 x 0.05 rad about world z
            obs, *_ = env.step(_ee(rotation=(0.0, 0.0, 1.0)))
        for _ in range(4):
            obs, *_ = env.step(_ee())
        tip = obs["fingertip_pose"].astype(float)
        np.testing.assert_allclose(tip[:3] - start[:3], [0.01, 0.0, 0.0], atol=0.002)
        turn = rotation_vector(_rotation(tip[3:]) @ _rotation(start[3:]).T)
        np.testing.assert_allclose(turn, [0.0, 0.0, 0.2], atol=0.01)
    finally:
        env.close()


def test_joint_limits_hold_and_an_unreachable_target_does_not_run_away() -> None:
    c = EEDeltaControl(0.05)
    c.reset(READY_ARM_Q)
    rng = np.random.default_rng(1)
    pushes = [_ee(position=(1.0, 0.0, 0.3))] * 150 + [_ee(rotation=(1.0, 0.0, 1.0))] * 100
    pushes += list(rng.uniform(-1, 1, (150, 7)).astype(np.float32))
    prev, reach = c.target.copy(), 0.0
    for a in pushes:
        q, _ = c.apply(a)
        assert np.all(q >= ARM_LOWER) and np.all(q <= ARM_UPPER)
        assert np.abs(q - prev).max() <= 0.05 + 1e-12
        reached = c.chain.forward(q)
        assert np.linalg.norm(c.target_pose[:3, 3] - reached[:3, 3]) < 2e-3
        prev, reach = q.copy(), max(reach, float(np.linalg.norm(reached[:2, 3])))
    assert reach > 0.8  # the arm went as far out as it could


def test_ee_delta_is_deterministic_and_the_expert_mirror_is_exact() -> None:
    actions = np.random.default_rng(2).uniform(-1, 1, (30, 7)).astype(np.float32)
    actions[:, 2] = np.abs(actions[:, 2])  # keep the fingertip off the table
    runs = []
    for _ in range(2):
        env = TopSlideEnv(object="E", control_mode="ee_delta")
        try:
            obs, _ = env.reset(seed=3)
            mirror = EEActions(0.05, 0.01, 0.05)
            mirror.reset(env.control.target)
            seen = [obs]
            for a in actions:
                obs, *_ = env.step(a)
                mirror.control.apply(a)
                assert np.array_equal(mirror.q_cmd, env.control.target)
                seen.append(obs)
            runs.append(seen)
        finally:
            env.close()
    for a, b in zip(*runs, strict=True):
        for key in a:
            np.testing.assert_array_equal(a[key], b[key])


def test_expert_actions_reach_the_desired_joint_targets_fingertip_pose() -> None:
    enc = EEActions(0.05, 0.01, 0.05)
    enc.reset(READY_ARM_Q)
    want = READY_ARM_Q + np.array([0.1, -0.05, 0.0, 0.1, 0.0, 0.1, -0.2])
    for _ in range(40):
        a = enc.action(want, 0.0)
        assert a.shape == (7,) and a.dtype == np.float32 and np.abs(a).max() <= 1.0
    got, goal = enc.control.chain.forward(enc.q_cmd), enc.control.chain.forward(want)
    assert np.linalg.norm(got[:3, 3] - goal[:3, 3]) < 1e-4
    assert np.linalg.norm(rotation_vector(got[:3, :3] @ goal[:3, :3].T)) < 1e-3
    assert not enc.behind and a[6] == -1.0


@pytest.mark.slow
def test_expert_slides_as_often_in_ee_delta_mode_as_in_joint_mode(plan_budget) -> None:
    cases = [("square", 0), ("E", 1), ("L", 2)]
    wins = {}
    for mode in CONTROL_MODES:
        wins[mode] = [
            run_episode(
                obj,
                "square",
                seed=seed,
                time_budget=plan_budget,
                env_id="SlideGym/TopSlide-v0",
                control_mode=mode,
            ).success
            for obj, seed in cases
        ]
    assert wins["joint_delta"] == [True] * len(cases), wins
    assert sum(wins["ee_delta"]) >= sum(wins["joint_delta"]), wins


@pytest.mark.slow
def test_expert_grasps_and_lifts_in_ee_delta_mode(plan_budget) -> None:
    """The whole episode, with the hand turned from pressing down to the side grasp."""
    r = run_episode("L", "square", seed=2, time_budget=plan_budget, control_mode="ee_delta")
    assert r.success and r.lift_height_m >= 0.05, r.expert.events
