"""LeRobot v3.0 export of a small Minari dataset, read back with pyarrow."""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import minari  # noqa: E402
import numpy as np
import pyarrow as pa  # noqa: E402
import pyarrow.parquet as pq  # noqa: E402
import pytest
from minari.data_collector import EpisodeBuffer  # noqa: E402

import slide_gym  # noqa: E402,F401  (registers the environments)
from slide_gym.datasets import lerobot  # noqa: E402
from slide_gym.datasets.lerobot import export_lerobot  # noqa: E402

LENGTHS = (4, 6, 5)
SEEDS = (10, 11, 12)
FPS = 20.0


def _buffer(
    obs_space: gym.spaces.Dict, act_space: gym.spaces.Box, steps: int, seed: int
) -> EpisodeBuffer:
    """One episode of sampled observations/actions; success only on the last step."""
    samples = [obs_space.sample() for _ in range(steps + 1)]
    observations = {k: np.stack([s[k] for s in samples]) for k in obs_space.spaces}
    success = np.zeros(steps + 1, dtype=bool)
    success[-1] = True
    return EpisodeBuffer(
        id=None,
        seed=seed,
        options=None,
        observations=observations,
        actions=np.stack([act_space.sample() for _ in range(steps)]),
        rewards=np.linspace(-1.0, 1.0, steps),
        terminations=np.arange(steps) == steps - 1,
        truncations=np.zeros(steps, dtype=bool),
        infos={"is_success": success},
    )


