"""Behaviour cloning from a Minari dataset (agents.bc) and agent evaluation (agents.evaluate)."""

from __future__ import annotations

import json
import os
import shutil
import warnings
from collections.abc import Iterator
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym  # noqa: E402
import minari  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
import torch  # noqa: E402

import slide_gym  # noqa: E402,F401 - registers the environments
from agents.bc import model_card_path, train_bc, write_model_card  # noqa: E402
from agents.evaluate import (  # noqa: E402
    episode_ending,
    evaluate,
    failure_summary,
    wilson_interval,
)

torch.set_num_threads(1)

ENV_ID = "SlideGym/TopSlide-v0"
SEEDS = (0, 1, 2)
T = 15
CONST_ACTION = np.array([0.6, -0.4, 0.2, -0.7, 0.5, -0.3, 0.1, 0.8], np.float32)
"""Every action of the dataset: a policy that learnt anything predicts it everywhere."""


def _episode(env: gym.Env, seed: int, actions: np.ndarray) -> minari.data_collector.EpisodeBuffer:
    from minari.data_collector import EpisodeBuffer

    obs, info = env.reset(seed=seed)
    observations, rewards, successes = [obs], [], [info["is_success"]]
    terminations = []
    for a in actions:
        obs, reward, terminated, _, info = env.step(a)
        observations.append(obs)
        rewards.append(reward)
        terminations.append(terminated)
        successes.append(info["is_success"])
        assert not terminated  # 15 steps of a fixed push never slide the plate off
    truncations = np.zeros(len(actions), bool)
    truncations[-1] = True
    return EpisodeBuffer(
        id=None,
        seed=seed,
        options=None,
        observations={
            k: np.stack([o[k] for o in observations]).astype(np.float32) for k in observations[0]
        },
        actions=np.asarray(actions, np.float32),
        rewards=np.asarray(rewards, np.float64),
        terminations=np.asarray(terminations, bool),
        truncations=truncations,
        infos={"is_success": np.asarray(successes, bool)},
    )


@pytest.fixture(scope="module")
def minari_root(tmp_path_factory) -> Iterator[Path]:
    """MINARI_DATASETS_PATH points into a fresh temporary folder for this module."""
    root = tmp_path_factory.mktemp("minari")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("MINARI_DATASETS_PATH", str(root))
        yield root


@pytest.fixture(scope="module")
def dataset(minari_root):
    """3 episodes x 15 steps of SlideGym/TopSlide-v0 (seeds 0-2), every action CONST_ACTION."""
    env = gym.make(ENV_ID)
    try:
        buffers = [_episode(env, s, np.tile(CONST_ACTION, (T, 1))) for s in SEEDS]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # author, permalink, ... not set
            minari.create_dataset_from_buffers(
                dataset_id="test/bc-v0",
                buffer=buffers,
                env=env.spec,
                algorithm_name="constant",
                jpeg_encoding=False,
            )
    finally:
        env.close()
    return minari.load_dataset("test/bc-v0")


@pytest.fixture(scope="module")
def trained(dataset, tmp_path_factory):
    """``(model, stats, path)``: 100 BC steps on :func:`dataset`, saved to ``path``."""
    model, stats = train_bc(dataset, steps=100, batch_size=64, learning_rate=3e-3, seed=0)
    path = tmp_path_factory.mktemp("models") / "bc.zip"
    model.save(path)
    model.env.close()
    return model, stats, path


def _dataset_obs(dataset) -> dict[str, np.ndarray]:
    eps = list(dataset.iterate_episodes())
    return {k: np.concatenate([ep.observations[k][:-1] for ep in eps]) for k in eps[0].observations}


