"""The dense reward: named terms that sum to it, and no gain from ending an episode early."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from agents.scripted import ScriptedSlider
from slide_gym.envs.reward import TERM_NAMES, DenseReward
from slide_gym.envs.top_slide import TopSlideEnv
from slide_gym.task import TaskParams

HOLD = np.r_[np.zeros(7), -1.0].astype(np.float32)
"""Keep the arm's joint targets, hand open: hold still."""


def _run(env: TopSlideEnv, seed: int, steps: int, push_off: bool, scripted: int) -> list[tuple]:
    """Scripted slider for ``scripted`` steps (``push_off``: slide 15 cm past the goal), then
    hold still; return the (reward, terminated, info) of each step."""
    obs, _ = env.reset(seed=seed)
    policy = ScriptedSlider(env)
    policy.act(obs)  # plans the slide
    if push_off:
        policy.slide_length += 0.15
    out = []
    for k in range(steps):
        action = policy.act(obs) if k < scripted else HOLD
        obs, reward, terminated, _, info = env.step(action)
        out.append((reward, terminated, info))
        if terminated:
            break
    return out


def test_terms_sum_to_the_reward_and_a_slide_pays_the_bonus() -> None:
    env = TopSlideEnv(object="square", table="square", reward_type="dense")
    try:
        _, info = env.reset(seed=0)
        assert set(info["reward_terms"]) == set(TERM_NAMES)
        steps = _run(env, 0, 400, push_off=False, scripted=400)
    finally:
        env.close()
    bonus = env.dense_reward.success_bonus
    for reward, _, info in steps:
        terms = info["reward_terms"]
        assert set(terms) == set(TERM_NAMES)
        assert reward == pytest.approx(sum(terms.values()))
        assert 0.0 <= reward - terms["success"] <= 1.0  # shaping, no fall: within [0, 1]
        assert terms["lift"] == 0.0 and terms["fall_off"] == 0.0
    reward, terminated, info = steps[-1]
    assert terminated and info["is_success"] and reward >= bonus
    assert max(r for r, _, _ in steps[:-1]) <= 1.0


def test_pushing_the_plate_off_scores_below_staying() -> None:
    limit = 220
    env = TopSlideEnv(object="square", table="square", reward_type="dense")
    try:
        pushed = _run(env, 0, limit, push_off=True, scripted=limit)
        fall = len(pushed)
        stopped = _run(env, 0, limit, push_off=True, scripted=fall - 30)  # stop 30 steps short
        still = _run(env, 0, limit, push_off=False, scripted=0)  # never move
    finally:
        env.close()
    reward, terminated, info = pushed[-1]
    assert terminated and info["fell_off"] and fall < limit
    assert reward == -env.dense_reward.fall_penalty
    assert all(r >= 0.0 for r, _, _ in pushed[:-1])
    assert len(stopped) == len(still) == limit  # neither ends the episode
    assert not any(i["fell_off"] for _, _, i in stopped + still)
    pushed_return, stopped_return, still_return = (
        sum(r for r, _, _ in run) for run in (pushed, stopped, still)
    )
    assert pushed_return < 0.0 <= still_return < stopped_return


def test_return_ordering_bounds() -> None:
    """For episodes of at most H steps: fell off < 0 <= neither <= H <= success."""
    env = TopSlideEnv(object="square", table="square", goal="grasp", reward_type="dense")
    try:
        env.reset(seed=0)
        s0 = env.unwrapped._state
        tip, _ = env.robot.fingertip_pose()
    finally:
        env.close()
    r, p, t = DenseReward(), TaskParams(), 0.002
    rng = np.random.default_rng(0)
    for _ in range(200):  # shaping of arbitrary states lies in [0, 1]
        s = dataclasses.replace(
            s0,
            overhang_m=float(rng.uniform(0, 0.2)),
            clearance_m=float(rng.uniform(-0.01, 0.2)),
            object_z=float(rng.uniform(-0.01, 0.2)),
        )
        for goal in ("slide", "grasp"):
            terms = r.terms(goal, s, tip + rng.normal(0, 0.1, 3), t, p, success=False)
            assert 0.0 <= sum(terms.values()) <= 1.0
            assert min(terms.values()) >= 0.0
    best = r.terms("grasp", dataclasses.replace(s0, overhang_m=0.1, clearance_m=0.1), tip, t, p, 0)
    fell = r.terms("grasp", dataclasses.replace(s0, fell_off=True), tip, t, p, success=False)
    assert sum(fell.values()) == fell["fall_off"] == -r.fall_penalty
    assert (r.horizon - 1) * 1.0 - r.fall_penalty < 0.0  # any dropping episode scores < 0
    assert r.horizon * max(1.0, sum(best.values())) <= r.success_bonus  # success beats lingering
    won = r.terms("slide", s0, tip, t, p, success=True)
    assert won["success"] == r.success_bonus


def test_sparse_reward_terms() -> None:
    env = TopSlideEnv(object="square", table="square")
    try:
        _, info = env.reset(seed=1)
        _, reward, _, _, info = env.step(HOLD)
    finally:
        env.close()
    assert info["reward_terms"] == {"success": 0.0} and reward == 0.0
