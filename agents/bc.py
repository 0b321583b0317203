"""Behaviour cloning: fit a Stable-Baselines3 policy to the actions of a Minari dataset.

:func:`train_bc` trains the actor of a ``PPO("MultiInputPolicy")`` by maximum likelihood on
every ``(observation, action)`` pair of the dataset, so the result saves with ``model.save`` and
opens with ``PPO.load`` like any SB3 model; ``predict(obs, deterministic=True)`` gives the
Gaussian's mean. :func:`write_model_card` writes the ``<model>.json`` that
:func:`agents.evaluate.evaluate` reads the environment settings from.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np
import torch
from gymnasium import spaces
from stable_baselines3 import PPO
from stable_baselines3.common.preprocessing import get_flattened_obs_dim
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor

from slide_gym.planning.result import json_values

if TYPE_CHECKING:
    import minari

ACTION_EPS = 1e-6
"""Dataset actions are clipped to ``[-1 + ACTION_EPS, 1 - ACTION_EPS]`` before the fit."""
NET_ARCH = [256, 256]
LOG_STD_INIT = -1.0
OBS_CLIP = 10.0
"""Normalised observation entries are clipped to +-this (as ``VecNormalize`` does)."""
MIN_STD = 1e-2
"""Floor of the per-entry standard deviation the observations are divided by."""


class NormalizedFlattenExtractor(BaseFeaturesExtractor):
    """Flattens a ``Dict`` of ``Box`` observations (in the space's key order) and standardises
    each entry with the dataset's mean and standard deviation (buffers, saved with the model);
    the identity until :meth:`set_stats` is called."""

    def __init__(self, observation_space: spaces.Dict, clip: float = OBS_CLIP) -> None:
        sizes = [get_flattened_obs_dim(s) for s in observation_space.spaces.values()]
        super().__init__(observation_space, features_dim=int(sum(sizes)))
        self.keys = list(observation_space.spaces)
        self.clip = float(clip)
        self.register_buffer("obs_mean", torch.zeros(self.features_dim))
        self.register_buffer("obs_std", torch.ones(self.features_dim))

    def set_stats(self, mean: np.ndarray, std: np.ndarray) -> None:
        """Use ``mean`` and ``std`` (flat, in key order) from now on."""
        self.obs_mean.copy_(torch.as_tensor(mean, dtype=torch.float32))
        self.obs_std.copy_(torch.as_tensor(std, dtype=torch.float32))

    def forward(self, observations: dict[str, torch.Tensor]) -> torch.Tensor:
        flat = torch.cat([observations[k].flatten(1).float() for k in self.keys], dim=1)
        return torch.clamp((flat - self.obs_mean) / self.obs_std, -self.clip, self.clip)


def _check_spaces(dataset: minari.MinariDataset, env: gym.Env) -> None:
    """ValueError unless the dataset's spaces are the env's (and a Dict of Boxes)."""
    if dataset.observation_space != env.observation_space:
        raise ValueError(
            "the dataset's observation space does not match the env's: "
            f"{dataset.observation_space} vs {env.observation_space}"
        )
    if dataset.action_space != env.action_space:
        raise ValueError(
            "the dataset's action space does not match the env's: "
            f"{dataset.action_space} vs {env.action_space}"
        )
    obs_space, act_space = env.observation_space, env.action_space
    if not isinstance(obs_space, spaces.Dict) or not all(
        isinstance(s, spaces.Box) for s in obs_space.spaces.values()
    ):
        raise ValueError(f"train_bc needs a Dict of Box observations, got {obs_space}")
    if not isinstance(act_space, spaces.Box) or len(act_space.shape) != 1:
        raise ValueError(f"train_bc needs a 1-D Box action space, got {act_space}")


def load_pairs(
    dataset: minari.MinariDataset, only_success: bool = True
) -> tuple[dict[str, np.ndarray], np.ndarray, int]:
    """All ``(observation_t, action_t)`` pairs of ``dataset`` (each episode's last observation
    has no action and is dropped): float32 observation arrays by key, the actions, and the
    number of episodes. ``only_success``: leave out episodes whose ``success`` flag is unset
    (a failed or idle expert episode teaches the wrong thing; an episode without the flag,
    from another tool, is kept). Unlike :func:`agents.learned.data.load_demonstrations`, a
    failed DAgger rollout is left out too: behaviour cloning fits the executed actions,
    which there are the learner's."""
    obs: dict[str, list[np.ndarray]] = {}
    actions: list[np.ndarray] = []
    episodes = 0
    ids = list(range(dataset.total_episodes))
    metas = list(dataset.storage.get_episode_metadata(ids))
    for ep, meta in zip(dataset.iterate_episodes(ids), metas, strict=True):
        if only_success and not bool(meta.get("success", True)):
            continue
        n = len(ep.actions)
        if not isinstance(ep.observations, dict):
            raise ValueError("train_bc needs Dict observations in the dataset")
        for key, value in ep.observations.items():
            value = np.asarray(value, np.float32)
            if len(value) != n + 1:
                raise ValueError(
                    f"episode {ep.id}: {len(value)} {key!r} observations for {n} actions "
                    "(Minari stores one more observation than actions)"
                )
            obs.setdefault(key, []).append(value[:n].reshape(n, -1))
        actions.append(np.asarray(ep.actions, np.float32).reshape(n, -1))
        episodes += 1
    if not actions or sum(len(a) for a in actions) == 0:
        which = "successful episode" if only_success else "episode"
        raise ValueError(
            f"the dataset has no {which} with steps (collect with --only-success"
            + (", or train with --no-only-success)" if only_success else ")")
        )
    return {k: np.concatenate(v) for k, v in obs.items()}, np.concatenate(actions), episodes


def _obs_stats(obs: dict[str, np.ndarray], keys: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Per-entry mean and std (flat, in ``keys`` order); a constant entry keeps std 1."""
    flat = np.concatenate([obs[k] for k in keys], axis=1).astype(np.float64)
    mean, std = flat.mean(axis=0), flat.std(axis=0)
    std = np.where(std < 1e-6, 1.0, np.maximum(std, MIN_STD))
    return mean, std


def train_bc(
    dataset: minari.MinariDataset,
    *,
    steps: int = 2000,
    batch_size: int = 256,
    learning_rate: float = 1e-3,
    seed: int = 0,
    env: gym.Env | None = None,
    log_every: int = 0,
    normalize_obs: bool = True,
    only_success: bool = True,
) -> tuple[PPO, dict[str, Any]]:
    """Behaviour cloning: ``steps`` Adam steps on the mean negative log-likelihood of the
    dataset's actions under a ``PPO("MultiInputPolicy")`` actor (MLP 256-256, state-independent
    ``log_std`` from -1); the value head is left untrained.

    Args:
        dataset: a Minari dataset with Dict observations and Box actions.
        steps, batch_size, learning_rate: the optimisation; minibatches are drawn uniformly
            with replacement from all pairs by ``numpy.random.default_rng(seed)``.
        seed: the policy's initialisation and the minibatches: the same seed, data and
            arguments give the same weights.
        env: the env the model is built for (its spaces must be the dataset's); default
            ``dataset.recover_environment()``. It stays open as ``model.env``.
        log_every: print the mean loss every this many steps to stderr (0: never).
        normalize_obs: standardise observations with the dataset's statistics inside the
            policy (:class:`NormalizedFlattenExtractor`, saved with the model).
        only_success: fit only the episodes whose ``success`` flag is set (see
            :func:`load_pairs`); False: every episode, failed and idle ones too.

    Returns:
        The model and ``{"steps", "final_loss" (mean of the last tenth of the steps, at most
        100), "initial_loss" (the first minibatch, before any update), "train_time_s",
        "frames", "episodes", "batch_size", "learning_rate", "seed", "normalize_obs",
        "only_success"}``.
    """
    for name, value in (("steps", steps), ("batch_size", batch_size)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ValueError(f"{name} must be a positive integer, got {value!r}")
    if not (np.isfinite(learning_rate) and learning_rate > 0):
        raise ValueError(f"learning_rate must be a positive number, got {learning_rate!r}")
    if log_every < 0:
        raise ValueError(f"log_every must be >= 0, got {log_every!r}")
    if dataset.total_episodes == 0 or dataset.total_steps == 0:
        raise ValueError("the dataset is empty (no episodes with steps)")
    torch.set_num_threads(1)
    env = dataset.recover_environment() if env is None else env
    _check_spaces(dataset, env)
    obs, actions, episodes = load_pairs(dataset, only_success)
    actions = np.clip(actions, -1 + ACTION_EPS, 1 - ACTION_EPS).astype(np.float32)
    frames = len(actions)

    policy_kwargs: dict[str, Any] = dict(net_arch=NET_ARCH, log_std_init=LOG_STD_INIT)
    if normalize_obs:
        policy_kwargs["features_extractor_class"] = NormalizedFlattenExtractor
    model = PPO("MultiInputPolicy", env, seed=seed, device="cpu", policy_kwargs=policy_kwargs)
    policy = model.policy
    keys = list(env.observation_space.spaces)  # type: ignore[attr-defined]
    if normalize_obs:
        mean, std = _obs_stats(obs, keys)
        for module in policy.modules():
            if isinstance(module, NormalizedFlattenExtractor):
                module.set_stats(mean, std)

    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    optimizer = torch.optim.Adam(policy.parameters(), lr=learning_rate)
    policy.set_training_mode(True)
    obs_t = {k: torch.from_numpy(np.ascontiguousarray(obs[k])) for k in keys}
    act_t = torch.from_numpy(actions)
    losses: list[float] = []
    start = time.perf_counter()
    for step in range(1, int(steps) + 1):
        idx = torch.from_numpy(rng.integers(0, frames, size=int(batch_size)))
        batch = {k: v[idx] for k, v in obs_t.items()}
        log_prob = policy.get_distribution(batch).log_prob(act_t[idx])
        loss = -log_prob.mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        losses.append(float(loss.detach()))
        if log_every and step % log_every == 0:
            recent = float(np.mean(losses[-log_every:]))
            print(f"bc step {step}/{steps}: loss {recent:.4f}", file=sys.stderr, flush=True)
    policy.set_training_mode(False)
    window = max(1, min(100, len(losses) // 10))
    stats = {
        "steps": int(steps),
        "final_loss": float(np.mean(losses[-window:])),
        "initial_loss": losses[0],
        "train_time_s": time.perf_counter() - start,
        "frames": int(frames),
        "episodes": int(episodes),
        "batch_size": int(batch_size),
        "learning_rate": float(learning_rate),
        "seed": int(seed),
        "normalize_obs": bool(normalize_obs),
        "only_success": bool(only_success),
    }
    return model, stats


def model_zip_path(model_path: str | Path) -> Path:
    """The file SB3 saves ``model_path`` as: the path itself if it ends in ``.zip``, else with
    ``.zip`` appended."""
    path = Path(model_path)
    return path if path.suffix == ".zip" else path.with_name(path.name + ".zip")


def model_card_path(model_path: str | Path) -> Path:
    """``<model>.json`` next to the model's ``.zip`` (same stem)."""
    return model_zip_path(model_path).with_suffix(".json")


def write_model_card(
    model_path: Path, env_id: str, env_kwargs: dict[str, Any], extra: dict[str, Any]
) -> Path:
    """Write ``{"env_id", "env_kwargs", **extra}`` to ``<model>.json`` next to the model's
    ``.zip`` (``evaluate`` takes its env_kwargs as defaults); return that path."""
    clash = {"env_id", "env_kwargs"} & set(extra)
    if clash:
        raise ValueError(f"extra must not contain {sorted(clash)}")
    card = {"env_id": env_id, "env_kwargs": dict(env_kwargs), **extra}
    try:
        text = json.dumps(json_values(card), indent=2)
    except TypeError as err:
        raise ValueError(f"model card: {err}") from err
    path = model_card_path(model_path)
    path.write_text(text + "\n")
    return path
