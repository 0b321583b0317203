"""``slide-gym bench env``: environment throughput, real-time factor, overhead over raw
physics stepping, and reset time."""

from __future__ import annotations

import json
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


def bench_env(
    object_name: str = "square",
    table_name: str = "square",
    steps: int = STEPS,
    resets: int = RESETS,
    seed: int = 0,
    repeats: int = REPEATS,
) -> dict[str, Any]:
    """Env throughput, real-time factor, overhead over raw physics stepping, and reset time.

    The actions are the scripted slider's (:class:`agents.scripted.ScriptedSlider`, recorded
    once, untimed), so the finger is in contact. The raw loop steps the very same world (robot
    springs applied every physics step, arm targets held) without building observations,
    rewards or infos.
    """
    from agents.scripted import ScriptedSlider  # agents builds on slide_gym: import on use
    from slide_gym.envs.top_slide import TopSlideEnv
    from slide_gym.robot import ARM_LOWER, ARM_UPPER

    if steps < 1 or resets < 1:
        raise ValueError(f"steps and resets must be >= 1, got {steps} and {resets}")
    env = TopSlideEnv(object=object_name, table=table_name)
    try:
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

        def run_env() -> float:
            env.reset(seed=seed)
            t0 = time.perf_counter()
            for a in actions:
                env.step(a)
            return time.perf_counter() - t0

        def run_raw() -> float:
            # The same world and the same actions, without observations/rewards/infos.
            env.reset(seed=seed)
            t0 = time.perf_counter()
            target = np.array(env._arm_target)  # noqa: SLF001 - the env's start target
            for a in actions:
                target = np.clip(target + max_step * a[:7], ARM_LOWER, ARM_UPPER)
                robot.set_arm_targets(target)
                robot.set_hand_command((a[7] + 1.0) / 2.0)
                for _ in range(n_sub):
                    robot.step_physics()
            return time.perf_counter() - t0

        # Best of a few alternating repeats: the least disturbed run of each.
        env_wall = raw_wall = float("inf")
        for _ in range(repeats):
            env_wall = min(env_wall, run_env())
            raw_wall = min(raw_wall, run_raw())
    finally:
        env.close()

    sim_time = steps * env.dt
    return {
        "benchmark": "env_step",
        "object": object_name,
        "table": table_name,
        "control_hz": 1.0 / env.dt,
        "physics_hz": 1.0 / env.sim.physics.timestep,
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


def write_result(result: dict[str, Any], out: Path | None) -> None:
    """Print the result as JSON and, if asked, append it as one line to ``out``."""
    line = json.dumps(result)
    print(json.dumps(result, indent=2))
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        with out.open("a") as f:
            f.write(line + "\n")
