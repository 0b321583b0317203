"""Run an agent (a saved SB3 model, a diffusion policy or a planner) in a slide-gym env and
report its success.

:func:`evaluate` runs ``episodes`` episodes on held-out reset seeds (``seed``, ``seed + 1``,
...) and returns the success rate with its Wilson 95 % interval (:func:`wilson_interval`).
"""

from __future__ import annotations

import json
import sys
import time
import warnings
from collections import Counter
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from slide_gym import DICT_ENV_IDS
from slide_gym.planning.api import PLANNERS
from slide_gym.planning.result import check_time_budget
from slide_gym.splits import TEST_SEED
from slide_gym.stats import wilson_interval

RANDOM = "random"
"""The agent name of uniform random actions."""


def _is_int(value: Any) -> bool:
    return not isinstance(value, bool) and isinstance(value, (int, np.integer))


def _model_file(agent: str | Path) -> Path | None:
    """The existing ``.zip`` that ``agent`` names (with or without the suffix), or None."""
    path = Path(agent)
    for candidate in (path, path.with_name(path.name + ".zip")):
        if candidate.suffix == ".zip" and candidate.is_file():
            return candidate
    return None


def load_model(path: Path) -> Any:
    """``PPO.load(path)``, else ``SAC.load(path)`` (on the CPU); ValueError if neither opens it."""
    import torch
    from stable_baselines3 import PPO, SAC

    torch.set_num_threads(1)
    errors = []
    for cls in (PPO, SAC):
        try:
            return cls.load(path, device="cpu")
        except Exception as err:  # noqa: BLE001 - any failure means: try the next algorithm
            errors.append(f"{cls.__name__}: {type(err).__name__}: {err}")
    raise ValueError(f"cannot load {str(path)!r} as a PPO or SAC model ({'; '.join(errors)})")


def read_model_card(path: Path) -> dict[str, Any]:
    """The ``<model>.json`` next to ``path`` (same stem), or ``{}`` if there is none."""
    card = path.with_suffix(".json")
    if not card.is_file():
        return {}
    data = json.loads(card.read_text())
    if not isinstance(data, dict) or not isinstance(data.get("env_kwargs", {}), dict):
        raise ValueError(f"{str(card)!r}: expected a JSON object with an 'env_kwargs' object")
    return data


def _planner_agent(planner: str, env: gym.Env, seed: int, time_budget: float) -> Any:
    """A :class:`PlannerAgent` for the episode ``env`` was just reset to."""
    from agents.planner_agent import PlannerAgent

    u = env.unwrapped
    control = u.control
    return PlannerAgent(
        planner,
        time_budget,
        seed=seed,
        objects=[u.task.object],
        tables=[u.task.table],
        max_joint_step=u.max_joint_step,
        control_hz=1.0 / u.dt,
        control_mode=u.control_mode,
        max_tip_step=getattr(control, "max_tip_step", 0.01),
        max_rot_step=getattr(control, "max_rot_step", 0.05),
    )


