"""Minari datasets from recorded episodes: build, read back, merge.

Datasets are written with ``minari.create_dataset_from_buffers`` from whole episodes (no
jax), then grown chunk by chunk with ``update_dataset_from_buffer``; both keep each episode's
seed and options (Minari's own ``combine_datasets`` drops them, so :func:`merge_datasets`
rebuilds episode buffers instead). Per episode, the HDF5 group also carries ``success``,
``steps`` and ``record`` (the ``slide-gym run --json`` object, as JSON text).
"""

from __future__ import annotations

import json
import shutil
import warnings
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from slide_gym.datasets.config import DATASET_ID, check_dataset_id
from slide_gym.datasets.recording import RecordedEpisode
from slide_gym.planning.result import json_values

CHUNK = 16
"""Episodes per write: bounds the memory a large dataset needs while it is built."""
METADATA_KEY = "slide_gym"
"""The dataset metadata entry holding the collection's configuration and figures."""


def local_dataset_ids() -> list[str]:
    """The ids of the Minari datasets on this machine (``MINARI_DATASETS_PATH``).

    ``minari.list_local_datasets`` ends in a traceback as soon as any folder under the
    datasets root has a ``data`` folder and a name Minari cannot parse (a LeRobot export
    written there, a partial folder a failed create left behind); such folders are skipped
    here, as are folders whose metadata names another id."""
    import minari

    root = Path(minari.storage.get_dataset_path())
    ids = []
    for meta in root.glob("**/data/metadata.json"):
        rel = meta.parent.parent.relative_to(root)
        if any(part.startswith(".") for part in rel.parts):
            continue
        dataset_id = rel.as_posix()
        if not DATASET_ID.match(dataset_id):
            continue
        try:
            if json.loads(meta.read_text()).get("dataset_id") == dataset_id:
                ids.append(dataset_id)
        except (OSError, ValueError):
            continue
    return sorted(ids)


def load(dataset_id: str) -> Any:
    """``minari.load_dataset(dataset_id)``, with a ValueError naming the local datasets."""
    import minari

    check_dataset_id(dataset_id)
    local = local_dataset_ids()
    if dataset_id not in local:
        raise ValueError(
            f"no local dataset {dataset_id!r}; local datasets: {', '.join(local) or 'none'} "
            f"(folder: {minari.storage.get_dataset_path()})"
        )
    return minari.load_dataset(dataset_id)


def build_dataset(
    dataset_id: str,
    episodes: Iterable[RecordedEpisode],
    env: gym.Env,
    metadata: dict[str, Any],
    *,
    algorithm_name: str,
    ref_max_score: float | None = None,
    description: str = "",
) -> Any:
    """Write ``episodes`` (in order, ids 0, 1, ...) as Minari dataset ``dataset_id``,
    replacing any dataset of that id; return it. ``env`` gives the spec (with its kwargs) and
    the spaces; ``metadata`` goes under :data:`METADATA_KEY`."""
    import minari

    check_dataset_id(dataset_id)
    _delete(dataset_id)
    dataset = None
    index = 0
    for chunk in _chunks(episodes, CHUNK):
        buffers = [episode_buffer(e) for e in chunk]
        if dataset is None:
            with warnings.catch_warnings():  # Minari's advice on optional fields
                # no e-mail or permalink to give; the code version is in our metadata
                warnings.filterwarnings("ignore", message=".*is set to None.*")
                dataset = _create(
                    minari,
                    dataset_id,
                    buffers,
                    env,
                    algorithm_name,
                    ref_max_score,
                    description,
                )
        else:
            dataset.update_dataset_from_buffer(buffers)
        dataset.storage.update_episode_metadata(
            [episode_attrs(e) for e in chunk], range(index, index + len(chunk))
        )
        index += len(chunk)
    if dataset is None:
        raise ValueError(f"dataset {dataset_id!r} would have no episodes")
    dataset.storage.update_metadata({METADATA_KEY: metadata})
    return minari.load_dataset(dataset_id)


