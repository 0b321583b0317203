"""Export a Minari dataset to the LeRobotDataset v3.0 on-disk layout (parquet + JSON, no videos).

Only pyarrow is needed; the ``lerobot`` package is not imported. Each Minari step becomes one
frame: the observation before the step, the action taken, and the reward / done / success that
the step produced (LeRobot's ``next.*`` columns).
"""

from __future__ import annotations

import json
import math
import os
import shutil
from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import chain
from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

if TYPE_CHECKING:
    import minari

__all__ = ["check_export_folder", "export_lerobot", "state_layout"]

CODEBASE_VERSION = "v3.0"
CHUNKS_SIZE = 1000  # files per chunk folder, as LeRobot
DATA_FILES_SIZE_IN_MB = 100
VIDEO_FILES_SIZE_IN_MB = 500
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
EPISODES_PATH = "meta/episodes/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"

# A new data file is started before an episode once the current one holds this many rows.
# Episodes never straddle two files. Module-level so tests can lower it.
_ROWS_PER_FILE = 1_000_000
# Frames buffered in memory before they are written out as one parquet row group.
_ROWS_PER_GROUP = 65_536


def state_layout(observation_space: gym.spaces.Space) -> list[tuple[str, int]]:
    """Return the (key, size) pairs that make up ``observation.state``, in concatenation order.

    Keys are sorted; only float Boxes of 0-D or 1-D shape are kept (images and other Boxes are
    skipped). Raises ValueError for anything but a Dict of Boxes, or when no key qualifies.
    """
    if not isinstance(observation_space, gym.spaces.Dict):
        raise ValueError(
            "LeRobot export needs a Dict observation space of Box entries, got "
            f"{type(observation_space).__name__}"
        )
    not_box = [k for k, s in observation_space.spaces.items() if not isinstance(s, gym.spaces.Box)]
    if not_box:
        raise ValueError(
            f"LeRobot export needs every observation entry to be a Box; not a Box: {not_box}"
        )
    layout: list[tuple[str, int]] = []
    for key in sorted(observation_space.spaces):
        space = observation_space.spaces[key]
        if np.issubdtype(space.dtype, np.floating) and len(space.shape) <= 1:
            layout.append((key, int(np.prod(space.shape, dtype=np.int64))))
    if not layout:
        raise ValueError("the observation space has no 1-D float Box entry to build a state from")
    return layout


def _state_names(layout: Sequence[tuple[str, int]]) -> list[str]:
    """Name each state dimension ``<key>_<i>``."""
    return [f"{key}_{i}" for key, size in layout for i in range(size)]


@dataclass
class _RunningStats:
    """Per-dimension min / max / mean / std over batches (Chan's parallel variance update)."""

    dim: int
    count: int = 0
    mean: np.ndarray = field(init=False)
    m2: np.ndarray = field(init=False)
    low: np.ndarray = field(init=False)
    high: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.mean = np.zeros(self.dim, dtype=np.float64)
        self.m2 = np.zeros(self.dim, dtype=np.float64)
        self.low = np.full(self.dim, np.inf, dtype=np.float64)
        self.high = np.full(self.dim, -np.inf, dtype=np.float64)

    def update(self, batch: np.ndarray) -> None:
        """Fold a (n, dim) batch into the totals."""
        x = np.asarray(batch, dtype=np.float64).reshape(-1, self.dim)
        n = x.shape[0]
        if n == 0:
            return
        b_mean = x.mean(axis=0)
        b_m2 = ((x - b_mean) ** 2).sum(axis=0)
        total = self.count + n
        delta = b_mean - self.mean
        self.mean = self.mean + delta * (n / total)
        self.m2 = self.m2 + b_m2 + delta**2 * (self.count * n / total)
        self.count = total
        self.low = np.minimum(self.low, x.min(axis=0))
        self.high = np.maximum(self.high, x.max(axis=0))

    def to_json(self) -> dict[str, list[float] | list[int]]:
        """LeRobot stats.json entry (population std; count is a one-element list)."""
        std = np.sqrt(np.maximum(self.m2 / max(self.count, 1), 0.0))
        return {
            "min": self.low.tolist(),
            "max": self.high.tolist(),
            "mean": self.mean.tolist(),
            "std": std.tolist(),
            "count": [self.count],
        }


