"""Demonstrations as training windows for a chunked policy.

:func:`load_demonstrations` reads a Minari dataset's episodes (by default only those the
expert solved) into policy inputs and action labels; :class:`ChunkSampler` draws windows of
``obs_horizon`` inputs and ``pred_horizon`` actions from them. A window may start before an
episode (the first input repeats; the steps before it are no arm motion and the first hand
command) or run past its end (zero arm motion and the last hand command: after the expert
is done, the arm holds still).

Where an episode carries expert labels (``infos["expert_action"]``, written by a DART or
DAgger collection), those are the targets; the executed ``actions`` are only what moved the
simulator. Where a DAgger rollout carries chunk labels (``infos["expert_chunk"]``: the
expert's own next actions from a step's state), its windows are those steps only, each
with its chunk label after the executed actions before the step.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from agents.learned.features import policy_input, slide_done
from agents.learned.frames import arm_fingertip_poses, targets_in_frame, task_frames
from slide_gym.datasets.recording import CHUNK_KEY, LABEL_KEY
from slide_gym.envs.control import EE_ACTION_SIZE

MIN_STD = 1e-2
"""Floor of the standard deviations the inputs are divided by."""


@dataclass
class Demonstrations:
    """Episodes as flat arrays: ``inputs`` (N, D) and ``labels`` (N, A), with ``starts`` and
    ``lengths`` giving each episode's rows; ``seeds`` the episodes' reset seeds. ``chunks``:
    per episode, its chunk labels (n, L, A) (NaN at steps without one; its ``labels`` are
    then the executed actions) or None."""

    inputs: np.ndarray
    labels: np.ndarray
    starts: np.ndarray
    lengths: np.ndarray
    seeds: list[int]
    skipped: int
    chunks: list[np.ndarray | None] | None = None

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
    dataset: Any,
    *,
    with_features: bool = True,
    tip_axes: bool = False,
    only_success: bool = True,
    after_slide: bool = False,
    targets: bool = False,
    episode_seeds: frozenset[int] | None = None,
) -> Demonstrations:
    """The episodes of Minari ``dataset`` as :class:`Demonstrations`: those whose ``success``
    flag is set (all, if ``only_success`` is False), and every DAgger rollout (whatever the
    learner did, its labels are the expert's). ``after_slide``: each episode from its first
    step where :func:`~agents.learned.features.slide_done` holds (an episode where it never
    does is skipped), the part a skill that takes over after a slide learns from.
    ``with_features``, ``tip_axes``: the inputs, as :func:`~agents.learned.features.policy_input`.
    ``targets``: the arm labels are the arm's fingertip poses after each step, in the task
    frame of the episode's first kept observation (:mod:`agents.learned.frames`; ``ee_delta``
    demonstrations only, and not relabelled ones). ``episode_seeds``: only the episodes reset
    with one of these seeds (ValueError if one of them is in no episode). ValueError if none
    is left."""
    episode_ids = list(range(dataset.total_episodes))
    metas = list(dataset.storage.get_episode_metadata(episode_ids))
    if episode_seeds is not None:
        missing = sorted(set(episode_seeds) - {int(m.get("seed", -1)) for m in metas})
        if missing:
            raise ValueError(
                f"{len(missing)} of the {len(episode_seeds)} episode seeds are in no episode "
                f"of the dataset (first: {missing[:5]}); list seeds of its episodes"
            )
    inputs, labels, lengths, seeds = [], [], [], []
    chunk_labels: list[np.ndarray | None] = []
    skipped = 0
    for episode, meta in zip(dataset.iterate_episodes(episode_ids), metas, strict=True):
        labelled_rollout = int(meta.get("dagger_round", 0)) > 0  # its labels are the expert's
        if episode_seeds is not None and int(meta.get("seed", -1)) not in episode_seeds:
            skipped += 1
            continue
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
        episode_targets = episode_labels(episode)
        infos = episode.infos if isinstance(episode.infos, dict) else {}
        chunk = None
        if labelled_rollout and CHUNK_KEY in infos:
            chunk = np.asarray(infos[CHUNK_KEY], np.float32)[1 : n + 1]
            if np.isfinite(chunk).all(axis=(1, 2)).any():
                episode_targets = np.asarray(episode.actions, np.float32)
            else:
                chunk = None  # no chunk was labelled: the per-step labels teach
        first = 0
        if after_slide:
            done = np.flatnonzero(slide_done(obs))
            if len(done) == 0:
                skipped += 1
                continue
            first = int(done[0])
            obs = {k: v[first:] for k, v in obs.items()}
            episode_targets, n = episode_targets[first:], n - first
            chunk = None if chunk is None else chunk[first:]
        if targets:
            episode_targets = _pose_targets(episode, obs, episode_targets, first)
        inputs.append(policy_input(obs, with_features, tip_axes))
        labels.append(episode_targets)
        lengths.append(n)
        seeds.append(int(meta.get("seed", -1)))
        chunk_labels.append(chunk)
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
        chunks=chunk_labels if any(c is not None for c in chunk_labels) else None,
    )


def _pose_targets(
    episode: Any, obs: dict[str, np.ndarray], labels: np.ndarray, first: int
) -> np.ndarray:
    """(n, TARGET_SIZE + 1) labels of ``"targets"``: the arm's fingertip pose after each kept
    step in the task frame of the first kept observation, then the hand command."""
    if labels.shape[1] != EE_ACTION_SIZE:
        raise ValueError(
            f"fingertip targets need ee_delta demonstrations ({EE_ACTION_SIZE} action "
            f"entries), got {labels.shape[1]}: collect with --control-mode ee_delta"
        )
    infos = episode.infos if isinstance(episode.infos, dict) else {}
    if LABEL_KEY in infos:
        raise ValueError(
            "fingertip targets are the demonstrated motion itself, so they cannot learn from "
            "relabelled (DART or DAgger) episodes; use --actions deltas"
        )
    after = np.asarray(episode.observations["arm_qpos"])[first + 1 : first + 1 + len(labels)]
    frame = task_frames({k: v[:1] for k, v in obs.items()})[0]
    poses = targets_in_frame(arm_fingertip_poses(after), frame)
    return np.column_stack([poses, labels[:, -1:]]).astype(np.float32)


def chunk_label_length(obs_horizon: int, pred_horizon: int) -> int:
    """Steps a chunk label holds: the part of a chunk predicted from its step on (the entries
    before it are actions already executed)."""
    return int(pred_horizon) - int(obs_horizon) + 1


ACTION_REPRESENTATIONS = ("offsets", "deltas", "targets")
"""How a chunk holds the arm part of its actions: ``"offsets"`` (each step's target relative
to the target before the window's current step, the running sum of the increments: a short
trajectory, as position control is in Chi et al.) or ``"deltas"`` (the per-step increments
the env takes) or ``"targets"`` (fingertip poses in a task frame, :mod:`agents.learned.frames`;
the policy turns each into an ``ee_delta`` step when it acts). The hand command is absolute
in all three."""


def chunk_to_actions(chunk: np.ndarray, first: int, count: int, representation: str) -> np.ndarray:
    """The env actions of chunk entries ``first .. first + count - 1`` (``first``: the
    current step's index in the chunk). With offsets, a step's arm increment is its offset
    minus the previous step's; the offset before the current step is 0 by construction."""
    out = chunk[first : first + count].copy()
    if representation == "offsets":  # "targets" stay targets: the policy steps toward them
        arm = out[:, :-1].copy()
        out[:, :-1] = arm - np.concatenate([np.zeros_like(arm[:1]), arm[:-1]])
    return out


class ChunkSampler:
    """Index tables of every window of :class:`Demonstrations` (one per step), and batches.

    Window ``t`` of an episode holds inputs ``t - obs_horizon + 1 .. t`` and the actions of
    steps ``t - obs_horizon + 1 .. t - obs_horizon + pred_horizon`` (inputs clamped at the
    start; past the end the arm holds still and the hand keeps its last command), so the
    policy's chunk begins at its oldest observation, as in Chi et al. With
    ``representation="offsets"`` the arm entries are cumulative (see
    :data:`ACTION_REPRESENTATIONS`); steps before the episode count as no motion.
    Windows that hold a dropped (NaN) label are left out and counted in ``dropped``. An
    episode with chunk labels (:attr:`Demonstrations.chunks`) gives a window only at its
    labelled steps: the executed actions before the step, then the step's chunk label
    (``"deltas"`` only).
    """

    def __init__(
        self,
        demos: Demonstrations,
        obs_horizon: int,
        pred_horizon: int,
        representation: str = "offsets",
    ) -> None:
        if representation not in ACTION_REPRESENTATIONS:
            raise ValueError(
                f"representation must be one of {', '.join(ACTION_REPRESENTATIONS)}, "
                f"got {representation!r}"
            )
        arm = demos.labels.shape[1] - 1
        obs_rows, chunks = [], []
        labelled = demos.chunks or [None] * demos.episodes
        if demos.chunks is not None and representation != "deltas":
            raise ValueError(
                f"chunk labels are per-step increments: train with --actions deltas, not "
                f"{representation!r}"
            )
        for start, n, chunk_label in zip(demos.starts, demos.lengths, labelled, strict=True):
            labels = demos.labels[start : start + n]
            # steps -obs_horizon+1 .. n+pred_horizon-1: before the start no motion, the first
            # hand command; after the end no motion, the last hand command
            before = np.zeros((obs_horizon - 1, labels.shape[1]), np.float32)
            before[:, arm:] = labels[0, arm:]
            after = np.zeros((pred_horizon, labels.shape[1]), np.float32)
            after[:, arm:] = labels[-1, arm:]
            if representation == "targets":  # before the start and after the end: hold still
                before[:], after[:] = labels[0], labels[-1]
            steps = np.concatenate([before, labels, after])  # step s at row s + obs_horizon - 1
            t = np.arange(n)
            rows = t[:, None] + np.arange(pred_horizon)  # window t's steps, as rows of `steps`
            chunk = steps[rows]
            if chunk_label is not None:
                ahead = chunk_label_length(obs_horizon, pred_horizon)
                if chunk_label.shape[1] < ahead:
                    raise ValueError(
                        f"chunk labels of {chunk_label.shape[1]} steps cannot fill chunks of "
                        f"{pred_horizon} with an observation horizon of {obs_horizon}"
                    )
                chunk[:, obs_horizon - 1 :] = chunk_label[:, :ahead]
                keep = np.isfinite(chunk_label[:, :ahead]).all(axis=(1, 2))
                chunk, t = chunk[keep], t[keep]
            if representation == "offsets":
                cum = np.concatenate([np.zeros((1, arm), np.float32), np.cumsum(steps[:, :arm], 0)])
                # offset of step s: sum of increments up to s minus those before step t
                chunk[..., :arm] = cum[rows + 1] - cum[(t + obs_horizon - 1)[:, None]]
            chunks.append(chunk)
            obs_rows.append(
                start + np.clip(t[:, None] - obs_horizon + 1 + np.arange(obs_horizon), 0, None)
            )
        self.inputs = demos.inputs
        self.representation = representation
        chunk_arr, obs_idx = np.concatenate(chunks), np.concatenate(obs_rows)
        # a window with a dropped label (a failed DAgger query) teaches nothing reliable
        valid = ~np.isnan(chunk_arr).any(axis=(1, 2))
        self.chunks, self.obs_rows = chunk_arr[valid], obs_idx[valid]
        self.dropped = int((~valid).sum())

    def __len__(self) -> int:
        return len(self.obs_rows)

    def chunk_stats(self) -> tuple[np.ndarray, ...]:
        """Mean, standard deviation, minimum and maximum of every chunk entry, each
        ``(pred_horizon, action_dim)``: what
        :meth:`~agents.learned.diffusion.DiffusionModel.set_stats` scales by."""
        c = self.chunks.astype(np.float64)
        stats = (c.mean(axis=0), c.std(axis=0), c.min(axis=0), c.max(axis=0))
        return tuple(a.astype(np.float32) for a in stats)

    def batch(self, rng: np.random.Generator, size: int) -> tuple[np.ndarray, np.ndarray]:
        """``size`` windows drawn uniformly with replacement: inputs (B, obs_horizon, D) and
        chunks (B, pred_horizon, A)."""
        idx = rng.integers(0, len(self), size=size)
        return self.inputs[self.obs_rows[idx]], self.chunks[idx]