def _create(
    minari: Any,
    dataset_id: str,
    buffers: list[Any],
    env: gym.Env,
    algorithm_name: str,
    ref_max_score: float | None,
    description: str,
) -> Any:
    return minari.create_dataset_from_buffers(
        dataset_id=dataset_id,
        buffer=buffers,
        env=env.spec,
        eval_env=env.spec,
        algorithm_name=algorithm_name,
        author="slide-gym",
        ref_min_score=0.0 if ref_max_score is not None else None,
        ref_max_score=ref_max_score,
        description=description or None,
        data_format="hdf5",
        jpeg_encoding=False,  # Minari's default compresses images lossily
    )


def episode_buffer(e: RecordedEpisode) -> Any:
    from minari.data_collector import EpisodeBuffer

    return EpisodeBuffer(
        id=None,
        seed=e.seed,
        options=e.options,
        observations=e.observations,
        actions=e.actions,
        rewards=list(e.rewards),
        terminations=list(e.terminations),
        truncations=list(e.truncations),
        infos=e.infos,
    )


def episode_attrs(e: RecordedEpisode) -> dict[str, Any]:
    return {
        "success": e.success,
        "steps": e.steps,
        "dagger_round": int(e.record.get("dagger_round", 0)),
        "record": json.dumps(e.record),
    }


def read_episodes(dataset: Any, indices: Iterable[int] | None = None) -> Iterator[RecordedEpisode]:
    """The dataset's episodes (all, or ``indices``) as :class:`RecordedEpisode`, with their
    seeds, reset options and records."""
    ids = list(range(dataset.total_episodes) if indices is None else indices)
    metas = list(dataset.storage.get_episode_metadata(ids))
    for data, meta in zip(dataset.storage.get_episodes(ids), metas, strict=True):
        yield RecordedEpisode(
            seed=int(meta["seed"]),
            options=json_values(meta.get("options", {})),
            observations=dict(data["observations"]),
            actions=np.asarray(data["actions"]),
            rewards=np.asarray(data["rewards"]),
            terminations=np.asarray(data["terminations"]),
            truncations=np.asarray(data["truncations"]),
            infos=dict(data["infos"]),
            record=json.loads(_text(meta.get("record", "{}"))),
        )


def merge_datasets(dataset_ids: list[str], out_id: str) -> Any:
    """One dataset ``out_id`` with the episodes of ``dataset_ids`` in turn (seeds, options and
    records kept). The datasets must share their environment spec."""
    if len(dataset_ids) < 2:
        raise ValueError("merge needs at least two dataset ids")
    datasets = [load(i) for i in dataset_ids]
    specs = {d.spec.env_spec.to_json() for d in datasets}
    if len(specs) != 1:
        raise ValueError(f"cannot merge datasets of different environments: {dataset_ids}")
    env = datasets[0].recover_environment()
    try:
        metadata = {"merged_from": list(dataset_ids)}
        return build_dataset(
            out_id,
            (e for d in datasets for e in read_episodes(d)),
            env,
            metadata,
            algorithm_name=str(datasets[0].storage.metadata.get("algorithm_name") or "merged"),
            description=f"The episodes of {', '.join(dataset_ids)}, in turn.",
        )
    finally:
        env.close()


def dataset_metadata(dataset: Any) -> dict[str, Any]:
    """What :func:`build_dataset` stored under :data:`METADATA_KEY` ({} if none)."""
    return dict(dataset.storage.metadata.get(METADATA_KEY) or {})


def _delete(dataset_id: str) -> None:
    import minari

    path = minari.storage.get_dataset_path(dataset_id)
    if path.exists():
        shutil.rmtree(path)


def _chunks(items: Iterable[Any], size: int) -> Iterator[list[Any]]:
    chunk: list[Any] = []
    for item in items:
        chunk.append(item)
        if len(chunk) == size:
            yield chunk
            chunk = []
    if chunk:
        yield chunk


def _text(value: Any) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)
