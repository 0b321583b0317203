"""One expert episode as arrays: what a dataset stores per episode, and how it is recorded.

:func:`record_episode` runs the planner expert for one seed and keeps every observation,
action, reward and the step infos, with ``infos["sim_state"]`` (the env's
:meth:`~slide_gym.envs.top_slide.TopSlideEnv.get_state`) at the reset and after every step.
:class:`RecordedEpisode` travels between processes and sits on disk as one ``.npz`` file.
"""

from __future__ import annotations

import io
import json
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np

from slide_gym.datasets.config import CollectConfig

INFO_KEYS = (
    "is_success",
    "overhang_m",
    "graspable",
    "lift_m",
    "clearance_m",
    "lift_held_s",
    "touching_robot",
    "touching_table",
    "fell_off",
    "object_pose_2d",
)
"""The env's step info entries a dataset keeps (with ``sim_state`` and ``reward_terms``); the
object and table names are in the episode's options instead."""


@dataclass
class RecordedEpisode:
    """One episode: ``T`` actions, ``T + 1`` observations and infos (the reset's first).

    Attributes:
        seed, options: ``env.reset(seed=seed, options=options)`` starts this episode again.
        observations: key -> (T + 1, ...) array, in the env's dtypes (float32, uint8 images).
        actions: (T, A) float32; rewards (T,) float64; terminations, truncations (T,) bool.
        infos: key -> (T + 1, ...) array (``reward_terms``: a dict of such arrays).
        record: the ``slide-gym run --json`` object of the episode.
    """

    seed: int
    options: dict[str, Any]
    observations: dict[str, np.ndarray]
    actions: np.ndarray
    rewards: np.ndarray
    terminations: np.ndarray
    truncations: np.ndarray
    infos: dict[str, Any]
    record: dict[str, Any] = field(default_factory=dict)

    @property
    def success(self) -> bool:
        return bool(self.record.get("success", False))

    @property
    def steps(self) -> int:
        return len(self.actions)

    def to_bytes(self) -> bytes:
        """The episode as a compressed ``.npz`` (arrays lossless; images too)."""
        arrays: dict[str, np.ndarray] = {f"obs/{k}": v for k, v in self.observations.items()}
        for k, v in self.infos.items():
            if isinstance(v, dict):
                arrays |= {f"info/{k}/{kk}": vv for kk, vv in v.items()}
            else:
                arrays[f"info/{k}"] = v
        arrays |= {
            "actions": self.actions,
            "rewards": self.rewards,
            "terminations": self.terminations,
            "truncations": self.truncations,
        }
        meta = {"seed": self.seed, "options": self.options, "record": self.record}
        arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
        buf = io.BytesIO()
        np.savez_compressed(buf, **arrays)
        return buf.getvalue()

    @classmethod
    def from_bytes(cls, data: bytes) -> RecordedEpisode:
        with np.load(io.BytesIO(data)) as z:
            arrays = {k: z[k] for k in z.files}
        meta = json.loads(arrays.pop("meta").tobytes().decode())
        obs = {k[4:]: v for k, v in arrays.items() if k.startswith("obs/")}
        infos: dict[str, Any] = {}
        for k, v in arrays.items():
            if k.startswith("info/"):
                parts = k.split("/")
                if len(parts) == 3:
                    infos.setdefault(parts[1], {})[parts[2]] = v
                else:
                    infos[parts[1]] = v
        return cls(
            seed=int(meta["seed"]),
            options=meta["options"],
            observations=obs,
            actions=arrays["actions"],
            rewards=arrays["rewards"],
            terminations=arrays["terminations"],
            truncations=arrays["truncations"],
            infos=infos,
            record=meta["record"],
        )


def reset_options(env: gym.Env, config: CollectConfig) -> dict[str, Any]:
    """The options that make ``reset(seed, options)`` start the episode the env just started
    (after a reset with the same seed): its object, table, scale, start pose and the
    randomisation values it drew (if any)."""
    base = env.unwrapped
    obj = config.object
    if obj == "random":
        obj = base.task.object.name
    table = base.task.table.name if config.table == "random" else config.table
    options: dict[str, Any] = {"object": obj, "table": table, "scale": float(config.scale)}
    if config.thickness is not None:
        options["thickness"] = float(config.thickness)
    options["object_pose"] = [float(v) for v in base.start_pose]
    if base.randomization_values:
        options["randomization"] = dict(base.randomization_values)
    return options


LABEL_KEY = "expert_action"
"""Step info of a DART collection: the expert's clean action of the step (zeros at reset)."""
CHUNK_KEY = "expert_chunk"
"""Step info of a DAgger rollout with chunk labels (``slide-gym dagger --chunk-labels K``):
the expert's own next actions from that step's state, ``(L, A)`` per step (NaN where none
was asked; zeros at reset)."""
DART_STREAM = 0xDA27
"""Mixed with the episode's seed into the seed of its DART noise."""


