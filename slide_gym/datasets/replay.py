"""``slide-gym replay``: play a dataset's episodes again and check them against the record.

``mode="actions"`` resets the recovered env with each episode's seed and options and steps
its actions: the world is rebuilt on every reset, so every observation must match the
recorded one bit for bit. ``mode="states"``, an approximate check, puts the env in each
step's recorded ``infos["sim_state"]`` and steps that one action: PyBullet keeps contact
caches that no state vector holds (see
:meth:`~slide_gym.envs.top_slide.TopSlideEnv.set_state`), so the next observation is
compared with the record within :data:`STATE_TOLERANCE`, the largest differences measured.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from slide_gym.datasets.store import load, read_episodes

REPLAY_MODES = ("actions", "states")
STATE_TOLERANCE = {
    "arm_qpos": 1.0e-3,
    "finger_qpos": 0.46,
    "fingertip_position": 0.036,
    "fingertip_rotation": 0.56,
    "object_position": 0.016,
    "object_rotation": 0.28,
}
"""``mode="states"``: what is compared one step after a restore, and the largest difference
each may show (joint angles and rotations in rad, positions in m): the largest measured on
82 expert episodes of four datasets (square slide; square grasp; procedural and catalog
plates on random tables, grasped), rounded up to two digits; docs/datasets.md
gives the commands and the table. Restores are approximate (PyBullet's contact caches are
not in the state), most where fingers hold the plate (the plate: 1.5 cm, 0.28 rad, an L on
the triangle table) and where a fingertip slips off a plate's edge onto the table (the
robot's figures, one generated plate). The check catches a wrong or mismatched state (the
arm moves up to 0.05 rad a step), not the restore's own error."""


@dataclass
class ReplayResult:
    """How one episode replayed: ``matched``; ``max_errors``, the largest difference of each
    observation entry (``actions``) or of each :data:`STATE_TOLERANCE` quantity
    (``states``) over the episode; and the first step (0 = the reset) that differed
    (``actions``: at all; ``states``: beyond the tolerance); ``approximate`` for ``states``."""

    episode: int
    seed: int
    steps: int
    matched: bool
    max_errors: dict[str, float]
    first_mismatch: int | None
    approximate: bool = False
    """``mode="states"``: matched within :data:`STATE_TOLERANCE`, not bit for bit."""

    @property
    def max_error(self) -> float:
        return max(self.max_errors.values(), default=0.0)

    def to_json(self) -> dict[str, Any]:
        return {**asdict(self), "max_error": self.max_error}


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
            compare = state_errors if mode == "states" else observation_errors
            worst = observation_errors(obs, episode.observations, 0)
            first = 0 if max(worst.values()) > 0 else None
            if video:
                frames.append(env.render())
            for t, action in enumerate(episode.actions):
                if mode == "states":
                    env.unwrapped.set_state(episode.infos["sim_state"][t])
                obs, *_ = env.step(action)
                errors = compare(obs, episode.observations, t + 1)
                for key, value in errors.items():
                    worst[key] = max(worst.get(key, 0.0), value)
                if first is None and not _within(errors, mode):
                    first = t + 1
                if video and (t + 1) % VIDEO_EVERY == 0:
                    frames.append(env.render())
            if mode == "states":
                worst = {k: v for k, v in worst.items() if k in STATE_TOLERANCE}
            results.append(
                ReplayResult(
                    episode=i,
                    seed=episode.seed,
                    steps=len(episode.actions),
                    matched=first is None,
                    max_errors=worst,
                    first_mismatch=first,
                    approximate=mode == "states",
                )
            )
    finally:
        env.close()
    if video:
        write_video(Path(video), frames, VIDEO_EVERY * env.unwrapped.dt)
    return results


def observation_errors(
    obs: dict[str, np.ndarray], recorded: dict[str, np.ndarray], t: int
) -> dict[str, float]:
    """Largest absolute difference of each entry of ``obs`` from the recorded observation
    ``t``."""
    out = {}
    for key, value in recorded.items():
        diff = np.abs(np.asarray(obs[key], np.float64) - np.asarray(value[t], np.float64))
        out[key] = float(diff.max()) if diff.size else 0.0
    return out


def state_errors(
    obs: dict[str, np.ndarray], recorded: dict[str, np.ndarray], t: int
) -> dict[str, float]:
    """The :data:`STATE_TOLERANCE` quantities: joint angle differences (rad), and for the
    fingertip and the object the position distance (m) and the rotation angle (rad) between
    the two poses (a quaternion and its negative are the same rotation)."""
    out = {k: observation_errors(obs, recorded, t)[k] for k in ("arm_qpos", "finger_qpos")}
    for name, key in (("fingertip", "fingertip_pose"), ("object", "object_pose")):
        a = np.asarray(obs[key], np.float64)
        b = np.asarray(recorded[key][t], np.float64)
        out[f"{name}_position"] = float(np.linalg.norm(a[:3] - b[:3]))
        dot = abs(float(a[3:] @ b[3:])) / (np.linalg.norm(a[3:]) * np.linalg.norm(b[3:]))
        out[f"{name}_rotation"] = float(2.0 * np.arccos(min(1.0, dot)))
    return out


def _within(errors: dict[str, float], mode: str) -> bool:
    if mode == "actions":
        return max(errors.values()) == 0.0
    return all(errors[k] <= tol for k, tol in STATE_TOLERANCE.items())
