"""The move from the slid plate to the side grasp stays short: IK along the arm's own branch,
and only the last few centimetres at the slow grasp speed."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import gymnasium as gym
import numpy as np
import pytest

import slide_gym  # noqa: F401 - registers the environments
from agents.evaluate import _planner_agent
from agents.learned.features import slide_done
from agents.params import GRASP_POSTURE, ExpertParams
from agents.tracking import LINE_ROT_STEP, cartesian_walk
from slide_gym.planning.ik import IKTarget, interpolate_rotation, solve_ik, solve_ik_along
from slide_gym.robot.kinematics import grasp_chain, mirrored_postures
from slide_gym.robot.model import READY_ARM_Q


def _angle(r: np.ndarray) -> float:
    return math.acos(float(np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0)))


@pytest.mark.parametrize("turn", [0.0, 1.0, math.pi])
def test_interpolated_rotation_runs_evenly_between_its_ends(turn):
    axis = np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    r0 = np.eye(3) + math.sin(0.3) * k + (1 - math.cos(0.3)) * (k @ k)
    r1 = r0 @ (np.eye(3) + math.sin(turn) * k + (1 - math.cos(turn)) * (k @ k))
    assert np.allclose(interpolate_rotation(r0, r1, 0.0), r0)
    assert np.allclose(interpolate_rotation(r0, r1, 1.0), r1, atol=1e-6)
    half = interpolate_rotation(r0, r1, 0.5)
    assert np.allclose(half.T @ half, np.eye(3))
    assert _angle(r0.T @ half) == pytest.approx(turn / 2, abs=1e-6)


def test_ik_along_the_branch_stays_near_the_start_where_restarts_need_not():
    chain = grasp_chain()
    q_goal = READY_ARM_Q + np.array([0.5, -0.3, 0.6, -0.4, 0.8, 0.5, -0.9])
    pose = chain.forward(q_goal[None])[0]
    target = IKTarget(pose[:3, 3], pose[:3, :3])
    q = solve_ik_along(chain, target, READY_ARM_Q, 8, np.random.default_rng(0))
    assert q is not None
    reached = chain.forward(q[None])[0]
    assert np.linalg.norm(reached[:3, 3] - target.position) < 1e-4
    near = np.linalg.norm(q - READY_ARM_Q)
    assert near <= np.linalg.norm(q_goal - READY_ARM_Q)  # no farther than the known solution
    with pytest.raises(ValueError, match="full orientation"):
        solve_ik_along(chain, IKTarget(pose[:3, 3]), READY_ARM_Q, 8, np.random.default_rng(0))
    # what random restarts answer, seed by seed: mostly far from the start
    restarts = [solve_ik(chain, target, np.random.default_rng(s)) for s in range(10)]
    farther = [np.linalg.norm(r - READY_ARM_Q) > near + 0.5 for r in restarts if r is not None]
    assert sum(farther) >= 5


@dataclass
class _Transfer:
    """One square-on-square grasp in fingertip steps, from the hand-off to closing the hand."""

    success: bool
    highest: float  # m, the fingertip's highest point
    steps: int
    events: list[str]


def _transfer(seed: int, straight: bool = False) -> _Transfer:
    env = gym.make(
        "SlideGym/TopSlideGrasp-v0", object="square", table="square", control_mode="ee_delta"
    )
    obs, _ = env.reset(seed=seed)
    agent = _planner_agent("regions", env, seed, 10.0)
    agent.params = dataclasses.replace(agent.params, straight_transfer=straight)
    heights, handed_over, closed, success = [], None, None, False
    for t in range(env.spec.max_episode_steps):
        action, _ = agent.predict(obs, deterministic=True)
        heights.append(float(obs["fingertip_pose"][2]))
        if handed_over is None and slide_done({k: v[None] for k, v in obs.items()})[0]:
            handed_over = t
        if closed is None and action[-1] > 0:
            closed = t
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            success = bool(info["is_success"])
            break
    env.close()
    expert = agent.expert(0)
    assert handed_over is not None and closed is not None and expert is not None
    highest = max(heights[handed_over:closed])
    return _Transfer(success, highest, closed - handed_over, expert.report.events)


def test_expert_transfer_stays_low_and_its_approach_short():
    """Square on the square table, seed 8, fingertip steps: the re-aimed grasp was on another
    IK branch and the transfer swept the fingertip 0.97 m above the table, then crept half a
    metre at grasp speed (294 steps from lift-off to closing the hand)."""
    run = _transfer(8)
    assert run.success and run.highest < 0.4 and run.steps < 200


def test_mirrored_postures_mirror_the_hand_and_turn_the_palm():
    chain = grasp_chain()
    poses = chain.forward(mirrored_postures(np.array(GRASP_POSTURE)))
    (p, m), (pt, mt) = poses[:2], poses[2:]
    assert np.allclose(m[:3, 3], p[:3, 3] * [1, -1, 1], atol=1e-9)  # mirrored in y
    assert np.allclose(m[:3, 2], p[:3, 2] * [1, -1, 1], atol=1e-9)  # so is the approach
    for a, b in ((p, pt), (m, mt)):  # the half turn: same grasp, palm the other way up
        assert np.allclose(a[:3, 3], b[:3, 3], atol=1e-9)
        assert np.allclose(a[:3, 2], b[:3, 2], atol=1e-9)
        assert np.allclose(a[:3, 1], -b[:3, 1], atol=1e-9)
    with pytest.raises(ValueError, match="7 finite joint angles"):
        mirrored_postures(np.zeros(6))
    with pytest.raises(ValueError, match="grasp_posture"):
        ExpertParams(grasp_posture=(0.0, 3.0, 0.0, 0.0, 0.0, 0.0, 0.0))


def test_ik_nearest_a_reference_returns_the_solution_on_its_branch():
    chain = grasp_chain()
    q_goal = np.array(GRASP_POSTURE)
    flipped = q_goal + [0.0, 0.0, 0.0, 0.0, -math.pi, 0.0, math.pi]  # the wrist's other branch
    flipped[5] = -flipped[5]
    pose = chain.forward(np.stack([q_goal, flipped]))
    assert np.allclose(pose[0], pose[1], atol=1e-9)  # two branches, one hand pose
    target = IKTarget(pose[0][:3, 3], pose[0][:3, :3])
    for reference in (q_goal, flipped):
        rng = np.random.default_rng(0)
        seeds = np.stack([READY_ARM_Q, q_goal + 0.1, flipped - 0.1])
        q = solve_ik(chain, target, rng, seeds, nearest=True, reference=reference[None] + 0.05)
        assert q is not None and np.abs(q - reference).max() < 0.2


def test_expert_grasps_of_several_seeds_lie_near_its_grasp_posture():
    """Square on the square table: with the grasp nearest the arm's sliding configuration,
    joint 2 of the grasps of 200 episodes spread from -1.98 to 2.0 rad over 6 IK branches."""
    references = mirrored_postures(np.array(GRASP_POSTURE))
    env = gym.make("SlideGym/TopSlideGrasp-v0", object="square", table="square")
    gaps = []
    for seed in range(4):
        obs, _ = env.reset(seed=seed)
        agent = _planner_agent("regions", env, seed, 10.0)
        for _ in range(env.spec.max_episode_steps):
            action, _ = agent.predict(obs, deterministic=True)
            if action[-1] > 0:  # the hand closes: the arm is at the grasp
                q = obs["arm_qpos"]
                gaps.append(float(np.linalg.norm(references - q, axis=1).min()))
                break
            obs, *_ = env.step(action)
    env.close()
    assert len(gaps) == 4 and max(gaps) < 1.0, gaps


def test_a_cartesian_walk_moves_straight_and_turns_evenly():
    chain = grasp_chain()
    start = chain.forward(READY_ARM_Q[None])[0]
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # a quarter turn
    goal = (start[:3, 3] + [0.05, -0.08, -0.1], start[:3, :3] @ turn)
    path = cartesian_walk(chain, READY_ARM_Q, [goal], np.random.default_rng(0))
    assert path is not None and len(path) >= math.ceil((math.pi / 2) / LINE_ROT_STEP) + 1
    poses = chain.forward(path)
    along = goal[0] - start[:3, 3]
    off_line = np.cross(poses[:, :3, 3] - start[:3, 3], along / np.linalg.norm(along))
    assert np.abs(off_line).max() < 1e-3  # on the straight line, to the IK's tolerance
    angles = [_angle(start[:3, :3].T @ p[:3, :3]) for p in poses]
    assert np.all(np.diff(angles) > 0.0) and angles[-1] == pytest.approx(math.pi / 2, abs=1e-3)
    assert np.abs(np.diff(path, axis=0)).max() <= 0.3  # one IK branch throughout
    far = (start[:3, 3] + [3.0, 0.0, 0.0], start[:3, :3])  # beyond the arm's reach
    assert cartesian_walk(chain, READY_ARM_Q, [far], np.random.default_rng(0)) is None


def test_a_straight_transfer_is_off_by_default_and_keeps_the_hand_low():
    """Square on the square table, seed 7, fingertip steps: between the hand-off and the
    grasp the planner's joint-space legs raise the fingertip to 0.20 m, the straight legs to
    0.105 m, and the plate is lifted either way."""
    assert ExpertParams().straight_transfer is False
    with pytest.raises(ValueError, match="straight_transfer must be True or False"):
        ExpertParams(straight_transfer=1)  # type: ignore[arg-type]
    planned, straight = _transfer(7), _transfer(7, straight=True)
    assert planned.success and straight.success
    assert "straight transfer to the grasp" in straight.events
    assert not any("straight" in e for e in planned.events)
    assert planned.highest > 0.18 and straight.highest < 0.12