def test_bc_fits_the_datasets_actions_and_reports_stats(dataset, trained):
    model, stats, _ = trained
    assert stats["steps"] == 100 and stats["frames"] == len(SEEDS) * T
    assert stats["episodes"] == len(SEEDS) and "train_time_s" in stats
    # Before training: mean ~0 and std e^-1, so NLL = sum 0.5 (c / 0.368)^2 - 1 + 0.92 ~ 8
    sigma = np.exp(-1.0)
    start = float(np.sum(0.5 * (CONST_ACTION / sigma) ** 2 - 1.0 + 0.5 * np.log(2 * np.pi)))
    assert stats["initial_loss"] == pytest.approx(start, rel=0.15)
    # a fitted mean leaves ~ 8 (log_std + 0.92) < 0: a drop by more than the whole start value
    assert stats["final_loss"] < 0.0 < start - 6.0
    obs = _dataset_obs(dataset)
    actions, _ = model.predict(obs, deterministic=True)
    assert actions.shape == (len(SEEDS) * T, 8)
    assert np.abs(actions - CONST_ACTION).max() < 0.1


def test_saved_model_loads_with_ppo_and_predicts_the_mean(dataset, trained):
    from stable_baselines3 import PPO

    model, _, path = trained
    loaded = PPO.load(path, device="cpu")
    obs = _dataset_obs(dataset)
    a_model, _ = model.predict(obs, deterministic=True)
    a_loaded, _ = loaded.predict(obs, deterministic=True)
    np.testing.assert_array_equal(a_model, a_loaded)
    obs_t, _ = loaded.policy.obs_to_tensor(obs)
    with torch.no_grad():
        mean = loaded.policy.get_distribution(obs_t).distribution.mean.numpy()
    np.testing.assert_allclose(a_loaded, np.clip(mean, -1, 1), atol=1e-6)
    # the normaliser's statistics are saved with it (not the identity it starts as)
    std = loaded.policy.features_extractor.obs_std
    assert not torch.all(std == 1.0)


def test_same_seed_gives_identical_weights(dataset):
    def weights(seed: int) -> dict[str, torch.Tensor]:
        model, _ = train_bc(dataset, steps=10, batch_size=32, seed=seed)
        model.env.close()
        return model.policy.state_dict()

    a, b, c = weights(3), weights(3), weights(4)
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert not all(torch.equal(a[k], c[k]) for k in a)


def test_train_bc_rejects_bad_input(dataset):
    with pytest.raises(ValueError, match="steps"):
        train_bc(dataset, steps=0)
    with pytest.raises(ValueError, match="batch_size"):
        train_bc(dataset, steps=1, batch_size=0)
    empty = dataset.filter_episodes(lambda ep: False)
    with pytest.raises(ValueError, match="empty"):
        train_bc(empty, steps=1)
    env = gym.make(ENV_ID, control_mode="ee_delta")  # 7-wide actions
    try:
        with pytest.raises(ValueError, match="action space"):
            train_bc(dataset, steps=1, env=env)
    finally:
        env.close()


def test_wilson_interval_values():
    lo, hi = wilson_interval(0, 10)
    assert lo == 0.0 and hi == pytest.approx(0.2775, abs=1e-3)
    lo, hi = wilson_interval(10, 10)
    assert hi == 1.0 and lo == pytest.approx(0.7225, abs=1e-3)
    lo, hi = wilson_interval(5, 10)
    assert lo == pytest.approx(1 - hi) and lo == pytest.approx(0.2366, abs=1e-3)
    for bad in ((0, 0), (3, 2), (-1, 5)):
        with pytest.raises(ValueError):
            wilson_interval(*bad)


def test_evaluate_runs_a_saved_model_on_held_out_seeds(trained):
    _, _, path = trained
    result = evaluate(path, ENV_ID, episodes=2, max_steps=20)
    assert result["agent"] == str(path) and result["env_id"] == ENV_ID
    assert result["env_kwargs"] == {} and result["episodes"] == 2
    assert result["seeds"] == [10_000, 10_001]
    assert [r["seed"] for r in result["results"]] == result["seeds"]
    assert all(r["length"] == 20 and r["success"] is False for r in result["results"])
    assert all(r["ended"] == "max_steps" for r in result["results"])
    assert result["ended"] == {"max_steps": 2}
    assert all(isinstance(r["return"], float) for r in result["results"])
    assert result["successes"] == 0 and result["success_rate"] == 0.0
    assert result["mean_length"] == 20.0
    assert result["ci95"] == list(wilson_interval(0, 2))
    json.dumps(result)  # a JSON report as it is
    # the same seeds give the same episodes
    again = evaluate(str(path), ENV_ID, episodes=1, seed=10_001, max_steps=20)
    assert again["results"][0] == result["results"][1]


