"""``slide-gym replay``: play a dataset's episodes again and check them against the record.

``mode="actions"`` resets the recovered env with each episode's seed and options and steps
its actions: the world is rebuilt on every reset, so every observation must match the
recorded one bit for bit. ``mode="states"`` puts the env in each step's recorded
``infos["sim_state"]`` and steps that one action: PyBullet keeps contact caches that no
state vector holds (see :meth:`~slide_gym.envs.top_slide.TopSlideEnv.set_state`), so the
next observation is compared with the record within :data:`STATE_TOLERANCE`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from slide_gym.datasets.store import load, read_episodes

REPLAY_MODES = ("actions", "states")
STATE_TOLERANCE = {
    "arm_qpos": 1e-3,
    "finger_qpos": 0.05,
    "fingertip_pose": 0.01,
    "object_pose": 0.01,
}
"""``mode="states"``: the observation entries compared one step after a restore, and the
largest difference each may show (rad; m and quaternion components). Measured on the expert
(``slide-gym replay --mode states``, README "Datasets"): the compliant fingers differ most
(up to 0.025 rad where a contact begins), the plate's pose by up to 7.4e-3."""


@dataclass
class ReplayResult:
    """How one episode replayed: ``matched``, the largest observation difference (over all
    entries for ``actions``; for ``states`` as a fraction of :data:`STATE_TOLERANCE`, so
    ``matched`` is ``max_error <= 1``), and the first step (0 = the reset) that differed."""

    episode: int
    seed: int
    steps: int
    matched: bool
    max_error: float
    first_mismatch: int | None

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


def replay(
    dataset_id: str,
    *,
    episodes: int | None = None,
    mode: str = "actions",
    video: Path | None = None,
) -> list[ReplayResult]:
    """Replay the first ``episodes`` episodes (all if None) of ``dataset_id`` in ``mode``;
    ``video`` (``.mp4`` or ``.gif``) records them one after another."""
    from agents.episode import VIDEO_EVERY, VIDEO_SUFFIXES, write_video

    if mode not in REPLAY_MODES:
        raise ValueError(f"mode must be one of {', '.join(REPLAY_MODES)}, got {mode!r}")
    if episodes is not None and episodes < 1:
        raise ValueError(f"--episodes must be >= 1, got {episodes}")
    if video is not None and Path(video).suffix.lower() not in VIDEO_SUFFIXES:
        raise ValueError(f"video must end in .mp4 or .gif, got {str(video)!r}")
    dataset = load(dataset_id)
    count = dataset.total_episodes if episodes is None else min(episodes, dataset.total_episodes)
    env = dataset.recover_environment(render_mode="rgb_array" if video else None)
    frames: list[np.ndarray] = []
    results = []
    try:
        for i, episode in enumerate(read_episodes(dataset, range(count))):
            obs, _ = env.reset(seed=episode.seed, options=episode.options)
            scale = STATE_TOLERANCE if mode == "states" else None
            errors = [_difference(obs, episode.observations, 0, scale)]
            if video:
                frames.append(env.render())
            for t, action in enumerate(episode.actions):
                if mode == "states":
                    env.unwrapped.set_state(episode.infos["sim_state"][t])
                obs, *_ = env.step(action)
                errors.append(_difference(obs, episode.observations, t + 1, scale))
                if video and (t + 1) % VIDEO_EVERY == 0:
                    frames.append(env.render())
            limit = 1.0 if mode == "states" else 0.0
            bad = [t for t, e in enumerate(errors) if e > limit]
            results.append(
                ReplayResult(
                    episode=i,
                    seed=episode.seed,
                    steps=len(episode.actions),
                    matched=not bad,
                    max_error=float(max(errors)),
                    first_mismatch=bad[0] if bad else None,
                )
            )
    finally:
        env.close()
    if video:
        write_video(Path(video), frames, VIDEO_EVERY * env.unwrapped.dt)
    return results


def _difference(
    obs: dict[str, np.ndarray],
    recorded: dict[str, np.ndarray],
    t: int,
    scale: dict[str, float] | None,
) -> float:
    """Largest absolute difference between ``obs`` and the recorded observation ``t``: over
    every entry, or over ``scale``'s entries divided by their scale."""
    worst = 0.0
    for key in scale or recorded:
        a = np.asarray(obs[key], dtype=np.float64)
        b = np.asarray(recorded[key][t], dtype=np.float64)
        diff = float(np.max(np.abs(a - b))) if a.size else 0.0
        worst = max(worst, diff / scale[key] if scale else diff)
    return worst
