"""A trained diffusion policy as an agent with Stable-Baselines3's ``predict`` interface.

The agent keeps, per batch slot (one per env of a vectorised env), the last
``obs_horizon`` policy inputs and a queue of actions. When a slot's queue is empty it samples
a chunk of ``pred_horizon`` actions and queues ``action_horizon`` of them, starting at the
current step (receding horizon). ``episode_start`` (as ``evaluate_policy`` passes it) clears
a slot's history and queue. Slots that need a chunk on the same call are sampled in one batch.

A policy folder holds ``policy.pt`` (the EMA weights with their statistics and config) and
``policy.json`` (the env it acts in, the dataset and the training figures), written by
:func:`save_policy`; :meth:`DiffusionPolicy.load` opens it.
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
from agents.learned.features import policy_input
from slide_gym.planning.result import json_values

WEIGHTS_FILE = "policy.pt"
CARD_FILE = "policy.json"


def is_policy_dir(path: str | Path) -> bool:
    """True if ``path`` is a folder with a saved diffusion policy."""
    return (Path(path) / WEIGHTS_FILE).is_file()


def save_policy(model: DiffusionModel, folder: Path, card: dict[str, Any]) -> Path:
    """Write ``model`` (weights, statistics, config) and ``card`` (``env_id``,
    ``env_kwargs``, ...) into ``folder``; return the weights' path."""
    folder.mkdir(parents=True, exist_ok=True)
    blob = {
        "config": model.config.to_json(),
        "input_dim": model.input_dim,
        "action_dim": model.action_dim,
        "state_dict": model.state_dict(),
    }
    tmp = folder / (WEIGHTS_FILE + ".tmp")
    torch.save(blob, tmp)
    tmp.replace(folder / WEIGHTS_FILE)
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
        card: the policy card (``env_id``, ``env_kwargs``, ...), if loaded from a folder.
    """

    def __init__(
        self,
        model: DiffusionModel,
        *,
        seed: int = 0,
        inference_steps: int | None = None,
        action_horizon: int | None = None,
        card: dict[str, Any] | None = None,
    ) -> None:
        torch.set_num_threads(1)
        self.model = model.eval()
        self.config = model.config
        most = self.config.pred_horizon - self.config.obs_horizon + 1
        if action_horizon is None:
            action_horizon = self.config.action_horizon
        if (
            isinstance(action_horizon, bool)
            or not isinstance(action_horizon, int)
            or not (1 <= action_horizon <= most)
        ):
            raise ValueError(
                f"action_horizon must be a whole number in 1..{most} (pred_horizon - "
                f"obs_horizon + 1), got {action_horizon!r}"
            )
        self.action_horizon = action_horizon
        self.inference_steps = inference_steps
        self.card = dict(card or {})
        self.seed = int(seed)
        self.generator = torch.Generator().manual_seed(self.seed)
        self._history: list[list[np.ndarray]] = []
        self._queues: list[list[np.ndarray]] = []

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
        return cls(load_model(folder / WEIGHTS_FILE), card=card, **kwargs)

    def reset(self, seed: int | None = None) -> None:
        """Forget every slot's history and queue (and reseed the noise if ``seed`` is given)."""
        if seed is not None:
            self.seed = int(seed)
        self.generator = torch.Generator().manual_seed(self.seed)
        self._history, self._queues = [], []

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
        inputs = policy_input(obs, self.config.with_features)
        while len(self._history) < n:
            self._history.append([])
            self._queues.append([])
        for i in range(n):
            if starts[i] or not self._history[i]:
                self._history[i] = [inputs[i]] * self.config.obs_horizon
                self._queues[i] = []
            else:
                self._history[i] = [*self._history[i][1:], inputs[i]]
        need = [i for i in range(n) if not self._queues[i]]
        if need:
            window = torch.from_numpy(np.stack([np.stack(self._history[i]) for i in need]))
            chunks = self.model.sample(window, self.generator, self.inference_steps).numpy()
            first, count = self.config.obs_horizon - 1, self.action_horizon
            for i, chunk in zip(need, chunks, strict=True):
                actions = chunk_to_actions(chunk, first, count, self.config.actions)
                self._queues[i] = list(actions)
        actions = np.stack([self._queues[i].pop(0) for i in range(n)])
        actions = np.clip(actions, -1.0, 1.0).astype(np.float32)
        if self.config.hand == "binary":
            actions[:, -1] = np.where(actions[:, -1] > 0.0, 1.0, -1.0)
        return (actions if batched else actions[0]), state
