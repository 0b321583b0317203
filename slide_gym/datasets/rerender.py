"""``slide-gym replay ID --obs-mode MODE --save-as NEW_ID``: a dataset in another observation
mode, by exact replay of its actions.

Each episode is reset with its seed and options in the dataset's env, with ``obs_mode`` (and
the cameras' size, the number of points) changed, and steps its recorded actions. The world is
rebuilt on every reset, so the replay is exact: every step's state entries, reward,
termination, truncation and ``infos["sim_state"]`` must equal the source's bit for bit. An
episode that differs anywhere is not kept, and the run ends in a ValueError naming it (the
source was recorded by other code). The new dataset keeps the source's actions, rewards,
infos, seeds, options and records with the new observations; its metadata names the source
(``rerendered_from``). Episodes run in parallel and are staged as ``collect`` stages them
(:func:`~slide_gym.datasets.collect.run_staged`): Ctrl-C or a kill loses only the episodes in
flight, and the same command continues.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from slide_gym import DICT_ENV_IDS
from slide_gym.datasets.collect import claim_stage, run_staged, staging_dir
from slide_gym.datasets.config import check_dataset_id
from slide_gym.datasets.recording import RecordedEpisode
from slide_gym.datasets.store import (
    build_dataset,
    dataset_metadata,
    load,
    local_dataset_ids,
    read_episodes,
)
from slide_gym.envs.observation import OBS_MODES, state_space
from slide_gym.geometry.shape_json import closest

STATE_KEYS = tuple(state_space().spaces)
"""The observation entries every mode shares, compared with the source's."""


def rerender(
    dataset_id: str,
    obs_mode: str,
    save_as: str,
    *,
    episodes: int | None = None,
    image_size: tuple[int, int] | None = None,
    num_points: int | None = None,
    workers: int | None = None,
    backend: str = "local",
    address: str | None = None,
) -> dict[str, Any]:
    """Replay the first ``episodes`` (all if None) of ``dataset_id`` with ``obs_mode``
    (``image_size``: the cameras' (width, height), ``num_points``: the point cloud's; None:
    the source env's, else the env's defaults) into the new dataset ``save_as``; a summary."""
    if obs_mode not in OBS_MODES:
        near = closest(obs_mode, OBS_MODES)
        hint = f"did you mean {near!r}? " if near is not None else ""
        raise ValueError(
            f"unknown --obs-mode {obs_mode!r}; {hint}choose from {', '.join(OBS_MODES)}"
        )
    check_dataset_id(save_as)
    if save_as in local_dataset_ids():
        raise ValueError(
            f"dataset {save_as!r} exists already; choose a new --save-as id (or delete it "
            f"with `minari delete {save_as}`)"
        )
    if episodes is not None and episodes < 1:
        raise ValueError(f"--episodes must be >= 1, got {episodes}")
    if workers is not None and workers < 1:
        raise ValueError(f"--workers must be >= 1, got {workers}")
    source = load(dataset_id)
    spec = source.spec.env_spec
    if spec.id not in DICT_ENV_IDS:
        raise ValueError(
            f"dataset {dataset_id!r} is of {spec.id}, whose observation is fixed; --obs-mode "
            f"re-renders datasets of {', '.join(DICT_ENV_IDS)}"
        )
    kwargs = {k: v for k, v in spec.kwargs.items() if k != "num_points"}
    kwargs["obs_mode"] = obs_mode
    if image_size is not None:
        kwargs["render_width"], kwargs["render_height"] = image_size
    if num_points is not None:
        kwargs["num_points"] = num_points
    job = {
        "source": dataset_id,
        "env_id": spec.id,
        "env_kwargs": kwargs,
        "max_episode_steps": spec.max_episode_steps,
    }
    env = _make_env(job)  # a bad argument fails here, before any work
    try:
        count = source.total_episodes if episodes is None else min(episodes, source.total_episodes)
        stage = staging_dir(save_as)
        claim_stage(stage, save_as, "rerender.json", job, lambda theirs: _differences(job, theirs))
        rows = run_staged(
            rerender_case,
            [{"episode": i, "job": job} for i in range(count)],
            stage,
            _file_name,
            desc=save_as,
            workers=workers,
            backend=backend,
            address=address,
            success_key="matched",
        )
        _check_matched(rows, dataset_id, dataset_metadata(source))
        dataset = _build(source, save_as, job, env, stage / "episodes", count)
    finally:
        env.close()
    size = sum(f.stat().st_size for f in Path(dataset.storage.data_path).rglob("*") if f.is_file())
    return {
        "dataset_id": save_as,
        "source": dataset_id,
        "obs_mode": obs_mode,
        "path": str(dataset.storage.data_path.parent),
        "episodes": dataset.total_episodes,
        "steps": dataset.total_steps,
        "bytes_per_step": size / max(dataset.total_steps, 1),
    }


