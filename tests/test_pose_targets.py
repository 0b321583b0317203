"""Fingertip targets in the task frame (``train-dp --actions targets``): labels, the step
toward a target, and a policy that acts with them. Tiny sizes: nothing here says how well
such a policy does."""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
import torch  # noqa: E402

import slide_gym  # noqa: E402,F401 - registers the environments
from agents.learned.data import ChunkSampler, load_demonstrations  # noqa: E402
from agents.learned.diffusion import DiffusionConfig  # noqa: E402
from agents.learned.frames import (  # noqa: E402
    TARGET_SIZE,
    arm_fingertip_poses,
    step_toward,
    targets_in_frame,
    task_frames,
)
from agents.learned.policy import DiffusionPolicy  # noqa: E402
from agents.learned.train import TrainConfig, train_diffusion  # noqa: E402
from slide_gym.cli import main  # noqa: E402
from slide_gym.datasets.store import load  # noqa: E402

torch.set_num_threads(1)

ENV_ID = "SlideGym/TopSlide-v0"
EE = {"object": "square", "table": "square", "control_mode": "ee_delta"}
TINY = DiffusionConfig(
    channels=(16, 32), step_embed_dim=16, train_steps=20, inference_steps=4, actions="targets"
)


@pytest.fixture(scope="module")
def ee_slide(minari_root):
    """One expert slide in fingertip steps (seed 3)."""
    args = ["collect", "--env", ENV_ID, "--episodes", "1", "--seed", "3", "--workers", "1"]
    args += ["--control-mode", "ee_delta", "--dataset-id", "test/ee-slide-v0"]
    assert main(args) == 0
    return load("test/ee-slide-v0")


def test_a_target_is_the_arms_fingertip_pose_after_the_step_in_the_first_frame(ee_slide):
    demos = load_demonstrations(ee_slide, targets=True)
    episode = next(ee_slide.iterate_episodes())
    obs = {k: np.asarray(v) for k, v in episode.observations.items()}
    n = len(episode.actions)
    assert demos.labels.shape == (n, TARGET_SIZE + 1)
    np.testing.assert_array_equal(demos.labels[:, -1], np.asarray(episode.actions)[:, -1])
    frame = task_frames({k: v[:1] for k, v in obs.items()})[0]
    for t in (0, n // 2, n - 1):
        target = demos.labels[t, :TARGET_SIZE].astype(np.float64)
        tip = arm_fingertip_poses(obs["arm_qpos"][t + 1])[0]
        pos = frame[:3, 3] + frame[:3, :3] @ target[:3]
        np.testing.assert_allclose(pos, tip[:3, 3], atol=1e-6)
        rot = frame[:3, :3] @ np.column_stack([target[3:6], target[6:9]])
        np.testing.assert_allclose(rot, tip[:3, :2], atol=1e-5)
    # with the hand at rest and no contact, that is the observed fingertip pose
    np.testing.assert_allclose(
        arm_fingertip_poses(obs["arm_qpos"][0])[0, :3, 3], obs["fingertip_pose"][0, :3], atol=2e-3
    )


def test_the_task_frame_faces_the_nearest_table_edge():
    env = gym.make(ENV_ID, object="square", table="square")
    try:
        obs, _ = env.reset(seed=0, options={"object_pose": (0.78, 0.0, 0.3)})  # near x = 0.85
    finally:
        env.close()
    frame = task_frames({k: v[None] for k, v in obs.items()})[0]
    np.testing.assert_allclose(frame[:3, 0], [1.0, 0.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(frame[:3, 2], [0.0, 0.0, 1.0])
    np.testing.assert_allclose(frame[:2, 3], obs["object_pose"][:2], atol=1e-6)


def test_the_step_toward_a_target_is_zero_there_and_clipped_far_away():
    frame = np.eye(4)
    frame[:3, 3] = [0.6, 0.1, 0.7]
    q = np.array([0.1, 0.9, 0.0, 1.2, 0.0, 0.4, 0.0])
    here = targets_in_frame(arm_fingertip_poses(q), frame)[0]
    np.testing.assert_allclose(step_toward(here, frame, q), np.zeros(6), atol=1e-5)
    far = here.copy()
    far[0] += 0.004  # 4 mm along the frame's x: 0.4 of a 1 cm step
    far[2] += 0.5  # half a metre up: clipped to a full step
    step = step_toward(far, frame, q)
    np.testing.assert_allclose(step, [0.4, 0.0, 1.0, 0.0, 0.0, 0.0], atol=1e-4)


def test_windows_of_targets_hold_still_before_the_start_and_after_the_end(ee_slide):
    demos = load_demonstrations(ee_slide, targets=True)
    sampler = ChunkSampler(demos, obs_horizon=2, pred_horizon=16, representation="targets")
    np.testing.assert_array_equal(sampler.chunks[0, 0], demos.labels[0])  # step -1 holds
    np.testing.assert_array_equal(sampler.chunks[-1, -1], demos.labels[-1])


def test_only_fingertip_step_demonstrations_give_targets(minari_root):
    args = ["collect", "--env", ENV_ID, "--episodes", "1", "--seed", "3", "--workers", "1"]
    assert main([*args, "--dataset-id", "test/joint-slide-v0"]) == 0
    with pytest.raises(ValueError, match="fingertip targets need ee_delta demonstrations"):
        load_demonstrations(load("test/joint-slide-v0"), targets=True)


@pytest.fixture(scope="module")
def targets_policy(ee_slide, tmp_path_factory):
    train = TrainConfig(iterations=20, batch_size=16, warmup=2, log_every=10, val_episodes=0)
    out = tmp_path_factory.mktemp("targets") / "run"
    card = {"dataset_id": "test/ee-slide-v0"}
    train_diffusion(
        ee_slide,
        out,
        config=TINY,
        train=train,
        env_id=ENV_ID,
        env_kwargs=EE,
        card=card,
        progress=False,
    )
    return out


def test_dagger_refuses_a_policy_of_targets(targets_policy, capsys):
    args = ["dagger", "--env", ENV_ID, "--policy", str(targets_policy), "--rounds", "1"]
    args += ["--episodes", "1", "--out", "unused", "--dataset-id", "test/dagger-targets-v0"]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert "acts with fingertip targets" in err and len(err.splitlines()) == 1


def test_a_policy_of_targets_steps_toward_them(targets_policy):
    policy = DiffusionPolicy.load(targets_policy, seed=0)
    env = gym.make(ENV_ID, **EE)
    try:
        obs, _ = env.reset(seed=5)
        action, _ = policy.predict(obs, episode_start=np.array([True]))
        assert action.shape == (7,) and np.all(np.abs(action) <= 1)
        assert len(policy._queues[0]) == 7  # noqa: SLF001 - 8 queued, one taken
        entry = policy._queues[0][0].copy()  # noqa: SLF001 - the next step's target
        obs, *_ = env.step(action)
        frame = policy._frames[0]  # noqa: SLF001
        expected = step_toward(entry[:-1], frame, obs["arm_qpos"])
        second, _ = policy.predict(obs, episode_start=np.array([False]))
        np.testing.assert_allclose(second[:6], expected, atol=1e-6)
    finally:
        env.close()