class _DataWriter:
    """Streams frames into data/chunk-XXX/file-YYY.parquet, rolling files between episodes."""

    def __init__(self, root: Path, schema: pa.Schema) -> None:
        self.root = root
        self.schema = schema
        self.file_number = -1  # running number over all files; chunk = number // CHUNKS_SIZE
        self.rows_in_file = 0
        self._writer: pq.ParquetWriter | None = None
        self._pending: list[pa.Table] = []
        self._pending_rows = 0

    @property
    def chunk_index(self) -> int:
        """Chunk folder of the current file."""
        return self.file_number // CHUNKS_SIZE

    @property
    def file_index(self) -> int:
        """Index of the current file inside its chunk."""
        return self.file_number % CHUNKS_SIZE

    def start_episode(self) -> None:
        """Open the first file, or a new one when the current file is full."""
        if self._writer is None or self.rows_in_file >= _ROWS_PER_FILE:
            self._close_file()
            self.file_number += 1
            path = self.root / DATA_PATH.format(
                chunk_index=self.chunk_index, file_index=self.file_index
            )
            path.parent.mkdir(parents=True, exist_ok=True)
            self._writer = pq.ParquetWriter(path, self.schema)
            self.rows_in_file = 0

    def write(self, table: pa.Table) -> None:
        """Queue one episode's frames; flush a row group once enough rows are queued."""
        self._pending.append(table)
        self._pending_rows += table.num_rows
        self.rows_in_file += table.num_rows
        if self._pending_rows >= _ROWS_PER_GROUP:
            self._flush()

    def _flush(self) -> None:
        if self._writer is not None and self._pending_rows > 0:
            self._writer.write_table(pa.concat_tables(self._pending))
        self._pending = []
        self._pending_rows = 0

    def _close_file(self) -> None:
        self._flush()
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    def close(self) -> None:
        """Flush and close the open file."""
        self._close_file()


def check_export_folder(out: Path) -> None:
    """Refuse an output path that is a file, a non-empty folder or inside Minari's folder."""
    import minari

    root = Path(minari.storage.get_dataset_path()).resolve()
    if out.resolve() == root or root in out.resolve().parents:
        raise ValueError(
            f"output folder {out} is inside the Minari datasets folder {root} "
            "(MINARI_DATASETS_PATH, default ~/.minari/datasets), where Minari takes every "
            "folder for a dataset; export to a folder outside it"
        )
    if out.exists():
        if not out.is_dir():
            raise ValueError(f"output path {out} exists and is not a folder; pick a new folder")
        if any(out.iterdir()):
            raise ValueError(
                f"output folder {out} already exists and is not empty; pick a new folder "
                "(the export never overwrites or merges into existing files)"
            )


def _fixed_list(values: np.ndarray, width: int) -> pa.FixedSizeListArray:
    """(n, width) float array -> arrow fixed_size_list<float32>[width]."""
    flat = pa.array(np.ascontiguousarray(values, dtype=np.float32).reshape(-1))
    return pa.FixedSizeListArray.from_arrays(flat, width)


def _column_1d(name: str, values: Any, rows: int) -> np.ndarray:
    """Cast a per-step Minari array to 1-D and check it has ``rows`` entries."""
    arr = np.asarray(values).reshape(-1)
    if arr.shape[0] != rows:
        raise ValueError(f"episode field {name!r} has {arr.shape[0]} entries, expected {rows}")
    return arr


def _feature(dtype: str, shape: list[int], names: list[str] | None = None) -> dict[str, Any]:
    """One info.json feature entry."""
    return {"dtype": dtype, "shape": shape, "names": names}


