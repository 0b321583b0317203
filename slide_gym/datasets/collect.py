"""``slide-gym collect``: expert episodes into a Minari dataset, in parallel and resumably.

Each episode runs as one case of :func:`slide_gym.jobs.run_cases` (a process pool, or
Ray tasks). As each finishes, this process writes it to its own file in the dataset's staging
folder (``<Minari root>/.slide_gym/<id>/episodes/seed-SEED.npz``, atomically) and then a line
to ``episodes.jsonl`` there; the seed is an episode's identity. A kill loses only the
episodes in flight, and the same command again continues to N. When all are in, the staged
episodes (in seed order) are built into the Minari dataset; the staging folder stays, so a
later run with a larger N only records the new seeds.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from slide_gym.datasets.config import CollectConfig, check_dataset_id
from slide_gym.datasets.recording import RecordedEpisode, record_episode
from slide_gym.datasets.store import build_dataset, dataset_metadata, local_dataset_ids
from slide_gym.envs.randomization import parse, to_json
from slide_gym.jobs import Case, check_backend, load_results, run_cases
from slide_gym.splits import get_split

MAX_TRIES_PER_EPISODE = 20
"""``only_success`` gives up after this many episodes per one asked for."""
LOW_SUCCESS = 0.8
"""Below this expert success rate :func:`failure_report` warns."""


def staging_dir(dataset_id: str) -> Path:
    """Where the episodes of ``dataset_id`` are staged (hidden from Minari's listing)."""
    import minari

    return minari.storage.get_dataset_path() / ".slide_gym" / check_dataset_id(dataset_id)


def collect_case(case: dict[str, Any]) -> dict[str, Any]:
    """One episode (a job-runner case ``{"seed", "config"}``), its bytes in ``payload``."""
    config = CollectConfig.from_json(case["config"])
    episode = record_episode(config, int(case["seed"]))
    return {
        "success": episode.success,
        "failure": episode.record.get("failure"),
        "gave_up": episode.record.get("gave_up"),
        "steps": episode.steps,
        "return": float(episode.rewards.sum()),
        "planning_time_s": episode.record.get("planning_time_s"),
        "wall_time_s": episode.record.get("wall_time_s"),
        "payload": episode.to_bytes(),
    }


def collect(
    config: CollectConfig,
    episodes: int,
    dataset_id: str,
    *,
    workers: int | None = None,
    backend: str = "local",
    address: str | None = None,
) -> dict[str, Any]:
    """Collect ``episodes`` episodes of ``config`` into Minari dataset ``dataset_id`` (see
    the module docstring); return a summary. ``only_success`` runs further seeds until that
    many succeeded (at most :data:`MAX_TRIES_PER_EPISODE` per episode asked for)."""
    import minari

    check_dataset_id(dataset_id)
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"--episodes must be a whole number >= 1, got {episodes!r}")
    if workers is not None and workers < 1:
        raise ValueError(f"--workers must be >= 1, got {workers}")
    check_backend(backend, address)
    split = None if config.split is None else get_split(config.split)
    if split is not None:  # every seed stays in the split's collect seeds
        split.first_seed("collect", episodes, config.seed)
    stage = staging_dir(dataset_id)
    claim_stage(
        stage,
        dataset_id,
        "config.json",
        config.to_json(),
        lambda theirs: config.differences(CollectConfig.from_json(theirs)),
    )
    episode_dir = stage / "episodes"

    def run(seeds: range) -> list[dict[str, Any]]:
        cases = [{"seed": s, "config": config.to_json()} for s in seeds]
        return run_staged(
            collect_case,
            cases,
            stage,
            lambda case: _name(case["seed"]),
            desc=dataset_id,
            workers=workers,
            backend=backend,
            address=address,
            success_key="success",
        )

    start = config.seed
    rows = run(range(start, start + episodes))
    if config.only_success:
        limit = start + MAX_TRIES_PER_EPISODE * episodes
        if split is not None:
            limit = min(limit, split.collect_seeds.stop)
        end = start + episodes
        while sum(r["success"] for r in rows) < episodes and end < limit:
            wins = sum(r["success"] for r in rows)
            rate = max(wins / len(rows), 0.1)
            end = min(limit, end + max(1, math.ceil((episodes - wins) / rate)))
            rows = run(range(start, end))
    by_seed = {r["case"]["seed"]: r for r in rows}
    seeds = sorted(by_seed)
    if config.only_success:
        seeds = [s for s in seeds if by_seed[s]["success"]][:episodes]
        if len(seeds) < episodes:
            print(
                f"only {len(seeds)} of {episodes} episodes succeeded in {len(by_seed)} tries; "
                "the dataset keeps those",
                file=sys.stderr,
            )
    if not seeds:
        raise ValueError(f"no episode to keep: none of {len(by_seed)} succeeded")
    tried = [by_seed[s] for s in sorted(by_seed)]
    return _build(dataset_id, config, episode_dir, seeds, tried, minari)


