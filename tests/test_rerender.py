"""``slide-gym replay ID --obs-mode MODE --save-as NEW_ID``: a dataset re-rendered in another
observation mode, its state entries, actions and infos the source's bit for bit; resumable;
bad input."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

from slide_gym.cli import main
from slide_gym.cli.data import OBS_MODES as CLI_OBS_MODES
from slide_gym.datasets import rerender as rerender_module
from slide_gym.datasets.collect import staging_dir
from slide_gym.datasets.config import CollectConfig
from slide_gym.datasets.recording import (
    RecordedEpisode,
    reset_options,
    stack_infos,
    step_info,
)
from slide_gym.datasets.store import (
    build_dataset,
    dataset_metadata,
    load,
    local_dataset_ids,
    read_episodes,
)
from slide_gym.envs.observation import OBS_MODES, POINT_KEYS
from slide_gym.version import code_version

ENV_ID = "SlideGym/TopSlide-v0"
SOURCE = "test/random-actions-v0"
STEPS = 12


def _random_episode(env: gym.Env, config: CollectConfig, seed: int) -> RecordedEpisode:
    """``STEPS`` seeded random actions, recorded as ``collect`` records the expert's."""
    env.reset(seed=seed)
    options = reset_options(env, config)
    obs, info = env.reset(seed=seed, options=options)
    observations, infos, steps = [obs], [step_info(info, env.unwrapped.get_state())], []
    rng = np.random.default_rng(seed)
    for _ in range(STEPS):
        action = rng.uniform(-1, 1, 8).astype(np.float32)
        obs, reward, term, trunc, info = env.step(action)
        steps.append((action, reward, term, trunc))
        observations.append(obs)
        infos.append(step_info(info, env.unwrapped.get_state()))
    return RecordedEpisode(
        seed=seed,
        options=options,
        observations={k: np.stack([o[k] for o in observations]) for k in observations[0]},
        actions=np.stack([s[0] for s in steps]),
        rewards=np.array([s[1] for s in steps], dtype=np.float64),
        terminations=np.array([s[2] for s in steps], dtype=bool),
        truncations=np.array([s[3] for s in steps], dtype=bool),
        infos=stack_infos(infos),
        record={"seed": seed, "steps": STEPS, "success": False},
    )


def _make_dataset(dataset_id: str, seeds: list[int], nudge: bool = False) -> None:
    """A state dataset of random-action episodes (``nudge``: one recorded joint angle off)."""
    config = CollectConfig(env_id=ENV_ID, object="A", table="square")
    env = gym.make(ENV_ID, **config.env_kwargs())
    try:
        episodes = [_random_episode(env, config, s) for s in seeds]
        if nudge:
            episodes[0].observations["arm_qpos"][5, 2] += 1e-6
        meta = {"config": config.to_json(), "env_kwargs": config.env_kwargs(), "seeds": seeds}
        meta["code_version"] = code_version()
        build_dataset(dataset_id, episodes, env, meta, algorithm_name="random actions")
    finally:
        env.close()


@pytest.fixture(scope="module")
def source(minari_root) -> str:
    _make_dataset(SOURCE, [0, 1])
    return SOURCE


def _replay(*args: str) -> int:
    return main(["replay", *args])