@pytest.fixture()
def built(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> tuple[Any, list[EpisodeBuffer]]:
    """A 3-episode Minari dataset (lengths 4, 6, 5; seeds 10, 11, 12) in tmp_path."""
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    env = gym.make("SlideGym/TopSlide-v0")
    obs_space, act_space = env.observation_space, env.action_space
    env.close()
    obs_space.seed(0)
    act_space.seed(0)
    buffers = [_buffer(obs_space, act_space, n, s) for n, s in zip(LENGTHS, SEEDS, strict=True)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # missing author / permalink notes
        dataset = minari.create_dataset_from_buffers(
            dataset_id="test/lerobot-v0",
            buffer=buffers,
            env=env.spec,
            observation_space=obs_space,
            action_space=act_space,
            algorithm_name="random",
            jpeg_encoding=False,
        )
    return dataset, buffers


def test_export_round_trip(built: tuple[Any, list[EpisodeBuffer]], tmp_path: Path) -> None:
    dataset, buffers = built
    out = tmp_path / "lerobot"
    result = export_lerobot(dataset, out, task="slide the plate off the table", fps=FPS)
    total = sum(LENGTHS)
    assert result == {"episodes": 3, "frames": total}

    data = pq.read_table(out / "data" / "chunk-000" / "file-000.parquet")
    assert data.num_rows == total
    dim = sum(int(np.prod(b.shape)) for b in dataset.observation_space.spaces.values())
    for name, width in (("observation.state", dim), ("action", 8)):
        kind = data.schema.field(name).type
        assert pa.types.is_fixed_size_list(kind)
        assert (kind.list_size, kind.value_type) == (width, pa.float32())
    cols = data.to_pydict()
    assert cols["index"] == list(range(total))
    assert cols["task_index"] == [0] * total
    assert cols["episode_index"] == [e for e, n in enumerate(LENGTHS) for _ in range(n)]
    assert cols["frame_index"] == [t for n in LENGTHS for t in range(n)]
    np.testing.assert_allclose(cols["timestamp"][:4], np.arange(4) / FPS, rtol=1e-6)
    # done and success only on each episode's last frame
    last = np.cumsum(LENGTHS) - 1
    assert np.flatnonzero(cols["next.done"]).tolist() == last.tolist()
    assert np.flatnonzero(cols["next.success"]).tolist() == last.tolist()
    np.testing.assert_allclose(cols["next.reward"][:4], np.linspace(-1, 1, 4), rtol=1e-6)

    first_obs = buffers[0].observations
    expected = np.concatenate([np.ravel(first_obs[k][0]) for k in sorted(first_obs)])
    np.testing.assert_array_equal(np.asarray(cols["observation.state"][0], np.float32), expected)
    second_ep_obs = buffers[1].observations
    expected = np.concatenate([np.ravel(second_ep_obs[k][2]) for k in sorted(second_ep_obs)])
    np.testing.assert_array_equal(np.asarray(cols["observation.state"][6], np.float32), expected)
    np.testing.assert_allclose(cols["action"][4], buffers[1].actions[0], rtol=1e-6)

    episodes = pq.read_table(out / "meta" / "episodes" / "chunk-000" / "file-000.parquet")
    ep = episodes.to_pydict()
    assert ep["episode_index"] == [0, 1, 2]
    assert ep["length"] == list(LENGTHS)
    assert ep["seed"] == list(SEEDS)
    assert ep["tasks"] == [["slide the plate off the table"]] * 3
    assert ep["dataset_from_index"] == [0, 4, 10]
    assert ep["dataset_to_index"] == [4, 10, 15]
    assert ep["data/chunk_index"] == [0, 0, 0]
    assert ep["data/file_index"] == [0, 0, 0]

    tasks = pq.read_table(out / "meta" / "tasks.parquet").to_pydict()
    assert tasks == {"task_index": [0], "task": ["slide the plate off the table"]}

    info = json.loads((out / "meta" / "info.json").read_text())
    assert info["codebase_version"] == "v3.0"
    assert info["total_episodes"] == 3
    assert info["total_frames"] == total
    assert info["total_tasks"] == 1
    assert info["fps"] == 20
    assert info["robot_type"] == "wam_t42"
    assert info["splits"] == {"train": "0:3"}
    state = info["features"]["observation.state"]
    assert state["shape"] == [dim]
    assert state["names"][:2] == ["arm_qpos_0", "arm_qpos_1"]
    assert len(state["names"]) == dim
    assert set(info["features"]) == set(data.column_names)

    stats = json.loads((out / "meta" / "stats.json").read_text())
    for key, width in (("observation.state", dim), ("action", 8), ("next.reward", 1)):
        for stat in ("min", "max", "mean", "std"):
            assert len(stats[key][stat]) == width
        assert stats[key]["count"] == [total]
    action = np.concatenate([b.actions for b in buffers]).astype(np.float32)
    np.testing.assert_allclose(stats["action"]["mean"], action.mean(axis=0), rtol=1e-5)
    np.testing.assert_allclose(stats["action"]["std"], action.std(axis=0), rtol=1e-5)


def test_files_roll_over_between_episodes(
    built: tuple[Any, list[EpisodeBuffer]], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    dataset, _ = built
    monkeypatch.setattr(lerobot, "_ROWS_PER_FILE", 5)
    out = tmp_path / "split"
    export_lerobot(dataset, out, task="t", fps=10)
    ep = pq.read_table(out / "meta" / "episodes" / "chunk-000" / "file-000.parquet").to_pydict()
    assert ep["data/file_index"] == [0, 0, 1]  # 4 rows, then 10 (>= 5): new file
    first = pq.read_table(out / "data" / "chunk-000" / "file-000.parquet")
    second = pq.read_table(out / "data" / "chunk-000" / "file-001.parquet")
    assert (first.num_rows, second.num_rows) == (10, 5)
    assert second.column("index").to_pylist() == list(range(10, 15))


def test_refuses_bad_input(built: tuple[Any, list[EpisodeBuffer]], tmp_path: Path) -> None:
    dataset, _ = built
    busy = tmp_path / "busy"
    busy.mkdir()
    (busy / "keep.txt").write_text("x")
    with pytest.raises(ValueError, match="not empty; pick a new folder"):
        export_lerobot(dataset, busy, task="t", fps=10)
    assert [p.name for p in busy.iterdir()] == ["keep.txt"]
    for fps in (0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="fps"):
            export_lerobot(dataset, tmp_path / "a", task="t", fps=fps)
    assert not (tmp_path / "a").exists()
    # an existing empty folder is fine
    empty = tmp_path / "empty"
    empty.mkdir()
    assert export_lerobot(dataset, empty, task="t", fps=10)["frames"] == sum(LENGTHS)


def test_refuses_non_dict_space_and_no_episodes(
    built: tuple[Any, list[EpisodeBuffer]], tmp_path: Path
) -> None:
    with pytest.raises(ValueError, match="Dict observation space"):
        lerobot.state_layout(gym.spaces.Box(-1, 1, (3,)))
    with pytest.raises(ValueError, match="Box"):
        lerobot.state_layout(gym.spaces.Dict({"a": gym.spaces.Discrete(2)}))
    image_only = gym.spaces.Dict({"rgb": gym.spaces.Box(0, 255, (4, 4, 3), np.uint8)})
    with pytest.raises(ValueError, match="no 1-D float"):
        lerobot.state_layout(image_only)
    mixed = gym.spaces.Dict(
        {"rgb": gym.spaces.Box(0, 255, (4, 4, 3), np.uint8), "b": gym.spaces.Box(0, 1, (2,))}
    )
    assert lerobot.state_layout(mixed) == [("b", 2)]

    dataset, _ = built
    empty = dataset.filter_episodes(lambda ep: False)
    with pytest.raises(ValueError, match="no episodes"):
        export_lerobot(empty, tmp_path / "none", task="t", fps=10)