def rerender_case(case: dict[str, Any]) -> dict[str, Any]:
    """One episode (a job-runner case ``{"episode", "job"}``) replayed; its bytes in
    ``payload`` if it matched the source, else None and where it first differed."""
    job = case["job"]
    episode = next(read_episodes(load(job["source"]), [case["episode"]]))
    env = _make_env(job)
    try:
        observations, mismatch = replay_observations(env, episode)
    finally:
        env.close()
    if mismatch is not None:
        step, what = mismatch
        return {"matched": False, "step": step, "differs": what, "payload": None}
    episode = dataclasses.replace(episode, observations=observations)
    return {"matched": True, "steps": episode.steps, "payload": episode.to_bytes()}


def replay_observations(
    env: gym.Env, episode: RecordedEpisode
) -> tuple[dict[str, np.ndarray], tuple[int, str] | None]:
    """The observations of ``episode``'s actions replayed in ``env`` (key -> (T + 1, ...)),
    and None, or the first step (0: the reset) and quantity that differ from the record."""
    keys = [k for k in STATE_KEYS if k in episode.observations]
    recorded_states = episode.infos.get("sim_state")

    def differs(obs: dict[str, np.ndarray], t: int) -> str | None:
        for key in keys:
            if not np.array_equal(obs[key], episode.observations[key][t]):
                return key
        state = env.unwrapped.get_state()
        if recorded_states is not None and not np.array_equal(state, recorded_states[t]):
            return "sim_state"
        return None

    obs, _ = env.reset(seed=episode.seed, options=episode.options)
    frames = [obs]
    what = differs(obs, 0)
    if what is not None:
        return {}, (0, what)
    for t, action in enumerate(episode.actions):
        obs, reward, terminated, truncated, _ = env.step(action)
        what = differs(obs, t + 1)
        for name, new, old in (
            ("reward", reward, episode.rewards[t]),
            ("termination", terminated, episode.terminations[t]),
            ("truncation", truncated, episode.truncations[t]),
        ):
            if what is None and new != old:
                what = name
        if what is not None:
            return {}, (t + 1, what)
        frames.append(obs)
    return {k: np.stack([f[k] for f in frames]) for k in frames[0]}, None


def _make_env(job: dict[str, Any]) -> gym.Env:
    return gym.make(job["env_id"], max_episode_steps=job["max_episode_steps"], **job["env_kwargs"])


def _file_name(case: dict[str, Any]) -> str:
    return f"episode-{case['episode']:06d}.npz"


def _differences(job: dict[str, Any], theirs: dict[str, Any]) -> list[str]:
    keys = sorted(set(job) | set(theirs))
    return [
        f"{k}: {job.get(k)!r} != {theirs.get(k)!r}" for k in keys if job.get(k) != theirs.get(k)
    ]


def _check_matched(rows: list[dict[str, Any]], dataset_id: str, meta: dict[str, Any]) -> None:
    """A ValueError naming the episodes whose replay differed from the record (none kept)."""
    bad = sorted((r for r in rows if not r["matched"]), key=lambda r: r["case"]["episode"])
    if not bad:
        return
    where = ", ".join(
        f"episode {r['case']['episode']} at step {r['step']} ({r['differs']})" for r in bad[:3]
    )
    from slide_gym.version import code_version

    raise ValueError(
        f"{len(bad)} of {len(rows)} episodes of {dataset_id!r} did not replay exactly: "
        f"{where}{' ...' if len(bad) > 3 else ''}; no dataset was written (recorded by code "
        f"version {meta.get('code_version', 'unknown')}, this is {code_version()})"
    )


def _build(
    source: Any, save_as: str, job: dict[str, Any], env: gym.Env, folder: Path, count: int
) -> Any:
    """The new dataset from the staged episodes, with the source's metadata, the new env
    arguments and observation mode, and ``rerendered_from``."""
    from slide_gym.version import code_version

    meta = dataset_metadata(source)
    obs_mode = job["env_kwargs"]["obs_mode"]
    metadata = {
        **meta,
        "env_kwargs": job["env_kwargs"],
        "code_version": code_version(),
        "rerendered_from": {
            "dataset_id": job["source"],
            "obs_mode": source.spec.env_spec.kwargs.get("obs_mode", "state"),
            "code_version": meta.get("code_version"),
            "episodes": count,
        },
    }
    if "config" in meta:
        metadata["config"] = {**meta["config"], "obs_mode": obs_mode}
    stored = source.storage.metadata
    episodes = (
        RecordedEpisode.from_bytes((folder / _file_name({"episode": i})).read_bytes())
        for i in range(count)
    )
    return build_dataset(
        save_as,
        episodes,
        env,
        metadata,
        algorithm_name=str(stored.get("algorithm_name") or "slide-gym"),
        ref_max_score=stored.get("ref_max_score"),
        description=(
            f"The episodes of {job['source']} replayed action by action with "
            f"obs_mode={obs_mode!r}; state entries, rewards and infos['sim_state'] equal the "
            "source's bit for bit."
        ),
    )
