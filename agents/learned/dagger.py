"""DAgger with the replanning expert: the learner acts, the expert labels the states it
reaches, the labels join the dataset, and the policy is trained again.

Round ``r`` runs ``episodes`` learner episodes (reset seeds from :data:`DAGGER_SEED`, never
a validation or test seed). A :class:`~agents.learned.labeler.PlanLabeler` labels every step:
one expert per episode keeps its plan and follows the executed actions, and a fresh one takes
over (from any state) only at a chunk boundary (each ``action_horizon`` steps) where the
learner has left the plan. With probability ``beta * decay ** (r - 1)`` (seeded) the
expert's actions are the ones executed for a chunk; otherwise the learner's are. Labels of
an expert whose plan failed are dropped (NaN, which the trainer skips) and counted, as are
labels given in one of ``skip_phases`` (e.g. ``release``: the expert raising a fingertip the
learner put where its plan cannot go on, a motion no demonstration shows).

With ``label_from_overhang`` U and/or ``label_from_miss`` H, an episode is labelled only
from the first step where the learner is somewhere the demonstrations do not go
(:func:`left_demonstrations`): the plate overhangs the table by U or more (set to the
demonstrations' stop, the learner has slid past every demonstration), or the fingertip is
within H of the table top but more than :data:`agents.expert.ON_PLATE_MARGIN` off the
plate's outline (it came down beside the plate instead of on it). The expert first takes
over at the next chunk boundary, and the steps before get no label, so the states the
learner handles like the demonstrations are not relabelled by an expert that would press,
slide and aim elsewhere.

With ``chunk_every`` K, every K-th step also gets a chunk label
(:meth:`~agents.learned.labeler.PlanLabeler.chunk`): the expert's own next actions from the
learner's state, run in a second env of the scene, as long as the part of a chunk the policy
predicts from there. The trainer then learns from those windows only and not from the
per-step labels, which along a motion the learner chose are no chunk the expert would
execute.

Each episode is kept like a collected one (executed actions, so a reset with its seed and
options replays it exactly; the labels in ``infos["expert_action"]``; ``dagger_round`` in
its metadata), staged under ``OUT/round-R/episodes`` as it finishes (a rerun resumes), and
after each round the base dataset and every round so far are built into one Minari dataset,
on which the policy is trained again, warm-started from the previous round's weights. A
grasping skill that follows a sliding skill (``train-dp --after``) keeps that sliding skill,
and only its own part is trained again: what follows the finished slide in each episode,
demonstrations and rollouts alike.
"""

from __future__ import annotations

import dataclasses
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import shapely

from agents.expert import ON_PLATE_MARGIN, PHASES
from agents.learned.data import chunk_label_length
from agents.learned.labeler import PlanLabeler
from agents.learned.policy import FIRST_FILE, DiffusionPolicy, is_policy_dir
from slide_gym.datasets.config import CollectConfig, check_dataset_id, check_expert_params
from slide_gym.datasets.recording import (
    CHUNK_KEY,
    LABEL_KEY,
    RecordedEpisode,
    reset_options,
    stack_infos,
    step_info,
)
from slide_gym.geometry import transform_polygon
from slide_gym.splits import DAGGER_SEED