def dart_noise(
    sigma: float,
    seed: int,
    labels: list[np.ndarray],
    noisy_now: Callable[[], bool] | None = None,
) -> Any:
    """``perturb(action)`` for :func:`agents.episode.play_episode`: keeps the clean action
    in ``labels`` and returns it with seeded Gaussian noise (standard deviation ``sigma``) on
    every entry but the last (the hand command), clipped to [-1, 1]; only where
    ``noisy_now()`` is true, if given (the noise is drawn every step all the same, so each
    step's draw depends on its index alone)."""
    rng = np.random.default_rng([int(seed), DART_STREAM])

    def perturb(action: np.ndarray) -> np.ndarray:
        clean = np.asarray(action, dtype=np.float32).reshape(-1)
        labels.append(clean.copy())
        draw = rng.normal(0.0, sigma, size=len(clean) - 1).astype(np.float32)
        if noisy_now is not None and not noisy_now():
            return clean.copy()
        noisy = clean.copy()
        noisy[:-1] += draw
        return np.clip(noisy, -1.0, 1.0)

    return perturb


def record_episode(config: CollectConfig, seed: int) -> RecordedEpisode:
    """Run the expert of ``config`` for the episode of reset seed ``seed`` and record it
    (with ``config.action_noise``: DART, the executed actions noisy and the expert's clean
    ones in ``infos["expert_action"]``)."""
    from agents.episode import play_episode
    from agents.planner_agent import PlannerAgent

    env = gym.make(config.env_id, **config.env_kwargs())
    base = env.unwrapped
    observations: list[dict[str, np.ndarray]] = []
    infos: list[dict[str, Any]] = []
    steps: list[tuple[np.ndarray, float, bool, bool]] = []
    labels: list[np.ndarray] = []
    noise, phases = config.action_noise, config.noise_phases
    agent: PlannerAgent | None = None

    def noisy_now() -> bool:
        expert = None if agent is None else agent.expert(0)
        return expert is not None and phases is not None and expert.phase in phases

    perturb = dart_noise(noise, seed, labels, noisy_now if phases else None) if noise else None

    def on_reset(obs: dict[str, np.ndarray], info: dict[str, Any]) -> None:
        observations.append(obs)
        infos.append(step_info(info, base.get_state()))

    def on_step(action: Any, obs: Any, reward: float, term: bool, trunc: bool, info: Any) -> None:
        steps.append((np.asarray(action, dtype=np.float32).reshape(-1), reward, term, trunc))
        observations.append(obs)
        infos.append(step_info(info, base.get_state()))

    try:
        # The scene is drawn at reset; the agent is told its shapes to recognise them.
        env.reset(seed=seed)
        options = reset_options(env, config)
        agent = PlannerAgent(
            config.agent,
            config.time_budget,
            seed=seed,
            objects=[base.task.object],
            tables=[base.task.table],
            control_mode=config.control_mode,
            **config.agent_kwargs(),
        )
        try:
            record = play_episode(
                env,
                agent,
                seed=seed,
                options=options,
                on_reset=on_reset,
                on_step=on_step,
                perturb=perturb,
            )
        finally:
            agent.close()
    finally:
        env.close()
    actions = np.stack([s[0] for s in steps])
    stacked = stack_infos(infos)
    if perturb is not None:
        stacked[LABEL_KEY] = np.concatenate([np.zeros_like(actions[:1]), np.stack(labels)])
    return RecordedEpisode(
        seed=int(seed),
        options=options,
        observations={k: np.stack([o[k] for o in observations]) for k in observations[0]},
        actions=actions,
        rewards=np.array([s[1] for s in steps], dtype=np.float64),
        terminations=np.array([s[2] for s in steps], dtype=bool),
        truncations=np.array([s[3] for s in steps], dtype=bool),
        infos=stacked,
        record=record.to_json_dict(),
    )


def step_info(info: dict[str, Any], sim_state: np.ndarray) -> dict[str, Any]:
    """What a dataset keeps of one step's info (:data:`INFO_KEYS`, the state, the terms)."""
    out = {k: info[k] for k in INFO_KEYS}
    out["sim_state"] = sim_state
    out["reward_terms"] = dict(info["reward_terms"])
    return out


def stack_infos(infos: list[dict[str, Any]]) -> dict[str, Any]:
    """:func:`step_info` dicts of an episode as arrays (``reward_terms`` a dict of them)."""
    out: dict[str, Any] = {}
    for k in infos[0]:
        if k == "reward_terms":
            terms = infos[0][k]
            out[k] = {t: np.array([i[k][t] for i in infos], dtype=np.float64) for t in terms}
        elif isinstance(infos[0][k], (bool, np.bool_)):
            out[k] = np.array([i[k] for i in infos], dtype=bool)
        else:
            out[k] = np.array([i[k] for i in infos], dtype=np.float64)
    return out