def export_lerobot(
    dataset: minari.MinariDataset,
    out: Path,
    *,
    task: str,
    fps: float,
    robot_type: str = "wam_t42",
) -> dict[str, int]:
    """Write ``dataset`` to ``out`` in the LeRobotDataset v3.0 layout; return episode/frame counts.

    ``observation.state`` concatenates the 1-D float observation keys in sorted order. ``out``
    must not exist or be an empty folder. Files are built in a sibling temporary folder and
    moved into place at the end, so a failed export leaves nothing behind.
    """
    out = Path(out)
    try:
        fps_value = float(fps)
    except (TypeError, ValueError):
        fps_value = math.nan
    if not math.isfinite(fps_value) or fps_value <= 0:
        raise ValueError(f"fps must be a positive finite number, got {fps!r}")
    if not isinstance(task, str) or not task.strip():
        raise ValueError("task must be a non-empty description string")
    check_export_folder(out)
    n_episodes = int(dataset.total_episodes)
    if n_episodes == 0:
        raise ValueError("the dataset has no episodes; nothing to export")
    layout = state_layout(dataset.observation_space)
    action_space = dataset.action_space
    if not isinstance(action_space, gym.spaces.Box):
        raise ValueError(
            f"LeRobot export needs a Box action space, got {type(action_space).__name__}"
        )
    state_dim = sum(size for _, size in layout)
    action_dim = int(np.prod(action_space.shape, dtype=np.int64))

    episode_ids = [int(i) for i in dataset.episode_indices]
    metadata = {
        eid: meta
        for eid, meta in zip(
            episode_ids, list(dataset.storage.get_episode_metadata(episode_ids)), strict=True
        )
    }

    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.parent / f".{out.name}.partial-{os.getpid()}"
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir()
    try:
        totals = _write_all(
            dataset,
            tmp,
            layout,
            state_dim,
            action_dim,
            metadata,
            task=task,
            fps=fps_value,
            robot_type=robot_type,
        )
        check_export_folder(out)  # still free?
        if out.exists():
            out.rmdir()
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return totals


def _write_all(
    dataset: minari.MinariDataset,
    root: Path,
    layout: list[tuple[str, int]],
    state_dim: int,
    action_dim: int,
    metadata: dict[int, dict[str, Any]],
    *,
    task: str,
    fps: float,
    robot_type: str,
) -> dict[str, int]:
    """Stream every episode into ``root`` and write the meta files; return the counts."""
    episodes = iter(dataset.iterate_episodes())
    first = next(episodes)
    has_success = isinstance(first.infos, dict) and "is_success" in first.infos

    fields = [
        pa.field("observation.state", pa.list_(pa.float32(), state_dim)),
        pa.field("action", pa.list_(pa.float32(), action_dim)),
        pa.field("timestamp", pa.float32()),
        pa.field("frame_index", pa.int64()),
        pa.field("episode_index", pa.int64()),
        pa.field("index", pa.int64()),
        pa.field("task_index", pa.int64()),
        pa.field("next.reward", pa.float32()),
        pa.field("next.done", pa.bool_()),
    ]
    if has_success:
        fields.append(pa.field("next.success", pa.bool_()))
    schema = pa.schema(fields)

    state_stats = _RunningStats(state_dim)
    action_stats = _RunningStats(action_dim)
    reward_stats = _RunningStats(1)
    rows: dict[str, list[Any]] = {
        "episode_index": [],
        "tasks": [],
        "length": [],
        "data/chunk_index": [],
        "data/file_index": [],
        "dataset_from_index": [],
        "dataset_to_index": [],
        "meta/episodes/chunk_index": [],
        "meta/episodes/file_index": [],
        "seed": [],
    }

    writer = _DataWriter(root, schema)
    global_index = 0
    try:
        for ep_number, ep in enumerate(chain([first], episodes)):
            steps = int(np.asarray(ep.rewards).reshape(-1).shape[0])
            state = _episode_state(ep.observations, layout, steps, ep.id)
            actions = np.asarray(ep.actions, dtype=np.float32).reshape(steps, -1)
            if actions.shape[1] != action_dim:
                raise ValueError(
                    f"episode {ep.id}: actions have width {actions.shape[1]}, expected {action_dim}"
                )
            reward = _column_1d("rewards", ep.rewards, steps).astype(np.float32)
            done = _column_1d("terminations", ep.terminations, steps).astype(bool) | _column_1d(
                "truncations", ep.truncations, steps
            ).astype(bool)
            frame = np.arange(steps, dtype=np.int64)
            columns: list[pa.Array] = [
                _fixed_list(state, state_dim),
                _fixed_list(actions, action_dim),
                pa.array((frame / float(fps)).astype(np.float32)),
                pa.array(frame),
                pa.array(np.full(steps, ep_number, dtype=np.int64)),
                pa.array(global_index + frame),
                pa.array(np.zeros(steps, dtype=np.int64)),
                pa.array(reward),
                pa.array(done),
            ]
            if has_success:
                infos = ep.infos if isinstance(ep.infos, dict) else {}
                if "is_success" not in infos:
                    raise ValueError(
                        f"episode {ep.id} has no infos['is_success'] but the first episode does"
                    )
                success = _column_1d("infos['is_success']", infos["is_success"], steps + 1)
                columns.append(pa.array(success[1:].astype(bool)))

            writer.start_episode()
            writer.write(pa.Table.from_arrays(columns, schema=schema))
            state_stats.update(state)
            action_stats.update(actions)
            reward_stats.update(reward)

            seed = metadata.get(int(ep.id), {}).get("seed")
            rows["episode_index"].append(ep_number)
            rows["tasks"].append([task])
            rows["length"].append(steps)
            rows["data/chunk_index"].append(writer.chunk_index)
            rows["data/file_index"].append(writer.file_index)
            rows["dataset_from_index"].append(global_index)
            rows["dataset_to_index"].append(global_index + steps)
            rows["meta/episodes/chunk_index"].append(0)
            rows["meta/episodes/file_index"].append(0)
            rows["seed"].append(-1 if seed is None else int(seed))
            global_index += steps
    finally:
        writer.close()

    n_episodes = len(rows["episode_index"])
    _write_episodes(root, rows)
    meta = root / "meta"
    pq.write_table(
        pa.table(
            {
                "task_index": pa.array([0], pa.int64()),
                "task": pa.array([task], pa.string()),
            }
        ),
        meta / "tasks.parquet",
    )
    stats = {
        "observation.state": state_stats.to_json(),
        "action": action_stats.to_json(),
        "next.reward": reward_stats.to_json(),
    }
    (meta / "stats.json").write_text(json.dumps(stats, indent=2) + "\n")

    features = {
        "observation.state": _feature("float32", [state_dim], _state_names(layout)),
        "action": _feature("float32", [action_dim], [f"action_{i}" for i in range(action_dim)]),
        "timestamp": _feature("float32", [1]),
        "frame_index": _feature("int64", [1]),
        "episode_index": _feature("int64", [1]),
        "index": _feature("int64", [1]),
        "task_index": _feature("int64", [1]),
        "next.reward": _feature("float32", [1]),
        "next.done": _feature("bool", [1]),
    }
    if has_success:
        features["next.success"] = _feature("bool", [1])
    info = {
        "codebase_version": CODEBASE_VERSION,
        "robot_type": robot_type,
        "total_episodes": n_episodes,
        "total_frames": global_index,
        "total_tasks": 1,
        "chunks_size": CHUNKS_SIZE,
        "data_files_size_in_mb": DATA_FILES_SIZE_IN_MB,
        "video_files_size_in_mb": VIDEO_FILES_SIZE_IN_MB,
        "fps": int(fps) if float(fps).is_integer() else float(fps),
        "splits": {"train": f"0:{n_episodes}"},
        "data_path": DATA_PATH,
        "video_path": None,
        "features": features,
    }
    (meta / "info.json").write_text(json.dumps(info, indent=2) + "\n")
    return {"episodes": n_episodes, "frames": global_index}


