"""A trained diffusion policy as an agent with Stable-Baselines3's ``predict`` interface.

The agent keeps, per batch slot (one per env of a vectorised env), the last
``obs_horizon`` policy inputs and a queue of actions. When a slot's queue is empty it samples
a chunk of ``pred_horizon`` actions and queues ``action_horizon`` of them, starting at the
current step (receding horizon). ``episode_start`` (as ``evaluate_policy`` passes it) clears
a slot's history and queue. Slots that need a chunk on the same call are sampled in one batch.

A policy folder holds ``policy.pt`` (the EMA weights with their statistics and config) and
``policy.json`` (the env it acts in, the dataset and the training figures), written by
:func:`save_policy`; :meth:`DiffusionPolicy.load` opens it. A policy trained to take over
after a slide (``slide-gym train-dp --after SLIDE_POLICY``) also holds ``first.pt``, the
sliding skill: each slot runs that one until its observation shows the slide done
(:func:`~agents.learned.features.slide_done`), then this folder's model, with a fresh history
and queue, until the episode ends.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import torch

from agents.batch import as_batch
from agents.learned.data import chunk_to_actions
from agents.learned.diffusion import DiffusionConfig, DiffusionModel
from agents.learned.features import policy_input, slide_done
from agents.learned.frames import TARGET_SIZE, step_toward, task_frames
from slide_gym.envs.control import EE_ACTION_SIZE, MAX_ROT_STEP, MAX_TIP_STEP
from slide_gym.planning.result import json_values

WEIGHTS_FILE = "policy.pt"
FIRST_FILE = "first.pt"
CARD_FILE = "policy.json"
MAX_SAMPLES = 64
"""The most chunks :class:`DiffusionPolicy` draws per decision (``samples``)."""


def is_policy_dir(path: str | Path) -> bool:
    """True if ``path`` is a folder with a saved diffusion policy."""
    return (Path(path) / WEIGHTS_FILE).is_file()


def _save_model(model: DiffusionModel, path: Path) -> None:
    blob = {
        "config": model.config.to_json(),
        "input_dim": model.input_dim,
        "action_dim": model.action_dim,
        "state_dict": model.state_dict(),
    }
    tmp = path.with_name(path.name + ".tmp")
    torch.save(blob, tmp)
    tmp.replace(path)


def save_policy(
    model: DiffusionModel,
    folder: Path,
    card: dict[str, Any],
    first: DiffusionModel | None = None,
) -> Path:
    """Write ``model`` (weights, statistics, config), the sliding skill ``first`` that acts
    before it (if any) and ``card`` (``env_id``, ``env_kwargs``, ...) into ``folder``; return
    the weights' path."""
    folder.mkdir(parents=True, exist_ok=True)
    if first is not None:
        _save_model(first, folder / FIRST_FILE)
    _save_model(model, folder / WEIGHTS_FILE)
    (folder / CARD_FILE).write_text(json.dumps(json_values(card), indent=2) + "\n")
    return folder / WEIGHTS_FILE


def load_model(path: Path) -> DiffusionModel:
    """The :class:`DiffusionModel` saved at ``path`` (a ``policy.pt`` or a checkpoint)."""
    blob = torch.load(path, map_location="cpu", weights_only=False)
    config = DiffusionConfig(**{**blob["config"], "channels": tuple(blob["config"]["channels"])})
    model = DiffusionModel(config, blob["input_dim"], blob["action_dim"])
    model.load_state_dict(blob["state_dict"] if "state_dict" in blob else blob["ema"]["model"])
    return model.eval()