def _check_same_episodes(source_id: str, new_id: str, count: int) -> list[RecordedEpisode]:
    """The re-rendered episodes, after checking that all but the observation's extra
    entries are the source's, bit for bit."""
    old = list(read_episodes(load(source_id)))[:count]
    new = list(read_episodes(load(new_id)))
    assert len(new) == count
    for a, b in zip(old, new, strict=True):
        assert (a.seed, a.options, a.record) == (b.seed, b.options, b.record)
        for name in ("actions", "rewards", "terminations", "truncations"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        np.testing.assert_array_equal(a.infos["sim_state"], b.infos["sim_state"])
        for key, value in a.observations.items():
            assert b.observations[key].dtype == value.dtype
            np.testing.assert_array_equal(b.observations[key], value)
    return new


def test_pointcloud_rerender_keeps_the_source_and_names_it(source, capsys) -> None:
    new_id = "test/random-actions-pointcloud-v0"
    args = ["--obs-mode", "pointcloud", "--save-as", new_id, "--workers", "2"]
    assert _replay(source, *args, "--image-size", "32", "24", "--num-points", "64") == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["episodes"] == 2 and summary["steps"] == 2 * STEPS
    episodes = _check_same_episodes(source, new_id, 2)
    obs = episodes[0].observations
    assert obs["pointcloud_xyz"].shape == (STEPS + 1, 64, 3)
    assert obs["pointcloud_segmentation"].dtype == np.uint8
    dataset = load(new_id)
    meta = dataset_metadata(dataset)
    assert meta["rerendered_from"]["dataset_id"] == source
    assert meta["rerendered_from"]["obs_mode"] == "state"
    assert meta["config"]["obs_mode"] == "pointcloud" and meta["seeds"] == [0, 1]
    env = dataset.recover_environment()
    try:
        assert env.spec.kwargs["num_points"] == 64 and env.spec.kwargs["render_width"] == 32
        assert set(POINT_KEYS) <= set(env.observation_space.spaces)
    finally:
        env.close()
    # The point cloud is seeded from the reset: the new dataset replays itself exactly.
    assert _replay(new_id) == 0


def test_rgbd_rerender_resumes_after_an_interrupt(source, monkeypatch, capsys) -> None:
    new_id = "test/random-actions-rgbd-v0"
    args = [source, "--obs-mode", "rgbd", "--save-as", new_id, "--image-size", "16", "12"]
    real = rerender_module.rerender_case
    calls: list[int] = []

    def interrupted(case: dict) -> dict:
        calls.append(case["episode"])
        if case["episode"] == 1:
            raise KeyboardInterrupt
        return real(case)

    monkeypatch.setattr(rerender_module, "rerender_case", interrupted)
    assert _replay(*args, "--workers", "1") == 130
    progress = staging_dir(new_id) / "episodes.jsonl"
    assert [json.loads(line)["case"]["episode"] for line in progress.open()] == [0]
    monkeypatch.undo()
    assert _replay(*args, "--workers", "1") == 0  # episode 0 is not run again
    assert [json.loads(line)["case"]["episode"] for line in progress.open()] == [0, 1]
    capsys.readouterr()
    episodes = _check_same_episodes(source, new_id, 2)
    assert episodes[1].observations["wrist_rgb"].shape == (STEPS + 1, 12, 16, 3)
    assert episodes[1].observations["scene_depth"].dtype == np.float32


def test_episodes_takes_the_first_k(source, capsys) -> None:
    new_id = "test/random-actions-first-v0"
    args = ["--obs-mode", "state", "--save-as", new_id, "--episodes", "1", "--workers", "1"]
    assert _replay(source, *args) == 0
    assert json.loads(capsys.readouterr().out)["episodes"] == 1
    (episode,) = _check_same_episodes(source, new_id, 1)
    assert episode.seed == 0


def test_a_replay_that_differs_from_the_record_writes_nothing(minari_root, capsys) -> None:
    _make_dataset("test/nudged-v0", [0], nudge=True)
    args = ["test/nudged-v0", "--obs-mode", "pointcloud", "--save-as", "test/nudged-pc-v0"]
    assert _replay(*args, "--workers", "1", "--num-points", "16") == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]  # after the progress bar
    assert last.startswith("slide-gym replay: error: 1 of 1 episodes")
    assert "episode 0 at step 5 (arm_qpos)" in last
    assert "test/nudged-pc-v0" not in local_dataset_ids()


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--obs-mode", "rgb", "--save-as", "test/x-v0"], "did you mean 'rgbd'"),
        (["--obs-mode", "rgbd", "--save-as", SOURCE], "exists already"),
        (["--obs-mode", "rgbd", "--save-as", "not-an-id"], "NAMESPACE/NAME-vK"),
        (["--obs-mode", "rgbd"], "go together"),
        (["--save-as", "test/x-v0", "--workers", "2"], "go together"),
        (["--obs-mode", "rgbd", "--save-as", "test/x-v0", "--mode", "states"], "--mode"),
        (["--obs-mode", "rgbd", "--save-as", "test/x-v0", "--num-points", "9"], "num_points"),
        (["--obs-mode", "state", "--save-as", "test/x-v0", "--workers", "0"], "workers"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(source, args, needle, capsys) -> None:
    assert _replay(source, *args) == 2
    err = capsys.readouterr().err
    assert needle in err and len(err.strip().splitlines()) == 1
    assert not staging_dir("test/x-v0").exists()


def test_the_cli_offers_every_observation_mode() -> None:
    assert CLI_OBS_MODES == OBS_MODES