def _build(
    dataset_id: str,
    config: CollectConfig,
    episode_dir: Path,
    seeds: list[int],
    tried: list[dict[str, Any]],
    minari: Any,
) -> dict[str, Any]:
    """Build (or keep, if it already holds exactly ``seeds``) the dataset; its summary."""
    from agents.outcome import failure_counts
    from agents.params import EXPERT_SLIDE_PARAMS, ExpertParams
    from slide_gym.version import code_version

    successes = sum(r["success"] for r in tried)
    kept = [r for r in tried if r["case"]["seed"] in set(seeds)]
    returns = [r["return"] for r in kept]
    steps = sum(r["steps"] for r in kept)
    expert = config.agent_kwargs().get("params", ExpertParams())
    metadata = {
        "config": config.to_json(),
        "env_id": config.env_id,
        "env_kwargs": config.env_kwargs(),
        "agent": {
            "planner": config.agent,
            "time_budget_s": config.time_budget,
            "expert_params": dataclasses.asdict(expert),
            "slide_params": dataclasses.asdict(EXPERT_SLIDE_PARAMS),
        },
        "randomization": to_json(parse(config.randomization)),
        "code_version": code_version(),
        "seeds": seeds,
        "episodes_run": len(tried),
        "expert_successes": successes,
        "expert_success_rate": successes / len(tried),
        "expert_failures": failure_counts(tried),
        "mean_return": float(np.mean(returns)),
        "total_steps": steps,
    }
    existing = None
    if dataset_id in local_dataset_ids():
        existing = minari.load_dataset(dataset_id)
        if dataset_metadata(existing).get("seeds") != seeds:
            existing = None
    if existing is None:
        env = gym.make(config.env_id, **config.env_kwargs())
        try:
            existing = build_dataset(
                dataset_id,
                (RecordedEpisode.from_bytes((episode_dir / _name(s)).read_bytes()) for s in seeds),
                env,
                metadata,
                algorithm_name=f"slide-gym expert ({config.agent} planner)",
                ref_max_score=metadata["mean_return"],
                description=(
                    f"Planner-expert episodes in {config.env_id} ({config.object} on the "
                    f"{config.table} table); per episode the reset seed and options, per step "
                    "infos['sim_state'] (TopSlideEnv.get_state)."
                ),
            )
        finally:
            env.close()
    size = sum(f.stat().st_size for f in Path(existing.storage.data_path).rglob("*") if f.is_file())
    return {
        "dataset_id": dataset_id,
        "path": str(existing.storage.data_path.parent),
        "episodes": len(seeds),
        "steps": steps,
        "episodes_run": len(tried),
        "expert_success_rate": metadata["expert_success_rate"],
        "failures": failure_counts(tried),
        "bytes_per_step": size / max(steps, 1),
        "planning_time_s_median": _median([r.get("planning_time_s") for r in kept]),
        "wall_time_s_median": _median([r.get("wall_time_s") for r in kept]),
    }


