"""Reading SB3-style ``predict`` arguments: one observation or a batch from a VecEnv."""

from __future__ import annotations

from typing import Any

import numpy as np


def as_batch(
    observation: Any, episode_start: Any
) -> tuple[dict[str, np.ndarray], bool, np.ndarray]:
    """``(batch, batched, starts)``: the Dict observation with a leading batch axis (added
    for a single one), whether it came batched, and ``episode_start`` as ``(n,)`` bools
    (all False when None). ValueError for anything but a slide-gym Dict observation, or a
    ``episode_start`` of another length."""
    if not isinstance(observation, dict) or "arm_qpos" not in observation:
        raise ValueError("observation must be a slide-gym Dict observation (with 'arm_qpos')")
    batched = np.asarray(observation["arm_qpos"]).ndim == 2
    batch = {k: np.asarray(v) if batched else np.asarray(v)[None] for k, v in observation.items()}
    n = len(batch["arm_qpos"])
    starts = np.zeros(n, bool) if episode_start is None else np.asarray(episode_start, bool)
    starts = starts.reshape(-1)
    if len(starts) != n:
        raise ValueError(f"episode_start has {len(starts)} entries for {n} observations")
    return batch, batched, starts