def _episode_state(
    observations: Any, layout: Sequence[tuple[str, int]], steps: int, episode_id: Any
) -> np.ndarray:
    """(steps, D) float32 state: obs_0 .. obs_{T-1}, layout keys concatenated in order."""
    if not isinstance(observations, dict):
        raise ValueError(f"episode {episode_id}: observations are not a dict")
    parts: list[np.ndarray] = []
    for key, size in layout:
        arr = np.asarray(observations[key])
        if arr.shape[0] != steps + 1:
            raise ValueError(
                f"episode {episode_id}: observation {key!r} has {arr.shape[0]} rows, "
                f"expected {steps + 1} (steps + 1)"
            )
        parts.append(arr[:steps].reshape(steps, size).astype(np.float32))
    return np.concatenate(parts, axis=1)


def _write_episodes(root: Path, rows: dict[str, list[Any]]) -> None:
    """Write meta/episodes/chunk-000/file-000.parquet (one row per episode)."""
    int_keys = [k for k in rows if k != "tasks"]
    arrays = {k: pa.array(rows[k], pa.int64()) for k in int_keys}
    arrays["tasks"] = pa.array(rows["tasks"], pa.list_(pa.string()))
    order = [
        "episode_index",
        "tasks",
        "length",
        "data/chunk_index",
        "data/file_index",
        "dataset_from_index",
        "dataset_to_index",
        "meta/episodes/chunk_index",
        "meta/episodes/file_index",
        "seed",
    ]
    path = root / EPISODES_PATH.format(chunk_index=0, file_index=0)
    path.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(pa.table({k: arrays[k] for k in order}), path)