@dataclass(frozen=True)
class DaggerConfig:
    """One DAgger run.

    Args:
        rounds: learner-and-label rounds (each followed by training).
        episodes: learner episodes per round.
        beta, decay: the share of chunks the expert executes is ``beta * decay ** (r - 1)``
            in round ``r``.
        label_budget: planning seconds per label query (the expert gives up after it).
        iterations: training iterations per round (warm-started from the last weights).
        seed: the learner's sampling noise and the expert-share draws.
        max_steps: cut learner episodes after this many steps (None: the env's time limit).
        skip_phases: expert phases (:data:`agents.expert.PHASES`) whose labels are withheld
            (NaN; the expert still acts in them when it executes a chunk).
        chunk_every: every this many steps, label the expert's whole chunk from the
            learner's state (0: per-step labels only).
        expert_params: overrides of the labelling expert's execution settings
            (:class:`agents.params.ExpertParams`) on top of the base dataset's.
        label_from_overhang: label each episode only from the first step where the plate
            overhangs the table by this much (m), or (with ``label_from_miss``) ...
        label_from_miss: ... where the fingertip is within this height of the table top (m)
            and off the plate (:func:`left_demonstrations`). Both None: label every step.
    """

    rounds: int = 2
    episodes: int = 20
    beta: float = 0.5
    decay: float = 0.5
    label_budget: float = 10.0
    iterations: int = 5_000
    seed: int = 0
    max_steps: int | None = None
    skip_phases: tuple[str, ...] = ()
    chunk_every: int = 0
    expert_params: dict[str, float] | None = None
    label_from_overhang: float | None = None
    label_from_miss: float | None = None

    def __post_init__(self) -> None:
        unknown = sorted(set(self.skip_phases) - set(PHASES))
        if unknown:
            raise ValueError(
                f"--skip-phases: unknown expert phase(s) {', '.join(unknown)}; "
                f"allowed: {', '.join(PHASES)}"
            )
        if self.max_steps is not None and (
            isinstance(self.max_steps, bool)
            or not isinstance(self.max_steps, int)
            or self.max_steps < 1
        ):
            raise ValueError(f"--max-steps must be a whole number >= 1, got {self.max_steps!r}")
        if self.expert_params is not None:
            object.__setattr__(self, "expert_params", check_expert_params(self.expert_params))
        every = self.chunk_every
        if isinstance(every, bool) or not isinstance(every, int) or every < 0:
            raise ValueError(f"--chunk-labels must be a whole number >= 0, got {every!r}")
        for name in ("rounds", "episodes", "iterations"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"--{name} must be a whole number >= 1, got {value!r}")
        for name in ("beta", "decay"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and 0.0 <= value <= 1.0):
                raise ValueError(f"--{name} must be a number in [0, 1], got {value!r}")
        for name in ("label_from_overhang", "label_from_miss"):
            value = getattr(self, name)
            if value is not None and not (
                isinstance(value, (int, float)) and not isinstance(value, bool) and 0 <= value < 1
            ):
                flag = "--" + name.replace("_", "-")
                raise ValueError(f"{flag} must be metres in [0, 1), got {value!r}")
        if not (isinstance(self.label_budget, (int, float)) and self.label_budget > 0):
            raise ValueError(f"--label-budget must be positive seconds, got {self.label_budget!r}")

    def expert_share(self, round_: int) -> float:
        return float(self.beta * self.decay ** (round_ - 1))

    def gates(self) -> dict[str, float]:
        """The label gates set (:func:`left_demonstrations`' keyword arguments)."""
        named = {"overhang": self.label_from_overhang, "miss_height": self.label_from_miss}
        return {k: float(v) for k, v in named.items() if v is not None}


def left_demonstrations(
    obs: dict[str, np.ndarray],
    info: dict[str, Any],
    plate: shapely.Polygon,
    *,
    overhang: float | None = None,
    miss_height: float | None = None,
) -> bool:
    """Whether the state is one the demonstrations do not reach: the plate overhangs the table
    by ``overhang`` or more (``info["overhang_m"]``), or the fingertip is within
    ``miss_height`` of the table top and more than :data:`agents.expert.ON_PLATE_MARGIN`
    outside ``plate`` (the plate's outline at the origin, placed at
    ``info["object_pose_2d"]``)."""
    if overhang is not None and float(info["overhang_m"]) >= overhang:
        return True
    if miss_height is None:
        return False
    tip = np.asarray(obs["fingertip_pose"], dtype=float)
    if tip[2] - float(obs["table_height"][0]) >= miss_height:
        return False
    placed = transform_polygon(plate, *np.asarray(info["object_pose_2d"], dtype=float))
    return not placed.buffer(ON_PLATE_MARGIN).contains(shapely.Point(tip[0], tip[1]))


