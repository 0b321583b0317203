"""Demonstration datasets: collect, resume, replay, merge, export, clone and evaluate."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import gymnasium as gym
import minari
import numpy as np
import pyarrow.parquet as pq
import pytest

from slide_gym.cli import main
from slide_gym.datasets.collect import staging_dir
from slide_gym.datasets.store import dataset_metadata, load, merge_datasets, read_episodes

ENV_ID = "SlideGym/TopSlide-v0"
DATASET = "test/square-slide-v0"


def _collect(*args: str) -> int:
    return main(["collect", "--env", ENV_ID, "--time-budget", "60", *args])


@pytest.fixture(scope="module")
def collected(minari_root):
    """3 expert episodes on 2 workers."""
    assert _collect("--episodes", "3", "--workers", "2", "--dataset-id", DATASET) == 0
    return load(DATASET)


def test_collection_loads_in_minari_with_seeds_options_and_sim_state(collected):
    dataset = minari.load_dataset(DATASET)
    assert dataset.total_episodes == 3
    episodes = list(read_episodes(dataset))
    assert [e.seed for e in episodes] == [0, 1, 2]
    for e in episodes:
        assert set(e.options) == {"object", "table", "scale", "object_pose"}
        assert e.options["object"] == "square" and len(e.options["object_pose"]) == 3
        assert e.infos["sim_state"].shape == (len(e.actions) + 1, 60)
        assert e.observations["arm_qpos"].dtype == np.float32
        assert e.record["seed"] == e.seed and e.record["steps"] == len(e.actions)
    meta = dataset_metadata(dataset)
    assert meta["config"]["env_id"] == ENV_ID and meta["seeds"] == [0, 1, 2]
    assert meta["agent"]["planner"] == "regions" and "expert_params" in meta["agent"]
    assert 0.0 <= meta["expert_success_rate"] <= 1.0 and meta["code_version"]
    env = dataset.recover_environment()
    assert env.spec.kwargs["object"] == "square" and env.spec.kwargs["obs_mode"] == "state"
    env.close()


@pytest.mark.parametrize("mode", ["actions", "states"])
def test_replay_matches(collected, mode, capsys):
    assert main(["replay", DATASET, "--mode", mode, "--json"]) == 0
    results = json.loads(capsys.readouterr().out)
    assert len(results) == 3 and all(r["matched"] for r in results)
    if mode == "actions":
        assert all(r["max_error"] == 0.0 for r in results)


def test_replay_notices_a_changed_action(collected, monkeypatch):
    """The check can fail: a dataset action nudged by 0.1 no longer replays exactly."""
    from slide_gym.datasets import replay as replay_module

    real = replay_module.read_episodes

    def nudged(dataset, indices):
        for e in real(dataset, indices):
            e.actions = e.actions.copy()
            e.actions[10, 0] += 0.1
            yield e

    monkeypatch.setattr(replay_module, "read_episodes", nudged)
    results = replay_module.replay(DATASET, episodes=1)
    assert not results[0].matched and results[0].first_mismatch == 11


def test_replay_states_is_approximate_and_catches_a_wrong_state(collected, monkeypatch, capsys):
    """A step restored from another step's state (5 steps earlier, the arm still moving)
    differs beyond the measured worst case; the output calls the mode approximate."""
    from slide_gym.datasets import replay as replay_module

    real = replay_module.read_episodes

    def shifted(dataset, indices):
        for e in real(dataset, indices):
            e.infos = {**e.infos, "sim_state": e.infos["sim_state"].copy()}
            e.infos["sim_state"][20] = e.infos["sim_state"][15]
            yield e

    monkeypatch.setattr(replay_module, "read_episodes", shifted)
    assert main(["replay", DATASET, "--mode", "states", "--episodes", "1"]) == 1
    lines = capsys.readouterr().out.splitlines()
    assert "differs beyond the tolerance from step 21;" in lines[0]
    assert lines[-1].startswith("0 of 1 episodes match (states replay, approximate: ")
    assert main(["replay", DATASET, "--mode", "states", "--episodes", "1", "--json"]) == 1
    (result,) = json.loads(capsys.readouterr().out)
    assert result["approximate"] is True and result["first_mismatch"] == 21
    assert result["max_errors"]["arm_qpos"] > replay_module.STATE_TOLERANCE["arm_qpos"]


def test_more_episodes_continue_the_collection(collected):
    progress = staging_dir(DATASET) / "episodes.jsonl"
    assert _collect("--episodes", "4", "--workers", "1", "--dataset-id", DATASET) == 0
    rows = [json.loads(line) for line in progress.read_text().splitlines()]
    assert sorted(r["case"]["seed"] for r in rows) == [0, 1, 2, 3]  # 0-2 not run again
    assert [e.seed for e in read_episodes(load(DATASET))] == [0, 1, 2, 3]


def test_killed_collection_resumes_without_loss_or_duplicates(minari_root):
    dataset_id = "test/killed-v0"
    cmd = [sys.executable, "-m", "slide_gym.cli", "collect", "--env", ENV_ID]
    cmd += ["--episodes", "3", "--workers", "1", "--dataset-id", dataset_id]
    cmd += ["--time-budget", "60"]
    env = {**os.environ, "MINARI_DATASETS_PATH": str(minari_root)}
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    progress = staging_dir(dataset_id) / "episodes.jsonl"
    deadline = time.monotonic() + 300
    while not (progress.exists() and progress.read_text().count("\n") >= 1):
        assert proc.poll() is None and time.monotonic() < deadline
        time.sleep(0.1)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    finished = progress.read_text().count("\n")
    assert 1 <= finished < 3 and dataset_id not in minari.list_local_datasets()
    assert subprocess.run(cmd, env=env, capture_output=True).returncode == 0
    rows = [json.loads(line) for line in progress.read_text().splitlines()]
    assert sorted(r["case"]["seed"] for r in rows) == [0, 1, 2]
    assert [e.seed for e in read_episodes(load(dataset_id))] == [0, 1, 2]


def test_same_id_with_another_configuration_is_refused(collected, capsys):
    code = _collect("--episodes", "3", "--object", "E", "--dataset-id", DATASET)
    assert code == 2
    err = capsys.readouterr().err
    assert "another configuration" in err and "object" in err and len(err.splitlines()) == 1


def test_merge_keeps_seeds_options_and_records(collected):
    merged = merge_datasets([DATASET, DATASET], "test/merged-v0")
    episodes = list(read_episodes(merged))
    original = list(read_episodes(load(DATASET)))
    assert [e.seed for e in episodes] == [e.seed for e in original] * 2
    assert episodes[-1].options == original[-1].options
    assert episodes[0].record == original[0].record
    assert np.array_equal(episodes[-1].infos["sim_state"], original[-1].infos["sim_state"])


def test_lerobot_export_reads_back(collected, tmp_path):
    out = tmp_path / "lerobot"
    assert main(["export", DATASET, "--format", "lerobot", "--out", str(out)]) == 0
    dataset = load(DATASET)
    frames = pq.read_table(out / "data" / "chunk-000" / "file-000.parquet")
    assert frames.num_rows == dataset.total_steps
    info = json.loads((out / "meta" / "info.json").read_text())
    assert info["total_episodes"] == dataset.total_episodes and info["fps"] == 20
    episodes = pq.read_table(out / "meta" / "episodes" / "chunk-000" / "file-000.parquet")
    assert episodes.column("seed").to_pylist() == [e.seed for e in read_episodes(dataset)]
    first = next(read_episodes(dataset))
    assert np.allclose(frames.column("action")[0].as_py(), first.actions[0])


def test_bc_trains_and_evaluate_runs_the_model(collected, tmp_path, capsys):
    model = tmp_path / "bc.zip"
    assert main(["train-bc", DATASET, "--out", str(model), "--steps", "20"]) == 0
    capsys.readouterr()
    card = json.loads(model.with_suffix(".json").read_text())
    assert card["env_id"] == ENV_ID and card["dataset_id"] == DATASET
    from agents.evaluate import evaluate

    result = evaluate(model, ENV_ID, episodes=1, max_steps=5)
    assert result["episodes"] == 1 and result["mean_length"] == 5
    assert result["env_kwargs"]["object"] == "square"


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["replay", "nobody/nothing-v0"], "no local dataset"),
        (["replay", "not-an-id"], "NAMESPACE/NAME-vK"),
        (["collect", "--episodes", "0", "--dataset-id", "test/x-v0"], "--episodes"),
        (["collect", "--episodes", "2", "--workers", "0", "--dataset-id", "test/x-v0"], "workers"),
        (["train-bc", "nobody/nothing-v0", "--out", "m.zip"], "no local dataset"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(minari_root, args, needle, capsys):
    assert main(args) == 2
    err = capsys.readouterr().err
    assert needle in err and len(err.strip().splitlines()) == 1


def test_unknown_env_is_refused(minari_root, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["collect", "--env", "CartPole-v1", "--episodes", "1", "--dataset-id", "t/x-v0"])
    assert exc.value.code == 2
    assert "SlideGym/TopSlide-v0" in capsys.readouterr().err


def test_ray_backend_without_ray_is_refused(minari_root, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    args = ["--episodes", "1", "--backend", "ray", "--dataset-id", "test/ray-missing-v0"]
    assert _collect(*args) == 2
    assert "pip install 'slide-gym[ray]'" in capsys.readouterr().err


def test_ray_backend_collects_on_a_local_instance(minari_root):
    pytest.importorskip("ray")
    args = ["--episodes", "2", "--workers", "2", "--backend", "ray"]
    assert _collect(*args, "--dataset-id", "test/ray-v0") == 0
    assert [e.seed for e in read_episodes(load("test/ray-v0"))] == [0, 1]


def test_json_procedural_and_rgbd_collections_replay(minari_root, tmp_path, capsys):
    """Every kind of plate a collection takes, and lossless images."""
    card = tmp_path / "card.json"
    card.write_text(
        json.dumps({"name": "card", "vertices": [[0, 0], [0.085, 0], [0.085, 0.054], [0, 0.054]]})
    )
    runs = {
        "test/json-v0": ["--object", str(card)],
        "test/procedural-v0": ["--object", "procedural", "--seed", "3"],
        "test/rgbd-v0": ["--obs-mode", "rgbd"],
    }
    for dataset_id, extra in runs.items():
        assert (
            _collect("--episodes", "1", "--workers", "1", "--dataset-id", dataset_id, *extra) == 0
        )
        assert main(["replay", dataset_id]) == 0
    capsys.readouterr()
    json_episode = next(read_episodes(load("test/json-v0")))
    assert json_episode.options["object"] == str(card.resolve())
    procedural = next(read_episodes(load("test/procedural-v0")))
    assert procedural.seed == 3 and procedural.options["object"] == "procedural"
    rgbd = load("test/rgbd-v0")
    image = next(read_episodes(rgbd)).observations["scene_rgb"]
    assert image.dtype == np.uint8 and image.shape[1:] == (128, 128, 3)
    assert not rgbd.storage.metadata["jpeg_encoding"]


def test_planner_param_overrides_are_checked_and_kept_in_the_identity():
    from slide_gym.datasets.config import CollectConfig

    config = CollectConfig(env_id="SlideGym/TopSlide-v0", planner_params={"u_star": 0.03})
    assert config.agent_kwargs() == {"u_star": 0.03}
    again = CollectConfig.from_json(config.to_json())
    assert again == config and again.differences(CollectConfig(env_id=config.env_id))
    assert "planner_params" not in CollectConfig(env_id=config.env_id).to_json()  # old ids
    for bad, needle in [({"bogus": 1.0}, "allowed: u_star"), ({"u_star": -1.0}, "positive")]:
        with pytest.raises(ValueError, match=needle):
            CollectConfig(env_id=config.env_id, planner_params=bad)


def test_expert_param_overrides_are_checked_and_kept_in_the_identity():
    from slide_gym.datasets.config import CollectConfig

    config = CollectConfig(env_id="SlideGym/TopSlide-v0", expert_params={"stop_overhang": 0.035})
    assert config.agent_kwargs()["params"].stop_overhang == 0.035
    again = CollectConfig.from_json(config.to_json())
    assert again == config and again.differences(CollectConfig(env_id=config.env_id))
    assert "expert_params" not in CollectConfig(env_id=config.env_id).to_json()  # old ids
    for bad, needle in [
        ({"stop_overhng": 0.03}, "allowed: approach_speed"),
        ({"stop_overhang": -0.03}, "finite positive"),
        ({"slide_speed": "fast"}, "must be a number"),
    ]:
        with pytest.raises(ValueError, match=needle):
            CollectConfig(env_id=config.env_id, expert_params=bad)


def test_physics_settings_reach_the_env_and_are_kept_in_the_identity():
    from slide_gym.datasets.config import CollectConfig

    config = CollectConfig(env_id="SlideGym/TopSlide-v0", physics={"friction_anchor": 1.0})
    assert config.physics == {"friction_anchor": True}
    assert config.env_kwargs()["physics"] == {"friction_anchor": True}
    env = gym.make(config.env_id, **config.env_kwargs())
    assert env.unwrapped.sim.settings.friction_anchor
    env.close()
    again = CollectConfig.from_json(config.to_json())
    assert again == config and again.differences(CollectConfig(env_id=config.env_id))
    plain = CollectConfig(env_id=config.env_id)
    assert "physics" not in plain.to_json() and "physics" not in plain.env_kwargs()  # old ids
    with pytest.raises(ValueError, match="allowed: solver_iterations"):
        CollectConfig(env_id=config.env_id, physics={"anchor": 1})


def test_the_collecting_experts_changed_defaults_come_back_from_the_metadata(collected):
    """A dataset collected before a default changed gives back the expert that collected it:
    what its metadata recorded beyond the config's own overrides, which still win."""
    from agents.params import ExpertParams
    from slide_gym.datasets.config import CollectConfig

    meta = dataset_metadata(collected)
    assert CollectConfig.from_metadata(meta) == CollectConfig.from_json(meta["config"])
    older = json.loads(json.dumps(meta))
    older["agent"]["expert_params"] |= {"slide_speed": 0.05, "settle_s": 0.3, "max_replans": 1}
    older["config"]["expert_params"] = {"settle_s": 0.2}
    config = CollectConfig.from_metadata(older)
    assert config.expert_params == {"slide_speed": 0.05, "max_replans": 1.0, "settle_s": 0.2}
    params = config.agent_kwargs()["params"]
    assert (params.slide_speed, params.settle_s, params.max_replans) == (0.05, 0.2, 1)
    assert params.grasp_posture == ExpertParams().grasp_posture
