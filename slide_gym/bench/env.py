"""``slide-gym bench env``: environment throughput, real-time factor, overhead over raw
physics stepping, and reset time; optionally the cost of ``obs_mode="rgbd"`` images and of
``obs_mode="pointcloud"`` points, against panda-gym on random actions, and the
press-and-drag check of :mod:`slide_gym.bench.drag` (the speed must not bring the creep
back)."""

from __future__ import annotations

import json
import math
import os
import platform
import time
from pathlib import Path
from typing import Any

import numpy as np

STEPS = 600
"""Timed env steps per run."""
RESETS = 20
"""Timed resets."""
REPEATS = 3
"""Alternating runs of the env and the raw loop; the best of each counts."""
RANDOM_STEPS = 2000
"""Env steps on random actions per run (``SlideGym/TopSlide-v0``, resets included)."""
AGAINST = {"panda-gym": "PandaPush-v3"}
"""Other environments ``--against`` runs on the same random-action protocol."""
IMAGE_SIZE = (128, 128)
"""(width, height) of the ``--rgbd`` and ``--pointcloud`` runs' cameras (the default)."""
NUM_POINTS = 1024
"""Points of the ``--pointcloud`` run (the observation's default)."""


def bench_env(
    object_name: str = "square",
    table_name: str = "square",
    steps: int = STEPS,
    resets: int = RESETS,
    seed: int = 0,
    repeats: int = REPEATS,
    random_steps: int = RANDOM_STEPS,
    against: str | None = None,
    drag: bool = False,
    stability: bool = False,
    rgbd: bool = False,
    image_size: tuple[int, int] = IMAGE_SIZE,
    pointcloud: bool = False,
    num_points: int = NUM_POINTS,
) -> dict[str, Any]:
    """Env throughput, real-time factor, overhead over raw physics stepping, and reset time.

    The actions are the scripted slider's (:class:`agents.scripted.ScriptedSlider`, recorded
    once, untimed), so the finger is in contact. The raw loop steps the very same world (robot
    springs applied every physics step, arm targets held) without building observations,
    rewards or infos. Then ``random_steps`` random actions through ``gym.make``
    (``SlideGym/TopSlide-v0``, its time limit, resets included), and with ``against``
    (a key of :data:`AGAINST`) the other environment on the same protocol, runs alternating,
    best of ``repeats`` each; ``rtf_ratio`` is ours over theirs. ``drag`` adds
    :func:`slide_gym.bench.drag.drag_summary` (sinking and creep of pressed, dragged plates);
    ``stability`` adds :func:`arm_speeds` (how fast random actions ever move the arm).
    ``rgbd`` also replays the actions in an ``obs_mode="rgbd"`` env (``image_size`` images,
    alternating with the other runs): its steps/s and the images' cost per step (ms);
    ``pointcloud`` likewise in an ``obs_mode="pointcloud"`` env (``num_points`` points from
    ``image_size`` cameras): its steps/s and the points' cost per step (ms).
    """
    if random_steps < 1:
        raise ValueError(f"random_steps must be >= 1, got {random_steps}")
    if against is not None:
        _load_against(against)  # fail before the long runs
    from agents.scripted import ScriptedSlider  # agents builds on slide_gym: import on use
    from slide_gym.envs.top_slide import TopSlideEnv
    from slide_gym.robot import ARM_LOWER, ARM_UPPER

    if steps < 1 or resets < 1:
        raise ValueError(f"steps and resets must be >= 1, got {steps} and {resets}")
    env = TopSlideEnv(object=object_name, table=table_name)
    width, height = image_size
    cameras = {"render_width": width, "render_height": height}
    modes: dict[str, dict[str, Any]] = {}  # observation mode -> its env's extra arguments
    if rgbd:
        modes["rgbd"] = {"obs_mode": "rgbd", **cameras}
    if pointcloud:
        modes["pointcloud"] = {"obs_mode": "pointcloud", "num_points": num_points, **cameras}
    envs = {"state": env}
    try:
        for mode, kwargs in modes.items():
            envs[mode] = TopSlideEnv(object=object_name, table=table_name, **kwargs)
        reset_times = []
        for i in range(resets):
            t0 = time.perf_counter()
            env.reset(seed=seed + i)
            reset_times.append(time.perf_counter() - t0)

        # Contact-rich actions: record the scripted slider once (untimed), then replay them.
        obs, _ = env.reset(seed=seed)
        policy = ScriptedSlider(env)
        actions = []
        for _ in range(steps):
            actions.append(policy.act(obs))
            obs, *_ = env.step(actions[-1])
        robot, n_sub, max_step = env.robot, env.n_substeps, env.max_joint_step

        def run_env(timed: Any = env) -> float:
            timed.reset(seed=seed)
            t0 = time.perf_counter()
            for a in actions:
                timed.step(a)
            return time.perf_counter() - t0

        def run_raw() -> float:
            # The same world and the same actions, without observations/rewards/infos.
            env.reset(seed=seed)
            t0 = time.perf_counter()
            target = np.array(env.control.target)  # the env's start target
            for a in actions:
                target = np.clip(target + max_step * a[:7], ARM_LOWER, ARM_UPPER)
                span = env._command_arm(target)  # noqa: SLF001 - the env's own settings
                robot.set_hand_command((a[7] + 1.0) / 2.0)
                for _ in range(n_sub // span):
                    robot.step_physics()
            return time.perf_counter() - t0

        # Best of a few alternating repeats: the least disturbed run of each.
        env_wall = raw_wall = float("inf")
        mode_wall = dict.fromkeys(modes, float("inf"))
        for _ in range(repeats):
            env_wall = min(env_wall, run_env())
            raw_wall = min(raw_wall, run_raw())
            for mode in modes:
                mode_wall[mode] = min(mode_wall[mode], run_env(envs[mode]))
    finally:
        for each in envs.values():
            each.close()

    sim_time = steps * env.dt
    result = {
        "benchmark": "env_step",
        "object": object_name,
        "table": table_name,
        "control_hz": 1.0 / env.dt,
        "physics_hz": 1.0 / env.sim.settings.timestep,
        "steps": steps,
        "repeats": repeats,
        "env_steps_per_s": steps / env_wall,
        "env_real_time_factor": sim_time / env_wall,
        "raw_real_time_factor": sim_time / raw_wall,
        "env_overhead": env_wall / raw_wall - 1.0,
        "reset_ms_median": 1e3 * float(np.median(reset_times)),
        "reset_ms_max": 1e3 * float(np.max(reset_times)),
        "machine": f"{platform.processor() or platform.machine()}, "
        f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}",
    }
    for mode, wall in mode_wall.items():
        cost = "image_ms_per_step" if mode == "rgbd" else "points_ms_per_step"
        result[mode] = {
            "image_size": list(image_size),
            **({"num_points": num_points} if mode == "pointcloud" else {}),
            "env_steps_per_s": steps / wall,
            "env_real_time_factor": sim_time / wall,
            cost: 1e3 * (wall - env_wall) / steps,
        }
    result.update(_random_actions(object_name, table_name, random_steps, seed, repeats, against))
    if drag:
        from slide_gym.bench.drag import drag_summary

        result["drag"] = drag_summary()
    if stability:
        result["stability"] = arm_speeds()
    return result