def rollout_case(case: dict[str, Any]) -> dict[str, Any]:
    """One learner episode with expert labels (a job-runner case); bytes in ``payload``."""
    config = CollectConfig.from_json(case["config"])
    seed, round_ = int(case["seed"]), int(case["round"])
    policy = DiffusionPolicy.load(case["policy"], seed=seed)
    horizon = policy.config.action_horizon
    chunk_every = int(case.get("chunk_every", 0))
    gates = case.get("label_gates") or {}
    chunk_length = chunk_label_length(policy.config.obs_horizon, policy.config.pred_horizon)
    rng = np.random.default_rng([seed, round_, case["dagger_seed"]])
    env = gym.make(config.env_id, **config.env_kwargs())
    base = env.unwrapped
    branch = gym.make(config.env_id, **config.env_kwargs()).unwrapped if chunk_every else None
    observations, infos, steps, labels, chunks = [], [], [], [], []
    expert_chunks = withheld = chunk_queries = chunk_failures = 0
    labeler: PlanLabeler | None = None
    wall = time.perf_counter()
    try:
        obs, info = env.reset(seed=seed)
        options = reset_options(env, config)
        if branch is not None:
            branch.reset(seed=seed, options=options)
        labeler = PlanLabeler(
            config,
            seed,
            case["label_budget"],
            base.task.object,
            base.task.table,
            skip_phases=tuple(case.get("skip_phases", ())),
        )
        observations.append(obs)
        infos.append(step_info(info, base.get_state()))
        t, done, expert_acts = 0, False, False
        plate = base.task.object.polygon
        gate_open = not gates
        while not done:
            boundary = t % horizon == 0
            gate_open = gate_open or left_demonstrations(obs, info, plate, **gates)
            label = labeler.label(obs, t, boundary) if gate_open else None
            if boundary:
                expert_acts = bool(rng.random() < case["expert_share"])
            learner, _ = policy.predict(obs, episode_start=np.array([t == 0]))
            action = label if expert_acts and label is not None else learner
            expert_chunks += boundary and expert_acts and label is not None
            labeler.executed(action)
            withheld += label is not None and labeler.withheld
            keep = label is not None and not labeler.withheld
            labels.append(label if keep else np.full_like(learner, np.nan))
            if branch is not None:
                chunk = None
                if keep and t % chunk_every == 0:
                    chunk = labeler.chunk(label, branch, base.get_state(), chunk_length)
                    chunk_queries += 1
                    chunk_failures += chunk is None
                chunks.append(chunk)
            obs, reward, term, trunc, info = env.step(action)
            steps.append((np.asarray(action, np.float32), float(reward), term, trunc))
            observations.append(obs)
            infos.append(step_info(info, base.get_state()))
            t += 1
            done = term or trunc or (case["max_steps"] is not None and t >= case["max_steps"])
    finally:
        if labeler is not None:
            labeler.close()
        if branch is not None:
            branch.close()
        env.close()
    queries, failures = labeler.queries, labeler.failures
    reasons = labeler.reasons
    actions = np.stack([s[0] for s in steps])
    stacked = stack_infos(infos)
    stacked[LABEL_KEY] = np.concatenate([np.zeros_like(actions[:1]), np.stack(labels)])
    if branch is not None:
        blank = np.full((chunk_length, actions.shape[1]), np.nan, np.float32)
        rows = [np.zeros_like(blank)] + [blank if c is None else c for c in chunks]
        stacked[CHUNK_KEY] = np.stack(rows)
    success = bool(info["is_success"])
    record = {
        "success": success,
        "dagger_round": round_,
        "label_queries": queries,
        "label_failures": failures,
        "label_failure_reasons": reasons,
        "labels_withheld": withheld,
        "chunk_queries": chunk_queries,
        "chunk_failures": chunk_failures,
        "expert_chunks": expert_chunks,
        "steps": len(actions),
        "wall_time_s": time.perf_counter() - wall,
    }
    episode = RecordedEpisode(
        seed=seed,
        options=options,
        observations={k: np.stack([o[k] for o in observations]) for k in observations[0]},
        actions=actions,
        rewards=np.array([s[1] for s in steps]),
        terminations=np.array([s[2] for s in steps], dtype=bool),
        truncations=np.array([s[3] for s in steps], dtype=bool),
        infos=stacked,
        record=record,
    )
    return {
        **record,
        "payload": episode.to_bytes(),
    }


