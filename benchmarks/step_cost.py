"""What a PyBullet step costs in an expert episode, by kind of step and solver threshold.

Runs the expert on the 9 catalog objects on the square and round tables (seed 0) once per
``--thresholds`` value (``PhysicsParams.solver_residual_threshold``) and times every
``stepSimulation``, split into free-space steps, steps near the plate without contact, and
steps where the robot touches the plate (the contact check is outside the timed call):

    python benchmarks/step_cost.py --thresholds 1e-7 1e-5 1e-4 3e-4 1e-3

Prints one line per threshold: episodes lifted, wall seconds, the share of wall time in
``stepSimulation``, milliseconds per step of each kind and the slid plates' median position
error. ``--solver-iterations N`` replaces the near-object solver iterations (100). For where
the rest of the wall time goes, run it under ``pyinstrument``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections import defaultdict
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

from slide_gym import sim as sim_module  # noqa: E402 - after the thread setting

TABLES = ("square", "round")


def _timed_steps(stats: dict[str, list[float]]) -> Any:
    """A ``Simulation.__init__`` that times each step of the new world into ``stats``."""
    original = sim_module.Simulation.__init__

    def init(self: sim_module.Simulation, *args: Any, **kwargs: Any) -> None:
        original(self, *args, **kwargs)
        step, client = self._step, self.client

        def timed() -> None:
            tick = time.perf_counter()
            step()
            spent = time.perf_counter() - tick
            free = self._mode is not None and self._mode[0]
            if free or "robot" not in self.bodies or "object" not in self.bodies:
                kind = "free"
            elif client.getContactPoints(self.bodies["robot"], self.bodies["object"]):
                kind = "touching"
            else:
                kind = "near"
            stats[kind].append(spent)

        self._step = timed

    return init


def run(threshold: float, iterations: int | None) -> dict[str, Any]:
    """The 18 episodes at one threshold: counts, shares and per-step costs."""
    from agents.episode import run_episode
    from slide_gym.geometry import OBJECT_NAMES

    stats: dict[str, list[float]] = defaultdict(list)
    original = sim_module.Simulation.__init__
    sim_module.Simulation.__init__ = _timed_steps(stats)  # type: ignore[method-assign]
    physics: dict[str, Any] = {"solver_residual_threshold": threshold}
    if iterations is not None:
        physics["solver_iterations"] = iterations
    lifted, errors = 0, []
    tick = time.perf_counter()
    try:
        for name in OBJECT_NAMES:
            for table in TABLES:
                record = run_episode(name, table, seed=0, time_budget=10.0, physics=physics)
                row = record.to_json_dict()
                lifted += bool(row["success"])
                if row["slide_error_m"] is not None:
                    errors.append(row["slide_error_m"])
    finally:
        sim_module.Simulation.__init__ = original  # type: ignore[method-assign]
    wall = time.perf_counter() - tick
    stepping = sum(sum(v) for v in stats.values())
    return {
        "threshold": threshold,
        "episodes": len(OBJECT_NAMES) * len(TABLES),
        "lifted": lifted,
        "wall_s": round(wall, 2),
        "stepping_share": round(stepping / wall, 3),
        "ms_per_step": {k: round(1e3 * sum(v) / len(v), 3) for k, v in sorted(stats.items())},
        "steps": {k: len(v) for k, v in sorted(stats.items())},
        "slide_error_mm_median": round(1e3 * statistics.median(errors), 2) if errors else None,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--thresholds", type=float, nargs="+", default=[1e-7, 1e-4])
    parser.add_argument("--solver-iterations", type=int, default=None)
    args = parser.parse_args()
    for threshold in args.thresholds:
        print(run(threshold, args.solver_iterations), flush=True)


if __name__ == "__main__":
    main()