def arm_speeds(episodes: int = 20, steps: int = 300, seed: int = 3) -> dict[str, Any]:
    """The fastest arm joint speed (rad/s, observed after each step) in each of ``episodes``
    random-action episodes of ``SlideGym/TopSlide-v0`` (seeds ``seed``, ``seed + 1``, ...;
    action generator seeded alike): the WAM's limit is 2 rad/s, the commands ask at most
    1 rad/s, and the observation clips at 20 (a diverging simulation)."""
    import gymnasium as gym

    import slide_gym  # noqa: F401 - registers the envs

    env = gym.make("SlideGym/TopSlide-v0", object="square", table="square")
    fastest = []
    try:
        for k in range(episodes):
            env.reset(seed=seed + k)
            rng = np.random.default_rng(seed + k)
            top = 0.0
            for _ in range(steps):
                obs, _, terminated, truncated, _ = env.step(
                    rng.uniform(-1, 1, 8).astype(np.float32)
                )
                top = max(top, float(np.abs(obs["arm_qvel"]).max()))
                if terminated or truncated:
                    break
            fastest.append(round(top, 2))
    finally:
        env.close()
    return {
        "episodes": episodes,
        "steps": steps,
        "fastest_per_episode": fastest,
        "episodes_above_6_rad_s": sum(v > 6.0 for v in fastest),
        "episodes_at_the_clip": sum(v >= 19.99 for v in fastest),
    }