def with_labels(episode: RecordedEpisode, chunk_length: int = 0) -> RecordedEpisode:
    """``episode`` with ``infos["expert_action"]`` (its own actions where it has none) and,
    with ``chunk_length``, ``infos["expert_chunk"]`` (NaN where it has none), so
    demonstrations and labelled episodes share one set of info keys."""
    actions = np.asarray(episode.actions, np.float32)
    if LABEL_KEY not in episode.infos:
        labels = np.concatenate([np.zeros_like(actions[:1]), actions])
        episode.infos = {**episode.infos, LABEL_KEY: labels}
    if chunk_length and CHUNK_KEY not in episode.infos:
        blank = np.full((len(actions) + 1, chunk_length, actions.shape[1]), np.nan, np.float32)
        episode.infos = {**episode.infos, CHUNK_KEY: blank}
    return episode


def _base_optimiser(training: dict[str, Any]) -> dict[str, Any]:
    """The base policy's batch size and AdamW settings (its card's ``training``), which
    every DAgger round keeps: a policy trained at batch 256 is retrained at batch 256."""
    keys = ("batch_size", "learning_rate", "weight_decay", "warmup")
    return {k: training[k] for k in keys if k in training}


def run_dagger(
    policy_dir: Path,
    out: Path,
    dataset_id: str,
    config: DaggerConfig,
    *,
    workers: int | None = None,
    backend: str = "local",
    address: str | None = None,
    progress: bool = True,
) -> dict[str, Any]:
    """Run DAgger from the policy in ``policy_dir`` into folder ``out``; the aggregated
    dataset is Minari ``dataset_id`` (rebuilt after each round). Returns a summary with one
    row per round. Rerunning the same command resumes where it stopped."""
    from agents.learned.train import TrainConfig, train_diffusion
    from slide_gym.datasets.store import build_dataset, load, read_episodes
    from slide_gym.jobs import check_backend, run_cases

    check_dataset_id(dataset_id)
    check_backend(backend, address)
    if not is_policy_dir(policy_dir):
        raise ValueError(
            f"--policy {str(policy_dir)!r} holds no diffusion policy (no policy.pt); train one "
            "with `slide-gym train-dp DATASET_ID --out DIR`"
        )
    card = json.loads((Path(policy_dir) / "policy.json").read_text())
    if card.get("config", {}).get("actions") == "targets":
        raise ValueError(
            f"--policy {str(policy_dir)!r} acts with fingertip targets, which learn from the "
            "demonstrated motion and not from an expert's labels; DAgger needs --actions "
            "deltas or offsets"
        )
    base_id = card.get("dataset_id")
    if not base_id:
        raise ValueError(f"{str(policy_dir)!r}: its policy.json names no dataset_id")
    if base_id == dataset_id:
        raise ValueError(f"--dataset-id must differ from the policy's dataset {base_id!r}")
    base = load(base_id)
    collect = CollectConfig.from_metadata(base.storage.metadata["slide_gym"])
    if config.expert_params:
        merged = {**(collect.expert_params or {}), **config.expert_params}
        collect = dataclasses.replace(collect, expert_params=merged)
    out = Path(out)
    current, rows = Path(policy_dir), []
    for r in range(1, config.rounds + 1):
        stage = out / f"round-{r}"
        (stage / "episodes").mkdir(parents=True, exist_ok=True)
        share = config.expert_share(r)
        first = DAGGER_SEED + (r - 1) * config.episodes
        cases = [
            {
                "seed": s,
                "round": r,
                "policy": str(current),
                "config": collect.to_json(),
                "expert_share": share,
                "label_budget": float(config.label_budget),
                "dagger_seed": config.seed,
                "max_steps": config.max_steps,
                **({"skip_phases": list(config.skip_phases)} if config.skip_phases else {}),
                **({"chunk_every": config.chunk_every} if config.chunk_every else {}),
                **({"label_gates": config.gates()} if config.gates() else {}),
            }
            for s in range(first, first + config.episodes)
        ]

        def store(case: dict[str, Any], result: dict[str, Any], stage: Path = stage) -> dict:
            path = stage / "episodes" / f"seed-{case['seed']:08d}.npz"
            tmp = path.with_suffix(f".{os.getpid()}.tmp")
            tmp.write_bytes(result.pop("payload"))
            os.replace(tmp, path)
            return result

        results = run_cases(
            rollout_case,
            cases,
            stage / "episodes.jsonl",
            workers,
            desc=f"dagger round {r}",
            backend=backend,
            address=address,
            store=store,
            success_key="success",
        )
        model = card["config"]
        chunk_length = (
            chunk_label_length(model["obs_horizon"], model["pred_horizon"])
            if config.chunk_every
            else 0
        )
        episodes = [with_labels(e, chunk_length) for e in read_episodes(base)]
        for k in range(1, r + 1):
            for path in sorted((out / f"round-{k}" / "episodes").glob("seed-*.npz")):
                episodes.append(RecordedEpisode.from_bytes(path.read_bytes()))
        env = gym.make(collect.env_id, **collect.env_kwargs())
        try:
            meta = {
                **base.storage.metadata["slide_gym"],
                "dagger": {"base_dataset": base_id, "rounds": r, "config": config.__dict__},
            }
            dataset = build_dataset(
                dataset_id,
                iter(episodes),
                env,
                meta,
                algorithm_name="slide-gym DAgger (diffusion policy, planner expert labels)",
                description=f"{base_id} and {r} DAgger round(s) of learner episodes labelled "
                "by the replanning expert (infos['expert_action']).",
            )
        finally:
            env.close()
        policy_out = stage / "policy"
        slide_skill = current / FIRST_FILE
        after = {"after": card["after"]} if "after" in card else {}
        summary = train_diffusion(
            dataset,
            policy_out,
            train=TrainConfig(
                iterations=config.iterations,
                seed=config.seed,
                val_every=0,
                val_episodes=int(card["training"].get("val_episodes", 20)),
                **_base_optimiser(card["training"]),
            ),
            env_id=collect.env_id,
            env_kwargs=collect.env_kwargs(),
            card={"dataset_id": dataset_id, "dagger_round": r, "init": str(current), **after},
            resume=(policy_out / "checkpoint.pt").exists(),
            init=current / "policy.pt",
            progress=progress,
            first=slide_skill if slide_skill.is_file() else None,
        )
        queries = sum(int(x["label_queries"]) for x in results)
        rows.append(
            {
                "round": r,
                "expert_share": share,
                "episodes": len(results),
                "learner_successes": sum(bool(x["success"]) for x in results),
                "label_queries": queries,
                "label_failures": sum(int(x["label_failures"]) for x in results),
                "labels_withheld": sum(int(x.get("labels_withheld", 0)) for x in results),
                "chunk_queries": sum(int(x.get("chunk_queries", 0)) for x in results),
                "chunk_failures": sum(int(x.get("chunk_failures", 0)) for x in results),
                "labelled_steps": sum(int(x["steps"]) for x in results),
                "dataset_episodes": len(episodes),
                "validation": summary.get("checkpoint"),
                "policy": str(policy_out),
            }
        )
        (out / "dagger.json").write_text(json.dumps({"rounds": rows}, indent=2) + "\n")
        current = policy_out
    return {"policy": str(current), "dataset_id": dataset_id, "rounds": rows}
