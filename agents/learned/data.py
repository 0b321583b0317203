"""Demonstrations as training windows for a chunked policy.

:func:`load_demonstrations` reads a Minari dataset's episodes (by default only those the
expert solved) into policy inputs and action labels; :class:`ChunkSampler` draws windows of
``obs_horizon`` inputs and ``pred_horizon`` actions from them. A window may start before an
episode (the first input and action repeat) or run past its end (padded with zero arm
motion and the last hand command: after the expert is done, the arm holds still).

Where an episode carries expert labels (``infos["expert_action"]``, written by a DART or
DAgger collection), those are the targets; the executed ``actions`` are only what moved the
simulator.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from agents.learned.features import policy_input
from slide_gym.datasets.recording import LABEL_KEY

MIN_STD = 1e-2
"""Floor of the standard deviations the inputs are divided by."""


@dataclass
class Demonstrations:
    """Episodes as flat arrays: ``inputs`` (N, D) and ``labels`` (N, A), with ``starts`` and
    ``lengths`` giving each episode's rows; ``seeds`` the episodes' reset seeds."""

    inputs: np.ndarray
    labels: np.ndarray
    starts: np.ndarray
    lengths: np.ndarray
    seeds: list[int]
    skipped: int

    @property
    def frames(self) -> int:
        return len(self.labels)

    @property
    def episodes(self) -> int:
        return len(self.lengths)

    def input_stats(self) -> tuple[np.ndarray, np.ndarray]:
        """Per-entry mean and standard deviation of the inputs (constant entries: std 1)."""
        mean = self.inputs.mean(axis=0, dtype=np.float64)
        std = self.inputs.std(axis=0, dtype=np.float64)
        std = np.where(std < 1e-6, 1.0, np.maximum(std, MIN_STD))
        return mean.astype(np.float32), std.astype(np.float32)

    def label_range(self) -> tuple[np.ndarray, np.ndarray]:
        """Per-entry minimum and maximum of the labels, zero included (the end padding);
        dropped labels (NaN) are left out."""
        low = np.minimum(np.nanmin(self.labels, axis=0), 0.0)
        high = np.maximum(np.nanmax(self.labels, axis=0), 0.0)
        return low.astype(np.float32), high.astype(np.float32)


def episode_labels(episode: Any) -> np.ndarray:
    """(T, A) targets of a Minari episode: the expert's labels if recorded, else its actions."""
    actions = np.asarray(episode.actions, np.float32)
    infos = episode.infos if isinstance(episode.infos, dict) else {}
    if LABEL_KEY in infos:
        labels = np.asarray(infos[LABEL_KEY], np.float32)[1:]  # infos are T + 1 long
        if labels.shape == actions.shape:
            return labels
    return actions


def load_demonstrations(
    dataset: Any, *, with_features: bool = True, only_success: bool = True
) -> Demonstrations:
    """The episodes of Minari ``dataset`` as :class:`Demonstrations`: those whose ``success``
    flag is set (all, if ``only_success`` is False), and every DAgger rollout (whatever the
    learner did, its labels are the expert's). ValueError if none is left."""
    episode_ids = list(range(dataset.total_episodes))
    metas = list(dataset.storage.get_episode_metadata(episode_ids))
    inputs, labels, lengths, seeds = [], [], [], []
    skipped = 0
    for episode, meta in zip(dataset.iterate_episodes(episode_ids), metas, strict=True):
        labelled_rollout = int(meta.get("dagger_round", 0)) > 0  # its labels are the expert's
        if only_success and not labelled_rollout and not bool(meta.get("success", True)):
            skipped += 1
            continue
        n = len(episode.actions)
        if n == 0:
            skipped += 1
            continue
        if not isinstance(episode.observations, dict):
            raise ValueError("the dataset's observations must be a Dict (a slide-gym env's)")
        obs = {k: np.asarray(v)[:n] for k, v in episode.observations.items()}
        inputs.append(policy_input(obs, with_features))
        labels.append(episode_labels(episode))
        lengths.append(n)
        seeds.append(int(meta.get("seed", -1)))
    if not lengths:
        raise ValueError(
            f"no episode to learn from: {skipped} of {dataset.total_episodes} were failures "
            "or empty (collect with --only-success, or pass only_success=False)"
        )
    lengths_arr = np.asarray(lengths)
    return Demonstrations(
        inputs=np.concatenate(inputs),
        labels=np.concatenate(labels),
        starts=np.concatenate([[0], np.cumsum(lengths_arr)[:-1]]),
        lengths=lengths_arr,
        seeds=seeds,
        skipped=skipped,
    )


class ChunkSampler:
    """Index tables of every window of :class:`Demonstrations` (one per step), and batches.

    Window ``t`` of an episode holds inputs ``t - obs_horizon + 1 .. t`` and actions
    ``t - obs_horizon + 1 .. t - obs_horizon + pred_horizon`` (clamped at the start, padded
    at the end), so the policy's chunk begins at its oldest observation, as in Chi et al.
    Windows that hold a dropped (NaN) label are left out and counted in ``dropped``.
    """

    def __init__(self, demos: Demonstrations, obs_horizon: int, pred_horizon: int) -> None:
        arm_dims = demos.labels.shape[1] - 1
        padded, obs_rows, act_rows = [], [], []
        offset = 0
        for start, n in zip(demos.starts, demos.lengths, strict=True):
            labels = demos.labels[start : start + n]
            pad = np.zeros((pred_horizon, labels.shape[1]), np.float32)
            pad[:, arm_dims:] = labels[-1, arm_dims:]  # hold the last hand command
            padded.append(np.concatenate([labels, pad]))
            t = np.arange(n)
            first = t - obs_horizon + 1
            obs_rows.append(start + np.clip(first[:, None] + np.arange(obs_horizon), 0, None))
            act_rows.append(offset + np.clip(first[:, None] + np.arange(pred_horizon), 0, None))
            offset += n + pred_horizon
        self.inputs = demos.inputs
        self.actions = np.concatenate(padded)
        obs_idx, act_idx = np.concatenate(obs_rows), np.concatenate(act_rows)
        # a window with a dropped label (a failed DAgger query) teaches nothing reliable
        valid = ~np.isnan(self.actions[act_idx]).any(axis=(1, 2))
        self.obs_rows, self.act_rows = obs_idx[valid], act_idx[valid]
        self.dropped = int((~valid).sum())

    def __len__(self) -> int:
        return len(self.obs_rows)

    def batch(self, rng: np.random.Generator, size: int) -> tuple[np.ndarray, np.ndarray]:
        """``size`` windows drawn uniformly with replacement: inputs (B, obs_horizon, D) and
        actions (B, pred_horizon, A)."""
        idx = rng.integers(0, len(self), size=size)
        return self.inputs[self.obs_rows[idx]], self.actions[self.act_rows[idx]]