class RandomAgent:
    """Uniform random actions in ``space`` from a seeded generator: the scale a learned
    policy is read against."""

    def __init__(self, space: gym.spaces.Box, seed: int = 0) -> None:
        self.space = space
        self.rng = np.random.default_rng(seed)

    def predict(
        self,
        observation: dict[str, np.ndarray],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        batch = np.asarray(observation["arm_qpos"]).shape[:-1]
        shape = (*batch, *self.space.shape)
        return self.rng.uniform(self.space.low, self.space.high, shape).astype(np.float32), state


def _open_agent(
    agent: Any,
    action_horizon: int | None = None,
    noise_scale: float | None = None,
    inference_steps: int | None = None,
    samples: int | None = None,
) -> tuple[str | None, Any, dict[str, Any]]:
    """``(planner name or None, policy with predict or None, its card)``: the card holds the
    ``env_id`` and ``env_kwargs`` it was trained with (``{}`` for planners and ``random``)."""
    sampling = {
        name: value
        for name, value in (
            ("action_horizon", action_horizon),
            ("noise_scale", noise_scale),
            ("inference_steps", inference_steps),
            ("samples", samples),
        )
        if value is not None
    }
    if sampling and not (isinstance(agent, (str, Path)) and Path(agent).is_dir()):
        raise ValueError(
            f"{' and '.join(sampling)} applies to a diffusion policy folder (from train-dp) "
            f"only, got the agent {str(agent)!r}"
        )
    if hasattr(agent, "predict"):
        return None, agent, dict(getattr(agent, "card", {}))
    if agent == RANDOM:
        return None, RANDOM, {}
    if isinstance(agent, str) and agent in PLANNERS:
        return agent, None, {}
    from agents.learned.policy import CARD_FILE, DiffusionPolicy, is_policy_dir

    if Path(agent).is_dir():
        if not is_policy_dir(agent):
            raise ValueError(
                f"{str(agent)!r} is a folder without a saved policy (policy.pt); "
                "train one with `slide-gym train-dp DATASET_ID --out DIR`"
            )
        policy = DiffusionPolicy.load(agent, **sampling)
        return None, policy, json.loads((Path(agent) / CARD_FILE).read_text())
    model_path = _model_file(agent)
    if model_path is None:
        raise ValueError(
            f"agent must be a planner ({', '.join(PLANNERS)}), {RANDOM!r}, a policy folder (from "
            f"train-dp) or an existing SB3 model .zip file, got {str(agent)!r}"
        )
    return None, load_model(model_path), read_model_card(model_path)


ENDINGS = ("success", "fell_off", "time_limit", "max_steps", "other")
"""How an evaluated episode ended (``results[i]["ended"]``): it succeeded, the plate fell
off the table (the envs end there), the env's time limit ran out, ``max_steps`` cut it, or
it terminated for another reason (e.g. a goal env's own ending)."""


def episode_ending(success: bool, terminated: bool, truncated: bool, info: dict) -> str:
    """Which of :data:`ENDINGS` an episode that stopped with these flags reached."""
    if success:
        return "success"
    if terminated and info.get("fell_off"):
        return "fell_off"
    if truncated:
        return "time_limit"
    return "other" if terminated else "max_steps"


def failure_summary(ended: dict[str, int]) -> str:
    """``"; failures: 9 fell off, 10 time limit"`` from an evaluation's ``ended`` counts
    (empty where every episode succeeded)."""
    parts = [f"{ended[kind]} {kind.replace('_', ' ')}" for kind in ENDINGS[1:] if ended.get(kind)]
    return f"; failures: {', '.join(parts)}" if parts else ""


def evaluate(
    agent: Any,
    env_id: str,
    *,
    episodes: int,
    seed: int = TEST_SEED,
    env_kwargs: dict[str, Any] | None = None,
    time_budget: float = 10.0,
    progress: bool = False,
    max_steps: int | None = None,
    action_horizon: int | None = None,
    noise_scale: float | None = None,
    inference_steps: int | None = None,
    samples: int | None = None,
) -> dict[str, Any]:
    """Run ``agent`` for ``episodes`` episodes of ``gym.make(env_id, **env_kwargs)`` with reset
    seeds ``seed``, ``seed + 1``, ... and report how often it succeeded.

    Args:
        agent: ``"random"`` (uniform random actions, seeded with ``seed``), a saved SB3 model
            (``.zip``; PPO, else SAC; acts with ``deterministic=True``),
            a diffusion-policy folder (``slide-gym train-dp``), any object with SB3's
            ``predict``, or a planner name (``"regions"``, ``"cbirrt"``, ``"cbirrt2"``: a
            :class:`~agents.planner_agent.PlannerAgent` per episode, seeded with the episode's
            seed, that knows the episode's object and table).
        env_id: one of ``slide_gym.DICT_ENV_IDS``.
        episodes: how many episodes (>= 1).
        seed: the first reset seed (default :data:`TEST_SEED`: held out from collection seeds
            from 0 and from the validation seeds of training).
        env_kwargs: env arguments; for a saved policy, those of its card (``<model>.json`` or
            ``policy.json``) are the defaults these override. A policy whose card names
            another env than ``env_id`` is evaluated in ``env_id`` with a warning.
        time_budget: the planner's seconds per episode (planners only).
        progress: print one line per episode to stderr.
        max_steps: stop an episode after this many steps and count it as a failure
            (default: the env's time limit only).
        action_horizon: a diffusion-policy folder's actions executed per chunk (default: the
            policy's own; :class:`~agents.learned.policy.DiffusionPolicy`).
        noise_scale: a diffusion-policy folder's initial sampling noise, scaled (default 1;
            :class:`~agents.learned.policy.DiffusionPolicy`).
        inference_steps: a diffusion-policy folder's DDIM steps per chunk (default: the
            policy's own, 10).
        samples: a diffusion-policy folder's chunks drawn per decision, of which it executes
            the medoid (default 1: one sample; :class:`~agents.learned.policy.DiffusionPolicy`).

    Returns:
        ``{"agent", "env_id", "env_kwargs", "episodes", "successes", "success_rate", "ci95",
        "mean_length", "ended", "seeds", "results": [{"seed", "success", "ended", "length",
        "return", "randomization"}], "wall_time_s"}`` (``randomization``: the episode's drawn
        values; ``ended``: one of :data:`ENDINGS` per episode, and their counts).
    """
    if not _is_int(episodes) or episodes < 1:
        raise ValueError(f"episodes must be a positive integer, got {episodes!r}")
    if not _is_int(seed) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    if max_steps is not None and (not _is_int(max_steps) or max_steps < 1):
        raise ValueError(f"max_steps must be a positive integer or None, got {max_steps!r}")
    if env_id not in DICT_ENV_IDS:
        raise ValueError(f"env_id must be one of {', '.join(DICT_ENV_IDS)}, got {env_id!r}")
    planner, model, card = _open_agent(agent, action_horizon, noise_scale, inference_steps, samples)
    if planner:
        check_time_budget(time_budget)
    trained_in = card.get("env_id")
    if trained_in is not None and trained_in != env_id:
        warnings.warn(
            f"the policy was trained in {trained_in}, not {env_id}: evaluating it in {env_id} "
            "as asked",
            stacklevel=2,
        )
    kwargs = {**dict(card.get("env_kwargs") or {}), **(env_kwargs or {})}

    env = gym.make(env_id, **kwargs)
    if model is RANDOM:
        model = RandomAgent(env.action_space, seed)
    wall = time.perf_counter()
    results: list[dict[str, Any]] = []
    try:
        if model is not None and hasattr(model, "observation_space"):
            for what, mine, theirs in (
                ("observation", model.observation_space, env.observation_space),
                ("action", model.action_space, env.action_space),
            ):
                if mine != theirs:
                    raise ValueError(
                        f"the model's {what} space does not match {env_id} with env_kwargs "
                        f"{kwargs}: {mine} vs {theirs}"
                    )
        for i in range(int(episodes)):
            ep_seed = int(seed) + i
            obs, info = env.reset(seed=ep_seed)
            drawn = info["randomization"]
            expert = _planner_agent(planner, env, ep_seed, time_budget) if planner else None
            steps, total, terminated, truncated = 0, 0.0, False, False
            try:
                while not (terminated or truncated):
                    if max_steps is not None and steps >= max_steps:
                        break
                    start = np.array([steps == 0])
                    if expert is not None:
                        action, _ = expert.predict(obs, episode_start=start)
                    else:
                        action, _ = model.predict(obs, episode_start=start, deterministic=True)
                    obs, reward, terminated, truncated, info = env.step(action)
                    steps += 1
                    total += float(reward)
            finally:
                if expert is not None:
                    expert.close()
            # the envs terminate on success: an episode cut by max_steps has not succeeded
            success = bool((terminated or truncated) and info["is_success"])
            ended = episode_ending(success, terminated, truncated, info)
            results.append(
                {
                    "seed": ep_seed,
                    "success": success,
                    "ended": ended,
                    "length": steps,
                    "return": total,
                    "randomization": drawn,
                }
            )
            if progress:
                done = sum(r["success"] for r in results)
                outcome = "success" if success else f"failure ({ended.replace('_', ' ')})"
                print(
                    f"episode {i + 1}/{episodes} seed {ep_seed}: "
                    f"{outcome} after {steps} steps "
                    f"({done}/{i + 1} so far)",
                    file=sys.stderr,
                    flush=True,
                )
    finally:
        env.close()
    k = sum(r["success"] for r in results)
    lo, hi = wilson_interval(k, len(results))
    return {
        "agent": str(agent),
        "env_id": env_id,
        "env_kwargs": kwargs,
        **({"action_horizon": action_horizon} if action_horizon is not None else {}),
        **({"noise_scale": noise_scale} if noise_scale is not None else {}),
        **({"inference_steps": inference_steps} if inference_steps is not None else {}),
        **({"samples": samples} if samples is not None else {}),
        "episodes": len(results),
        "successes": k,
        "success_rate": k / len(results),
        "ci95": [lo, hi],
        "mean_length": float(np.mean([r["length"] for r in results])),
        "ended": dict(Counter(r["ended"] for r in results)),
        "seeds": [r["seed"] for r in results],
        "results": results,
        "wall_time_s": time.perf_counter() - wall,
    }