def _load_against(against: str) -> str:
    """Import the other environment's package (it registers its ids); return the env id."""
    if against not in AGAINST:
        raise ValueError(f"--against must be one of {', '.join(AGAINST)}, got {against!r}")
    from slide_gym.sim import silenced_stdout

    try:
        with silenced_stdout():
            import panda_gym  # noqa: F401 - registers the Panda environments
    except ImportError:
        raise ValueError(
            f"--against {against} needs panda-gym: pip install 'slide-gym[compare]'"
        ) from None
    return AGAINST[against]


def _random_actions(
    object_name: str, table_name: str, steps: int, seed: int, repeats: int, against: str | None
) -> dict[str, Any]:
    """Real-time factor on random actions: ours, and the other env's if ``against``; runs
    alternate, the best of ``repeats`` each counts."""
    import gymnasium as gym

    from slide_gym.sim import silenced_stdout

    envs: dict[str, Any] = {}
    try:
        with silenced_stdout():  # PyBullet and panda-gym print banners on stdout
            envs["random"] = gym.make("SlideGym/TopSlide-v0", object=object_name, table=table_name)
            if against is not None:
                envs["against"] = gym.make(_load_against(against))
        wall = dict.fromkeys(envs, math.inf)
        for _ in range(repeats):
            for key, env in envs.items():
                wall[key] = min(wall[key], _time_random_run(env, steps, seed))
        out: dict[str, Any] = {"random_steps": steps}
        for key, env in envs.items():
            u = env.unwrapped
            dt = float(u.dt if key == "random" else u.sim.dt)
            out[key] = {
                "env_id": env.spec.id,
                "control_dt": dt,
                "env_steps_per_s": steps / wall[key],
                "real_time_factor": steps * dt / wall[key],
            }
        if against is not None:
            sim = envs["against"].unwrapped.sim
            engine = sim.physics_client.getPhysicsEngineParameters()
            out["against"].update(
                name=against,
                physics_hz=1.0 / sim.timestep,
                solver_iterations=engine["numSolverIterations"],
            )
            ratio = out["random"]["real_time_factor"] / out["against"]["real_time_factor"]
            out["rtf_ratio"] = ratio
    finally:
        for env in envs.values():
            env.close()
    return out


def _time_random_run(env: Any, steps: int, seed: int) -> float:
    """Wall time of ``steps`` seeded random actions (resets on termination or truncation)."""
    env.action_space.seed(seed)
    actions = [env.action_space.sample() for _ in range(steps)]
    episode = 0
    env.reset(seed=seed)
    t0 = time.perf_counter()
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            episode += 1
            env.reset(seed=seed + episode)
    return time.perf_counter() - t0


def write_result(result: dict[str, Any], out: Path | None) -> None:
    """Print the result as JSON and, if asked, append it as one line to ``out``."""
    line = json.dumps(result)
    print(json.dumps(result, indent=2))
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        with out.open("a") as f:
            f.write(line + "\n")