@pytest.mark.parametrize(
    ("flags", "info", "ended"),
    [
        ((True, True, False), {"fell_off": False}, "success"),
        ((False, True, False), {"fell_off": True}, "fell_off"),
        ((False, False, True), {"fell_off": False}, "time_limit"),
        ((False, True, False), {}, "other"),
        ((False, False, False), {"fell_off": False}, "max_steps"),
    ],
)
def test_episode_ending_names_how_an_episode_stopped(flags, info, ended):
    assert episode_ending(*flags, info) == ended


def test_failure_summary_counts_the_failed_endings_only():
    assert failure_summary({"success": 80, "fell_off": 9, "time_limit": 11}) == (
        "; failures: 9 fell off, 11 time limit"
    )
    assert failure_summary({"success": 3}) == ""


def test_model_card_supplies_env_kwargs_that_explicit_ones_override(trained, tmp_path):
    _, stats, path = trained
    model = shutil.copy(path, tmp_path / "card_model.zip")
    card = write_model_card(Path(model), ENV_ID, {"control_mode": "ee_delta"}, {"bc": stats})
    assert card == tmp_path / "card_model.json" == model_card_path(tmp_path / "card_model")
    data = json.loads(card.read_text())
    assert data["env_id"] == ENV_ID and data["bc"]["steps"] == 100
    # the card's ee_delta env has 7-wide actions: the 8-wide model does not fit it
    with pytest.raises(ValueError, match="action space does not match"):
        evaluate(model, ENV_ID, episodes=1, max_steps=2)
    result = evaluate(
        model, ENV_ID, episodes=1, max_steps=2, env_kwargs={"control_mode": "joint_delta"}
    )
    assert result["env_kwargs"] == {"control_mode": "joint_delta"}
    with pytest.raises(ValueError, match="must not contain"):
        write_model_card(Path(model), ENV_ID, {}, {"env_id": "x"})


def test_evaluate_falls_back_to_sac(tmp_path):
    from stable_baselines3 import SAC

    env = gym.make(ENV_ID)
    try:
        SAC("MultiInputPolicy", env, buffer_size=10, seed=0, device="cpu").save(tmp_path / "sac")
    finally:
        env.close()
    result = evaluate(tmp_path / "sac.zip", ENV_ID, episodes=1, max_steps=3)
    assert result["results"][0]["length"] == 3


def test_evaluate_rejects_bad_input(trained, tmp_path):
    _, _, path = trained
    with pytest.raises(ValueError, match="episodes"):
        evaluate(path, ENV_ID, episodes=0)
    with pytest.raises(ValueError, match="env_id must be one of"):
        evaluate(path, "SlideGym/TopSlideGoal-v0", episodes=1)
    with pytest.raises(ValueError, match="regions, cbirrt"):
        evaluate("rrt", ENV_ID, episodes=1)
    with pytest.raises(ValueError, match="existing SB3 model"):
        evaluate(tmp_path / "missing.zip", ENV_ID, episodes=1)
    with pytest.raises(ValueError, match="max_steps"):
        evaluate(path, ENV_ID, episodes=1, max_steps=0)
    with pytest.raises(ValueError, match="observation space does not match"):
        evaluate(path, ENV_ID, episodes=1, env_kwargs={"obs_mode": "rgbd"})
    not_a_model = tmp_path / "junk.zip"
    not_a_model.write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="cannot load"):
        evaluate(not_a_model, ENV_ID, episodes=1)


@pytest.mark.slow
def test_evaluate_runs_the_planner(plan_budget):
    result = evaluate("regions", ENV_ID, episodes=1, seed=0, time_budget=plan_budget)
    assert result["agent"] == "regions" and result["episodes"] == 1
    assert result["results"][0]["success"] is True
    assert result["successes"] == 1 and result["ci95"][1] == 1.0
