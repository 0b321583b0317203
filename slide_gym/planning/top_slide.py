"""Top-sliding planning problem and the planner facade (OMPL-like flow).

``TopSlideProblem`` holds the scene and what follows from it (P_o in the world, the goal band
P_g, the contact height band); ``TopSlidePlanner`` wires the robot-specific callables
(regions, projection, collision, pair validation) into the search core and turns its answer
into a :class:`PlanResult` with a densified path and everything needed to execute it.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np
import shapely

from slide_gym.geometry import ObjectShape, TableShape, get_object, get_table, transform_points
from slide_gym.planning.collision import CollisionChecker
from slide_gym.planning.constraints import ContactBand, SlideConstraints
from slide_gym.planning.ik import fingertip_chain
from slide_gym.planning.pair import PairValidator
from slide_gym.planning.params import SlideParams
from slide_gym.planning.regions import GoalRegion, StartRegion, goal_band
from slide_gym.planning.result import Planner, PlannerStats, PlanResult, PlanStatus, SearchParams
from slide_gym.planning.search import (
    PLANNERS,
    DensifyError,
    SearchFunctions,
    densify,
    forest_connect_search,
)
from slide_gym.planning.smoothing import shortcut_path
from slide_gym.robot.model import ARM_LOWER, ARM_UPPER
from slide_gym.task import check_scene, validate_start_pose


def _supported_pose(obj: ObjectShape, table: TableShape, pose: Any) -> np.ndarray:
    """A start pose whose centroid is over the table (the plate may overhang)."""
    arr = np.asarray(pose, dtype=float).reshape(-1)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"object_pose must be 3 finite numbers (x, y, yaw), got {pose!r}")
    if not shapely.contains_xy(table.polygon, arr[0], arr[1]):
        raise ValueError(f"object_pose {arr.tolist()} puts the object's centroid off the table")
    return arr


class TopSlideProblem:
    """A plate on a table at a start pose; raises ValueError for scenes that cannot work.

    Args:
        obj: an :class:`ObjectShape` or a catalog name / JSON path.
        table: a :class:`TableShape` or a catalog name / JSON path.
        object_start_pose: (x, y, yaw) of the plate, fully on the table and in reach.
        params: planner parameters.
        allow_overhang: accept a start pose that already overhangs an edge (a replan after a
            short slide); the centroid must still be over the table, and presses stay over it.
    """

    def __init__(
        self,
        obj: ObjectShape | str,
        table: TableShape | str,
        object_start_pose: Any,
        params: SlideParams | None = None,
        allow_overhang: bool = False,
    ):
        self.object = get_object(obj)
        self.table = get_table(table)
        self.params = params or SlideParams()
        check_scene(self.object, self.table)
        if allow_overhang:
            self.start_pose = _supported_pose(self.object, self.table, object_start_pose)
        else:
            self.start_pose = validate_start_pose(self.object, self.table, object_start_pose)
        self.z_surface = self.table.height + self.object.thickness
        self.height_range = self.params.contact_height_range(self.z_surface)
        top = self.object.top_surface_points(self.params.cloud_spacing)
        if self.params.press_edge_margin > 0.0:  # a rounded tip pressed near an edge slips off
            inset = shapely.distance(self.object.polygon.boundary, shapely.points(top[:, :2]))
            top = top[inset >= min(self.params.press_edge_margin, inset.max())]
        if self.params.press_radius is not None:  # P_o near the centroid: less spin while sliding
            d = np.linalg.norm(top[:, :2], axis=1)  # the shape's frame is centred on its centroid
            top = top[d <= d.min() + self.params.press_radius]
        xy = transform_points(top[:, :2], *self.start_pose)
        if allow_overhang:  # press only where the table is underneath
            inner = self.table.polygon.buffer(-self.params.cloud_spacing)
            xy = xy[shapely.contains_xy(inner, xy[:, 0], xy[:, 1])]
            if len(xy) == 0:
                raise ValueError("no part of the object's top lies over the table to press on")
        self.start_points = np.column_stack([xy, np.full(len(xy), self.z_surface)])
        grasp_z = self.table.height + 0.5 * self.object.thickness
        self.goal_band = goal_band(
            self.table.polygon,
            self.params.goal_band_width,
            grasp_z if self.params.goal_band_reachable else None,
            self.params.grasp.edge_clearance,
        )

    def describe(self) -> dict[str, Any]:
        """Scene summary for results and logs."""
        return {
            "object": self.object.name,
            "table": self.table.name,
            "object_start_pose": self.start_pose.tolist(),
            "z_surface": self.z_surface,
            "contact_height_range": list(self.height_range),
            "n_start_points": len(self.start_points),
        }


class _OutOfTime(Exception):
    """Densifying the found path would overrun the budget."""


class TopSlidePlanner(Planner):
    """Plans a top-sliding motion that leaves the plate graspable (Algorithm 1 and baselines).

    * ``"regions"``: start and goal forests both sample roots from C_s / C_g (the paper's).
    * ``"cbirrt2"``: one start configuration drawn first; goal roots sampled from C_g.
    * ``"cbirrt"``: draws start/goal pairs until one passes pair validation (inside the budget),
      then only connects that pair under the motion constraints.

    ``solve(time_budget)`` returns a :class:`PlanResult` whose ``path`` (fingertip moves
    <= ``path_resolution`` between neighbours) runs from ``start_config`` to ``goal_config``;
    ``extra`` holds ``object_start_pose``, ``object_goal_pose`` (x, y, yaw from Eq. 2),
    ``overhang_m``, ``edge`` (the table edge it overhangs), ``grasp_config``,
    ``transfer_path`` (phi_g ... grasp), ``contact_height_range`` and ``parameters`` (every
    value used), plus counters. The planner owns a PyBullet client: ``close()`` it, or use it
    as a context manager.

    Args:
        problem: the scene and parameters.
        planner: one of ``PLANNERS``.
        seed: seed (anything ``numpy.random.default_rng`` takes) or a Generator.
    """

    def __init__(
        self,
        problem: TopSlideProblem,
        planner: str = "regions",
        seed: int | Sequence[int] | np.random.Generator | None = None,
    ):
        if planner not in PLANNERS:
            raise ValueError(f"planner must be one of {', '.join(PLANNERS)}, got {planner!r}")
        self.problem = problem
        self.name = planner
        self.seed = seed if not isinstance(seed, np.random.Generator) else None
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        p = problem.params
        self.chain = fingertip_chain()
        band = ContactBand(p.beta0, p.dbeta, *problem.height_range, problem.z_surface)
        self.constraints = SlideConstraints(self.chain, band, problem.table.polygon, p.tolerance)
        self.checker = CollisionChecker(problem.table, problem.object)
        args = (self.constraints, self.checker, p.ik)
        self.start_region = StartRegion(problem.start_points, *args)
        self.goal_region = GoalRegion(problem.goal_band, *args)
        self.validator = PairValidator(
            problem.object,
            problem.table,
            problem.start_pose,
            p.u_star,
            self.chain,
            self.checker,
            self.rng,
            p.grasp,
            p.ik,
            p.centroid_margin,
            p.max_rotation,
        )
        self.search_params = SearchParams(
            step_size=p.step, n_star=p.n_star, distance_weights=p.distance_weights
        )
        self._pair_cache: dict[bytes, tuple[bool, Any]] = {}
        self.max_root_draws = 300

    # ------------------------------------------------------------ callables
    def pair_valid(self, q_s: np.ndarray, q_g: np.ndarray) -> tuple[bool, Any]:
        """IsPairValid, remembered per pair (the cbirrt baseline validates its pair twice)."""
        key = np.concatenate([q_s, q_g]).tobytes()
        if key not in self._pair_cache:
            self._pair_cache[key] = self.validator(q_s, q_g)
        return self._pair_cache[key]

    def project(self, q: np.ndarray, q_near: np.ndarray | None = None) -> np.ndarray | None:
        """Projection onto the relaxed manifold (None if it fails or breaks a checked rule)."""
        return self.constraints.project(q, q_near)

    def collides(self, q: np.ndarray) -> bool:
        """Collision in ``"sliding"`` mode (finger A may sink into the table top)."""
        return self.checker.collides(q, "sliding")

    def functions(self, start: bool = True, goal: bool = True) -> SearchFunctions:
        """The search core's callables; ``start``/``goal`` False fix that side's roots."""
        return SearchFunctions(
            sample_config=lambda rng: rng.uniform(ARM_LOWER, ARM_UPPER),
            project=self.project,
            collides=self.collides,
            pair_valid=self.pair_valid,
            sample_start_root=self.start_region.sample if start else None,
            sample_goal_root=self.goal_region.sample if goal else None,
            distance_weights=self.problem.params.distance_weights,
        )

    def tip_distance(self, a: np.ndarray, b: np.ndarray) -> float:
        """Fingertip displacement (m) between two configurations."""
        tips = self.chain.forward(np.stack([a, b]))
        return float(np.linalg.norm(tips[0, :3, 3] - tips[1, :3, 3]))

    # ---------------------------------------------------------------- solve
    def _draw(self, region: Any, deadline: float, stats: PlannerStats) -> np.ndarray | str:
        """A root from ``region`` or why none came: "timeout" or "exhausted"."""
        for _ in range(self.max_root_draws):
            if time.perf_counter() >= deadline:
                return "timeout"
            t0 = time.perf_counter()
            q = region.sample(self.rng)
            stats.time_sampling_s += time.perf_counter() - t0
            if q is not None:
                return q
        return "exhausted"

    def _initial_roots(self, deadline: float, stats: PlannerStats) -> tuple[list, list, str | None]:
        """Roots drawn before the search (Init of Algorithm 1, or the baselines' fixed roots)."""
        regions = (("start", self.start_region), ("goal", self.goal_region))
        if self.name == "cbirrt":
            while True:
                drawn = [self._draw(r, deadline, stats) for _, r in regions]
                for (side, _), q in zip(regions, drawn, strict=True):
                    if isinstance(q, str):
                        return [], [], f"{q}:{side}"
                t0 = time.perf_counter()
                ok, _ = self.pair_valid(drawn[0], drawn[1])
                stats.time_validation_s += time.perf_counter() - t0
                if ok:
                    return [drawn[0]], [drawn[1]], None
                if time.perf_counter() >= deadline:
                    return [], [], "timeout:pair"
        roots: list[list] = [[], []]
        for k, (side, region) in enumerate(regions):
            if k == 1 and self.name == "cbirrt2":
                break
            q = self._draw(region, deadline, stats)
            if isinstance(q, str):
                return [], [], f"{q}:{side}"
            roots[k].append(q)
        return roots[0], roots[1], None

    def _solve(self, deadline: float, stats: PlannerStats) -> PlanResult:
        t_start = time.perf_counter()
        budget = deadline - t_start
        hard = deadline + 0.04 * budget
        search_deadline = deadline - min(0.05 * budget, 0.25)
        self.validator.deadline = search_deadline
        self.start_region.deadline = self.goal_region.deadline = search_deadline
        if self.problem.goal_band.is_empty:
            reason = "no stretch of the table edge allows a side grasp within the arm's reach"
            return PlanResult(PlanStatus.INFEASIBLE, reason, extra=self._extra())
        starts, goals, why = self._initial_roots(search_deadline, stats)
        if why is not None:
            what, side = why.split(":")
            if what == "exhausted":
                reason = (
                    f"no {side} configuration: {self.max_root_draws} draws from C_{side[0]} "
                    "all failed (IK, manifold checks or collisions)"
                )
                return PlanResult(PlanStatus.INFEASIBLE, reason, extra=self._extra())
            return PlanResult(
                PlanStatus.TIMEOUT,
                f"time budget exhausted while drawing the {side}",
                extra=self._extra(),
            )
        fns = self.functions(start=self.name == "regions", goal=self.name != "cbirrt")
        failures = 0
        while True:
            res = forest_connect_search(
                fns, self.search_params, self.rng, search_deadline, stats, starts, goals
            )
            if not res.solved:
                res.extra = {**self._extra(), **res.extra, "densify_failures": failures}
                return res
            path = shortcut_path(
                res.path,
                fns,
                self.search_params,
                self.rng,
                self.problem.params.shortcut_attempts,
                search_deadline,
            )
            try:
                dense = densify(
                    path,
                    self.problem.params.path_resolution,
                    self._dense_project(hard),
                    self.tip_distance,
                )
            except (DensifyError, _OutOfTime) as exc:
                if isinstance(exc, _OutOfTime) or time.perf_counter() >= search_deadline:
                    reason = "found a path but densifying it did not fit in the time budget"
                    return PlanResult(PlanStatus.TIMEOUT, reason, extra=self._extra())
                failures += 1
                continue
            return self._solved(res, dense, failures)

    def _dense_project(self, hard: float):
        def project(q: np.ndarray, q_near: np.ndarray) -> np.ndarray | None:
            if time.perf_counter() >= hard:
                raise _OutOfTime
            q = self.constraints.project(q, q_near)
            return None if q is None or self.collides(q) else q

        return project

    def _solved(self, res: PlanResult, dense: np.ndarray, failures: int) -> PlanResult:
        info = res.extra.pop("pair_info")
        extra = {
            **self._extra(),
            **res.extra,
            "object_goal_pose": np.asarray(info["object_goal_pose"]).tolist(),
            "overhang_m": float(info["overhang_m"]),
            "edge": np.asarray(info["edge"]).tolist(),
            "grasp_config": np.asarray(info["grasp_config"]).tolist(),
            "transfer_path": np.asarray(info["transfer_path"]).tolist(),
            "raw_path_length": len(res.path),
            "densify_failures": failures,
        }
        return PlanResult(
            PlanStatus.SOLVED, None, res.start_config, res.goal_config, dense, extra=extra
        )

    def _extra(self) -> dict[str, Any]:
        prob = self.problem
        params = prob.params.as_dict()
        params["contact_height_range"] = list(prob.height_range)
        params["max_root_draws"] = self.max_root_draws
        return {
            "planner": self.name,
            "seed": self.seed,
            **prob.describe(),
            "parameters": params,
            "validator_counts": dict(self.validator.counts),
            "region_draws": {
                "start": [self.start_region.draws, self.start_region.accepted],
                "goal": [self.goal_region.draws, self.goal_region.accepted],
            },
        }

    def close(self) -> None:
        """Release the private collision world (safe to call twice)."""
        self.checker.close()

    def __enter__(self) -> TopSlidePlanner:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
