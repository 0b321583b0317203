"""One expert episode in ``SlideGym/TopSlideGrasp-v0``, returned as an
:class:`~agents.record.EpisodeRecord` (its ``to_json_dict()`` is the ``slide-gym run --json``
contract)."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding as gym_seeding

from agents.outcome import Outcome, failure_cause
from agents.params import ExpertParams
from agents.planner_agent import PlannerAgent
from agents.record import EpisodeRecord
from slide_gym import DICT_ENV_IDS, EXPERT_ENV_ID
from slide_gym.envs.scene import SceneChoice
from slide_gym.geometry import ObjectShape, TableShape
from slide_gym.planning.result import check_time_budget
from slide_gym.task import TaskParams

START_MARGIN = TaskParams.start_margin

ENV_ID = EXPERT_ENV_ID
VIDEO_SUFFIXES = (".mp4", ".gif")
VIDEO_EVERY = 2
"""Record every second control step (10 frames per simulated second)."""


def run_episode(
    object: str | ObjectShape,  # noqa: A002 - the public argument name
    table: str | TableShape,
    *,
    scale: float = 1.0,
    seed: int = 0,
    planner: str = "regions",
    time_budget: float = 10.0,
    video: Path | None = None,
    thickness: float | None = None,
    params: ExpertParams | None = None,
    env_id: str = ENV_ID,
    object_pose: Any = None,
    control_mode: str = "joint_delta",
    physics: dict[str, Any] | None = None,
    **planner_params: Any,
) -> EpisodeRecord:
    """Run the planner agent for one seeded episode; success is the env's ``is_success``.

    ``object`` and ``table`` are what the env takes: also ``"random"`` (a catalog shape drawn
    from ``seed``) and, for objects, ``"procedural"`` (the plate of ``seed``); ``thickness``
    (m) overrides the object's. ``env_id``: one of :data:`slide_gym.DICT_ENV_IDS`; the slide
    envs end when the plate is left graspable. ``object_pose``: ``(x, y, yaw)`` instead of the
    seed's. ``control_mode``: the env's and the agent's (``"joint_delta"`` or ``"ee_delta"``).
    ``physics``: the env's physics settings (``{"friction_anchor": True}``), if any.

    ``params`` (execution) and ``planner_params`` (:class:`~slide_gym.planning.params.SlideParams`
    overrides) go to :class:`~agents.planner_agent.PlannerAgent`.
    """
    check_time_budget(time_budget)
    if env_id not in DICT_ENV_IDS:
        raise ValueError(f"env_id must be one of {', '.join(DICT_ENV_IDS)}, got {env_id!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    if video is not None:  # checked up front: the episode takes a minute
        if Path(video).suffix.lower() not in VIDEO_SUFFIXES:
            raise ValueError(f"video must end in .mp4 or .gif, got {str(video)!r}")
        if not Path(video).parent.is_dir():
            raise ValueError(
                f"video: folder {str(Path(video).parent)!r} does not exist (for {str(video)!r})"
            )
    # The env draws the scene from the seed; the same draw here tells the agent what it is.
    choice = SceneChoice(object, table, scale, thickness)
    shape, table_shape = choice.draw(gym_seeding.np_random(int(seed))[0], int(seed), START_MARGIN)
    env = gym.make(
        env_id,
        object=object,
        table=table,
        scale=scale,
        thickness=thickness,
        render_mode="rgb_array" if video else None,
        control_mode=control_mode,
        **({"physics": physics} if physics else {}),
    )
    agent = PlannerAgent(
        planner,
        time_budget,
        seed=seed,
        objects=[shape],
        tables=[table_shape],
        params=params,
        control_mode=control_mode,
        **planner_params,
    )
    frames: list[np.ndarray] = []
    dt = env.unwrapped.dt
    try:
        options = None if object_pose is None else {"object_pose": object_pose}
        record = play_episode(
            env, agent, seed=seed, options=options, frames=frames if video else None
        )
    finally:
        agent.close()
        env.close()
    if video:
        write_video(Path(video), frames, VIDEO_EVERY * dt)
        record.video = str(video)
    return record


StepHook = Callable[[Any, dict[str, Any], float, bool, bool, dict[str, Any]], None]
"""``hook(action, observation, reward, terminated, truncated, info)`` after every step."""


def play_episode(
    env: gym.Env,
    agent: PlannerAgent,
    *,
    seed: int,
    options: dict[str, Any] | None = None,
    frames: list[np.ndarray] | None = None,
    on_reset: Callable[[dict[str, Any], dict[str, Any]], None] | None = None,
    on_step: StepHook | None = None,
    perturb: Callable[[np.ndarray], np.ndarray] | None = None,
) -> EpisodeRecord:
    """Reset ``env`` with ``seed`` and ``options``, let ``agent`` act until the episode ends,
    and return its record. The episode also ends, truncated, on the step the expert gives up
    (an infeasible plan, the planning budget spent, ...): it would only hold still until the
    time limit. ``frames`` collects ``env.render()`` every :data:`VIDEO_EVERY` steps;
    ``on_reset(obs, info)`` and ``on_step`` see every observation (``on_step`` the
    truncation of a give-up too). ``perturb(action)`` gives the action executed instead of
    the agent's (DART's noise), which the expert then carries on from at its own pace
    (:meth:`~agents.expert.SlideGraspExpert.follow`); ``on_step`` sees the executed one."""
    base = env.unwrapped
    wall = time.perf_counter()
    obs, info = env.reset(seed=seed, options=options)
    if on_reset is not None:
        on_reset(obs, info)
    start = info["object_pose_2d"]
    if frames is not None:
        frames.append(env.render())
    outcome = Outcome(base.goal)
    outcome.update(info)
    steps, max_lift, terminated, truncated = 0, 0.0, False, False
    while not (terminated or truncated):
        action, _ = agent.predict(obs, episode_start=np.array([steps == 0]))
        if perturb is not None:
            clean = np.asarray(action)
            action = perturb(clean)
            if not np.array_equal(action, clean):  # it carries on from what was executed
                executing = agent.expert(0)
                assert executing is not None
                executing.follow(action, retime=False)
        obs, reward, terminated, truncated, info = env.step(action)
        expert = agent.expert(0)
        assert expert is not None
        truncated = bool(truncated) or (expert.report.gave_up is not None and not terminated)
        outcome.update(info, truncated)
        if on_step is not None:
            on_step(action, obs, float(reward), terminated, truncated, info)
        steps += 1
        max_lift = max(max_lift, float(info["lift_m"]))
        if frames is not None and steps % VIDEO_EVERY == 0:
            frames.append(env.render())
    expert = agent.expert(0)
    assert expert is not None
    success = bool(info["is_success"])
    params = base.task.params
    failure = failure_cause(
        success,
        outcome,
        expert.phase,
        expert.report.gave_up,
        lift_height=params.lift_height,
        hold_s=params.lift_hold_s,
    )
    return EpisodeRecord(
        object=base.task.object.name,
        table=base.task.table.name,
        scale=float(base.scale),
        seed=int(seed),
        planner=agent.planner,
        env_id=env.spec.id if env.spec is not None else "",
        success=success,
        failure=failure,
        expert=expert.report,
        phase_reached=expert.phase,
        steps=steps,
        sim_time_s=steps * base.dt,
        wall_time_s=time.perf_counter() - wall,
        object_start_pose=[float(v) for v in start],
        object_final_pose=[float(v) for v in info["object_pose_2d"]],
        lift_height_m=float(info["lift_m"]),
        max_lift_height_m=max_lift,
        clearance_m=outcome.clearance_m,
        max_clearance_m=outcome.max_clearance_m,
        fell_off=bool(info["fell_off"]),
        truncated=bool(truncated),
    )


def write_video(path: Path, frames: list[np.ndarray], frame_dt: float) -> None:
    """Frames as an ``.mp4`` (H.264) or ``.gif`` with ``frame_dt`` seconds per frame."""
    import imageio.v3 as iio

    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix.lower() == ".gif":
        iio.imwrite(path, np.stack(frames), duration=1000 * frame_dt, loop=0)
    else:
        # 480 x 360 frames: 8-pixel macro blocks avoid a resize (16 would need 368 rows)
        iio.imwrite(path, np.stack(frames), fps=1.0 / frame_dt, codec="libx264", macro_block_size=8)