class DiffusionPolicy:
    """Acts with a :class:`DiffusionModel` in a slide-gym env (single or vectorised).

    Args:
        model: the trained model (its EMA weights).
        seed: seeds the initial noise of every chunk; the same seed and observations give the
            same actions.
        inference_steps: DDIM steps per chunk (default: the model's).
        action_horizon: actions of each chunk executed before sampling the next (default:
            the model's; at most ``pred_horizon - obs_horizon + 1``). Fewer react sooner to
            what the plate does, at one sample per that many steps.
        noise_scale: the initial noise of each chunk's DDIM sampling, scaled (default 1: a
            sample of the learned action distribution; 0 starts every chunk from zero noise,
            a deterministic function of the observations). A number in [0, 1].
        samples: chunks drawn for each decision (default 1). With more, the one executed is
            their medoid: the sample whose executed actions lie nearest the others' (summed
            Euclidean distance in the model's standardised action units), so a stray sample
            is outvoted while the chosen chunk is still one the model drew. 1..64.
        card: the policy card (``env_id``, ``env_kwargs``, ...), if loaded from a folder.
        first: a sliding skill that acts until the observation shows the slide done
            (:func:`~agents.learned.features.slide_done`); ``model`` acts from then on.
    """

    def __init__(
        self,
        model: DiffusionModel,
        *,
        seed: int = 0,
        inference_steps: int | None = None,
        action_horizon: int | None = None,
        noise_scale: float = 1.0,
        samples: int = 1,
        card: dict[str, Any] | None = None,
        first: DiffusionModel | None = None,
    ) -> None:
        torch.set_num_threads(1)
        self.model = model.eval()
        self.config = model.config
        # the skills in the order they act: [first,] model
        self.skills = [first.eval(), self.model] if first is not None else [self.model]
        if first is not None and _env_action_dim(first) != _env_action_dim(model):
            raise ValueError(
                f"the first skill's actions ({_env_action_dim(first)} entries) differ from "
                f"the policy's ({_env_action_dim(model)})"
            )
        self.horizons = [self._action_horizon(m.config, action_horizon) for m in self.skills]
        self.action_horizon = self.horizons[-1]
        self.inference_steps = self._inference_steps(model.config, inference_steps)
        self.noise_scale = self._noise_scale(noise_scale)
        self.samples = _whole_number("samples", samples, MAX_SAMPLES)
        self.card = dict(card or {})
        env_kwargs = self.card.get("env_kwargs") or {}
        self.max_steps = (
            float(env_kwargs.get("max_tip_step", MAX_TIP_STEP)),
            float(env_kwargs.get("max_rot_step", MAX_ROT_STEP)),
        )
        self.seed = int(seed)
        self.generator = torch.Generator().manual_seed(self.seed)
        self._history: list[list[np.ndarray]] = []
        self._queues: list[list[np.ndarray]] = []
        self._skill: list[int] = []  # per slot: the index in self.skills acting now
        self._frames: list[np.ndarray | None] = []  # per slot: the task frame of "targets"

    @staticmethod
    def _action_horizon(config: DiffusionConfig, action_horizon: int | None) -> int:
        if action_horizon is None:
            return config.action_horizon
        most = config.pred_horizon - config.obs_horizon + 1
        return _whole_number(
            "action_horizon", action_horizon, most, "pred_horizon - obs_horizon + 1"
        )

    @staticmethod
    def _inference_steps(config: DiffusionConfig, steps: int | None) -> int | None:
        if steps is None:
            return None
        return _whole_number(
            "inference_steps", steps, config.train_steps, "the model's training diffusion steps"
        )

    @staticmethod
    def _noise_scale(noise_scale: float) -> float:
        if (
            isinstance(noise_scale, bool)
            or not isinstance(noise_scale, (int, float))
            or not 0.0 <= noise_scale <= 1.0
        ):
            raise ValueError(f"noise_scale must be a number in [0, 1], got {noise_scale!r}")
        return float(noise_scale)

    @classmethod
    def load(cls, folder: str | Path, **kwargs: Any) -> DiffusionPolicy:
        """The policy saved in ``folder``; ValueError if there is none."""
        folder = Path(folder)
        if not is_policy_dir(folder):
            raise ValueError(
                f"{str(folder)!r} holds no diffusion policy (no {WEIGHTS_FILE}); train one with "
                "`slide-gym train-dp DATASET_ID --out DIR`"
            )
        card_path = folder / CARD_FILE
        card = json.loads(card_path.read_text()) if card_path.is_file() else {}
        first = load_model(folder / FIRST_FILE) if (folder / FIRST_FILE).is_file() else None
        return cls(load_model(folder / WEIGHTS_FILE), card=card, first=first, **kwargs)

    def reset(self, seed: int | None = None) -> None:
        """Forget every slot's history and queue (and reseed the noise if ``seed`` is given)."""
        if seed is not None:
            self.seed = int(seed)
        self.generator = torch.Generator().manual_seed(self.seed)
        self._history, self._queues, self._skill, self._frames = [], [], [], []

    def predict(
        self,
        observation: dict[str, np.ndarray],
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """The action for one observation (A,) or a batch (n, A); ``state`` is passed through.
        Sampling is deterministic given the seed either way (DDIM with eta 0)."""
        obs, batched, starts = as_batch(observation, episode_start)
        n = len(starts)
        while len(self._history) < n:
            self._history.append([])
            self._queues.append([])
            self._skill.append(0)
            self._frames.append(None)
        done = slide_done(obs) if len(self.skills) > 1 else np.zeros(n, dtype=bool)
        fresh = np.zeros(n, dtype=bool)
        for i in range(n):
            if starts[i] or not self._history[i]:
                self._skill[i], fresh[i] = 0, True
            if self._skill[i] < len(self.skills) - 1 and done[i]:
                self._skill[i], fresh[i] = self._skill[i] + 1, True
        inputs: dict[tuple[bool, bool], np.ndarray] = {}
        for k, skill in enumerate(self.skills):
            slots = [i for i in range(n) if self._skill[i] == k]
            if not slots:
                continue
            config = skill.config
            key = (config.with_features, config.tip_axes)
            if key not in inputs:
                inputs[key] = policy_input(obs, *key)
            rows = inputs[key]
            for i in slots:
                if fresh[i]:
                    self._history[i] = [rows[i]] * config.obs_horizon
                    self._queues[i] = []
                    if config.actions == "targets":
                        self._frames[i] = task_frames({k: v[i : i + 1] for k, v in obs.items()})[0]
                else:
                    self._history[i] = [*self._history[i][1:], rows[i]]
            need = [i for i in slots if not self._queues[i]]
            if need:
                window = torch.from_numpy(np.stack([np.stack(self._history[i]) for i in need]))
                first, count = config.obs_horizon - 1, self.horizons[k]
                chunks = self._sample_chunks(skill, window, first, count)
                for i, chunk in zip(need, chunks, strict=True):
                    actions = chunk_to_actions(chunk, first, count, config.actions)
                    if config.hand == "binary":
                        actions[:, -1] = np.where(actions[:, -1] > 0.0, 1.0, -1.0)
                    self._queues[i] = list(actions)
        actions = np.stack([self._env_action(i, obs) for i in range(n)])
        actions = np.clip(actions, -1.0, 1.0).astype(np.float32)
        return (actions if batched else actions[0]), state

    def _sample_chunks(
        self, skill: DiffusionModel, window: torch.Tensor, first: int, count: int
    ) -> np.ndarray:
        """One chunk per window: a sample, or the medoid of :attr:`samples` samples by their
        executed entries ``first:first + count``."""
        k = self.samples
        drawn = skill.sample(
            window.repeat_interleave(k, dim=0),
            self.generator,
            self.inference_steps,
            self.noise_scale,
        )
        if k == 1:
            return drawn.numpy()
        drawn = drawn.view(len(window), k, *drawn.shape[1:])
        executed = skill.normalize_action(drawn)[:, :, first : first + count].flatten(2)
        medoid = torch.cdist(executed, executed).sum(dim=-1).argmin(dim=-1)
        return drawn[torch.arange(len(window)), medoid].numpy()

    def _env_action(self, slot: int, obs: dict[str, np.ndarray]) -> np.ndarray:
        """The next queued entry of ``slot`` as an env action (a target: the step toward it)."""
        entry = self._queues[slot].pop(0)
        if self.skills[self._skill[slot]].config.actions != "targets":
            return entry
        frame = self._frames[slot]
        assert frame is not None
        arm = step_toward(entry[:-1], frame, obs["arm_qpos"][slot], *self.max_steps)
        return np.concatenate([arm, entry[-1:]])


def _whole_number(name: str, value: Any, most: int, why: str = "") -> int:
    """``value`` if it is an int in 1..``most``; else ValueError naming ``name`` (and why
    ``most`` is the limit)."""
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= most:
        limit = f" ({why})" if why else ""
        raise ValueError(f"{name} must be a whole number in 1..{most}{limit}, got {value!r}")
    return value


def _env_action_dim(model: DiffusionModel) -> int:
    """Entries of the env action a model's chunks stand for."""
    if model.config.actions == "targets":
        return model.action_dim - TARGET_SIZE + EE_ACTION_SIZE - 1
    return model.action_dim
