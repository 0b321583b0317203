"""One planning query from plain inputs to a JSON-ready report (the ``slide-gym plan`` contract)."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from slide_gym.geometry import ObjectShape, TableShape, get_table
from slide_gym.planning.api import SlideParams, TopSlidePlanner, TopSlideProblem
from slide_gym.planning.ompl_reference import OmplReferencePlanner
from slide_gym.planning.result import PlanResult, check_time_budget
from slide_gym.planning.search import REFERENCE_PLANNERS
from slide_gym.task import check_scene, scene_object, seeded_start_pose


def seeded_generators(seed: int) -> tuple[np.random.Generator, np.random.Generator]:
    """Two independent streams from one seed: ``(pose, planner)``. :func:`plan_once` uses only
    the planner's (its start pose is :func:`~slide_gym.task.seeded_start_pose`, the env's
    draw); the first is kept so the planner's stream for a seed stays what it was."""
    pose_seq, plan_seq = np.random.SeedSequence(seed).spawn(2)
    return np.random.default_rng(pose_seq), np.random.default_rng(plan_seq)


def make_params(
    dz: tuple[float, float] | None = None,
    dbeta: float | None = None,
    n_star: int | None = None,
    base: SlideParams | None = None,
    restart_iterations: int | None = None,
) -> SlideParams:
    """SlideParams with the given overrides (None keeps the default)."""
    changes = {"dz": dz, "dbeta": dbeta, "n_star": n_star, "restart_iterations": restart_iterations}
    return dataclasses.replace(
        base or SlideParams(), **{k: v for k, v in changes.items() if v is not None}
    )


def plan_once(
    obj: str | ObjectShape,
    table: str | TableShape,
    *,
    scale: float = 1.0,
    thickness: float | None = None,
    object_pose: Any = None,
    seed: int = 0,
    planner: str = "regions",
    time_budget: float = 10.0,
    params: SlideParams | None = None,
) -> dict[str, Any]:
    """Solve one problem; without ``object_pose`` a valid random start pose comes from ``seed``.

    ``obj`` may be ``"procedural"`` (the plate of ``seed``); ``thickness`` (m) overrides it.
    ``planner`` is one of ``PLANNERS`` or of ``REFERENCE_PLANNERS`` (``"ompl"``: OMPL's
    RRTConnect on our manifold, see :mod:`slide_gym.planning.ompl_reference`).
    """
    check_time_budget(time_budget)
    table_shape = get_table(table)
    shape = scene_object(obj, table_shape, seed=seed, scale=scale, thickness=thickness)
    check_scene(shape, table_shape)
    _, plan_rng = seeded_generators(seed)  # the pose as env.reset(seed=seed) draws it
    if object_pose is None:
        object_pose = seeded_start_pose(shape, table_shape, seed)
    problem = TopSlideProblem(shape, table_shape, object_pose, params)
    if planner in REFERENCE_PLANNERS:
        solver: TopSlidePlanner = OmplReferencePlanner(problem, plan_rng)
    else:
        solver = TopSlidePlanner(problem, planner, plan_rng)
    try:
        result = solver.solve(time_budget)
    finally:
        solver.close()
    return report(problem, result, planner, seed)


def report(problem: TopSlideProblem, result: PlanResult, planner: str, seed: int) -> dict[str, Any]:
    """The public JSON shape of a planning result (see docs/planners.md, "slide-gym plan")."""
    raw = result.to_json_dict()
    extra = raw["extra"]
    return {
        "status": raw["status"],
        "reason": raw["reason"],
        "planner": planner,
        "planning_time_s": result.stats.time_total_s,
        "seed": seed,
        "object": problem.object.name,
        "table": problem.table.name,
        "object_start_pose": [float(v) for v in problem.start_pose],
        "object_goal_pose": extra.get("object_goal_pose"),
        "overhang_m": extra.get("overhang_m"),
        "start_config": raw["start_config"],
        "goal_config": raw["goal_config"],
        "grasp_config": extra.get("grasp_config"),
        "path": raw["path"],
        "grasp_edge": extra.get("edge"),
        "transfer_path": extra.get("transfer_path"),
        "table_polygon": [list(p) for p in problem.table.polygon.exterior.coords[:-1]],
        "table_height": problem.table.height,
        "object_thickness": problem.object.thickness,
        "parameters": extra.get("parameters"),
        "stats": {
            **raw["stats"],
            "restarts": extra.get("restarts", 0),
            "pair_checks": extra.get("validator_counts", {}),
        },
    }