def failure_report(summary: dict[str, Any]) -> str:
    """Lines for the end of a collection: the failed episodes counted by cause (numbers left
    out), and a warning when the expert succeeded in fewer than :data:`LOW_SUCCESS` of them."""
    run, rate = summary["episodes_run"], summary["expert_success_rate"]
    lines = [f"expert success: {round(rate * run)} of {run} episodes ({100 * rate:.0f} %)"]
    lines += [f"  {n} x {kind}" for kind, n in summary["failures"].items()]
    if rate < LOW_SUCCESS:
        lines.append(
            f"warning: expert success {100 * rate:.0f} % is below {100 * LOW_SUCCESS:.0f} %: "
            "the scene may be too hard for the expert (see the failures above)"
        )
    return "\n".join(lines)


def claim_stage(
    stage: Path,
    dataset_id: str,
    name: str,
    identity: dict[str, Any],
    differences: Callable[[dict[str, Any]], list[str]],
) -> None:
    """Tie the staging folder to ``identity`` (a JSON object kept there as ``name``); a
    ValueError if the folder holds another configuration (``differences(theirs)`` lists the
    fields that differ), another command's job, or the id is a dataset made elsewhere."""
    path = stage / name
    if path.exists():
        diff = differences(json.loads(path.read_text()))
        if diff:
            raise ValueError(
                f"dataset {dataset_id!r} was made with another configuration "
                f"({'; '.join(diff)}, new != existing); use a new id (e.g. bump -vK)"
            )
        return
    others = sorted(p.name for p in stage.glob("*.json")) if stage.exists() else []
    if others:
        raise ValueError(
            f"dataset {dataset_id!r} is another command's job (its staging folder {stage} "
            f"holds {others[0]}); use a new id"
        )
    if dataset_id in local_dataset_ids():
        raise ValueError(
            f"dataset {dataset_id!r} exists and was not made here (no staging folder "
            f"{stage}); use a new id, or delete it with `minari delete {dataset_id}`"
        )
    stage.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(identity, indent=2))
    os.replace(tmp, path)


def run_staged(
    fn: Callable[[Case], dict[str, Any]],
    cases: list[Case],
    stage: Path,
    file_name: Callable[[Case], str],
    *,
    desc: str,
    workers: int | None = None,
    backend: str = "local",
    address: str | None = None,
    success_key: str | None = None,
) -> list[dict[str, Any]]:
    """:func:`run_cases` of ``fn`` (progress bar ``desc``) into ``stage/episodes.jsonl``:
    each result's ``payload`` (bytes) is written to ``stage/episodes/file_name(case)``
    (atomically) before its line. A payload of None leaves no file; a line without its file
    is dropped on the next run, so that case runs again."""
    progress = stage / "episodes.jsonl"
    episode_dir = stage / "episodes"
    episode_dir.mkdir(parents=True, exist_ok=True)
    _forget_missing(progress, episode_dir, file_name)

    def store(case: Case, result: dict[str, Any]) -> dict[str, Any]:
        payload = result.pop("payload")
        if payload is not None:
            path = episode_dir / file_name(case)
            tmp = path.with_suffix(f".{os.getpid()}.tmp")
            tmp.write_bytes(payload)
            os.replace(tmp, path)
        return result

    return run_cases(
        fn,
        cases,
        progress,
        workers,
        desc=desc,
        backend=backend,
        address=address,
        store=store,
        success_key=success_key,
    )


def _forget_missing(progress: Path, episode_dir: Path, file_name: Callable[[Case], str]) -> None:
    """Drop progress lines whose episode file is gone, so those cases run again."""
    rows = load_results(progress)
    keep = [r for r in rows if (episode_dir / file_name(r["case"])).exists()]
    if len(keep) != len(rows):
        tmp = progress.with_suffix(".tmp")
        tmp.write_text("".join(json.dumps(r) + "\n" for r in keep))
        os.replace(tmp, progress)


def _name(seed: int) -> str:
    return f"seed-{seed:08d}.npz"


def _median(values: list[Any]) -> float | None:
    vals = [float(v) for v in values if v is not None]
    return float(np.median(vals)) if vals else None
