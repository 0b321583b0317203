"""``slide-gym bench execute``: the expert agent's full episodes (slide, grasp, lift) on every
object and table, run in parallel and resumable, summarized as JSON or markdown tables.

Each result row is an :class:`agents.record.EpisodeRecord` as JSON (the ``slide-gym run
--json`` keys), whether the episode ran or its scene was rejected.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from slide_gym import EXPERT_ENV_ID
from slide_gym.jobs import run_cases

if TYPE_CHECKING:  # agents builds on slide_gym: imported on use only
    from agents.record import EpisodeRecord

PLANNER = "regions"
TRIALS = 10
"""Seeds per object and table."""
TIME_BUDGET = 10.0
"""Planning seconds per episode (first plan and replans together)."""
OUT = Path("results/bench_execute.jsonl")
ENV_ID = EXPERT_ENV_ID
"""The default environment: slide, grasp and lift."""
UNNAMED_ENV_ID = "SlideGym/TopSlideGrasp-v0"
"""The env of a case that names none: the cases written before the v1 ids, which left the
default of their day (v0) out."""


def _run_episode() -> Callable[..., EpisodeRecord]:
    """``agents.episode.run_episode``, imported on use."""
    from agents.episode import run_episode

    return run_episode


def execute_case(case: dict[str, Any]) -> dict[str, Any]:
    """One expert episode of the execute benchmark (runs in a worker process).

    A case's ``expert`` (a dict of :class:`agents.params.ExpertParams` fields), if any,
    replaces those execution settings, and its ``physics`` (PhysicsParams fields) the env's.
    Its ``dz`` (``[dz_lo, dz_hi]``, m), if any, replaces
    the expert's contact band (``agents.params.EXPERT_SLIDE_PARAMS.dz``) for every plan of
    the episode: the first, the relaxed fallback and the replans (they all derive from the
    agent's parameters and keep its ``dz``). A scene the episode rejects (``ValueError``)
    becomes a failed row carrying the message, with the same keys as an episode's row.
    """
    from agents.params import expert_params
    from agents.record import EpisodeRecord

    overrides: dict[str, Any] = {}
    if "dz" in case:
        overrides["dz"] = (float(case["dz"][0]), float(case["dz"][1]))
    if "expert" in case:
        overrides["params"] = expert_params(case["expert"])
    try:
        record = _run_episode()(
            case["object"],
            case["table"],
            seed=case["seed"],
            planner=case["planner"],
            time_budget=case["time_budget"],
            scale=case.get("scale", 1.0),
            thickness=case.get("thickness"),
            env_id=case.get("env_id", UNNAMED_ENV_ID),
            physics=case.get("physics"),
            **overrides,
        )
    except ValueError as err:
        record = EpisodeRecord.rejected(
            case["object"],
            case["table"],
            seed=case["seed"],
            planner=case["planner"],
            reason=err,
            scale=case.get("scale", 1.0),
            env_id=case.get("env_id", UNNAMED_ENV_ID),
        )
    return record.to_json_dict()


def bench_execute(
    objects: Sequence[str],
    tables: Sequence[str],
    trials: int = TRIALS,
    out: Path = OUT,
    planner: str = PLANNER,
    time_budget: float = TIME_BUDGET,
    workers: int | None = None,
    seed: int = 0,
    scale: float = 1.0,
    thickness: float | None = None,
    env_id: str = ENV_ID,
    backend: str = "local",
    address: str | None = None,
    expert: dict[str, float] | None = None,
    physics: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Run ``trials`` seeded episodes per object and table (resumable: results go to ``out``).

    Episode ``i`` of a catalog object uses seed ``seed + i`` on every table. Procedural plates
    are not repeated across tables: table ``k`` of ``T`` gets the plates of seeds
    ``seed + k + T * i``, so ``--objects procedural --trials 50`` runs 200 different plates
    on the 4 tables. ``scale`` and ``thickness`` (m) apply to every object. ``env_id``: the
    environment (default :data:`slide_gym.EXPERT_ENV_ID`; ``SlideGym/TopSlide-v1``: the slide
    alone, success = left graspable; the ``-v0`` ids: the physics before friction anchors).
    ``backend``, ``address``: where episodes run (:func:`slide_gym.jobs.run_cases`).
    ``expert``: :class:`agents.params.ExpertParams` fields to override (speeds, gains).
    ``physics``: :class:`slide_gym.sim.PhysicsParams` fields to override
    (``{"friction_anchor": True}``).
    """
    from agents.params import expert_params
    from slide_gym import DICT_ENV_IDS
    from slide_gym.geometry import OBJECT_NAMES, get_object, get_table
    from slide_gym.geometry.catalog import unknown_name
    from slide_gym.planning.result import check_time_budget
    from slide_gym.planning.search import PLANNERS
    from slide_gym.sim import physics_overrides
    from slide_gym.task import PROCEDURAL

    time_budget = check_time_budget(time_budget)
    if trials < 1:
        raise ValueError(f"trials must be >= 1, got {trials}")
    if planner not in PLANNERS:
        raise ValueError(f"planner must be one of {', '.join(PLANNERS)}, got {planner!r}")
    if env_id not in DICT_ENV_IDS:
        raise ValueError(f"env must be one of {', '.join(DICT_ENV_IDS)}, got {env_id!r}")
    if not objects or not tables:
        raise ValueError("need at least one object and one table")
    for name in objects:
        if name not in (*OBJECT_NAMES, PROCEDURAL) and not name.lower().endswith(".json"):
            raise unknown_name("object", name, (*OBJECT_NAMES, PROCEDURAL))
        if name != PROCEDURAL:
            get_object(name, scale)
    for name in tables:
        get_table(name)
    extra = {"scale": float(scale)} if scale != 1.0 else {}
    if thickness is not None:
        extra["thickness"] = float(thickness)
    extra["env_id"] = env_id  # in every case, so a file resumed under another default reruns
    if expert:
        expert_params(expert)  # a bad name or value fails here, not in every worker
        extra["expert"] = dict(expert)
    if physics:
        extra["physics"] = physics_overrides(physics)
    n = len(tables)
    cases = [
        {
            "object": o,
            "table": t,
            "seed": seed + (k + n * i if o == PROCEDURAL else i),
            "planner": planner,
            "time_budget": time_budget,
            **extra,
        }
        for i in range(trials)
        for o in objects
        for k, t in enumerate(tables)
    ]
    rows = run_cases(
        execute_case, cases, out, workers, desc="execute", backend=backend, address=address
    )
    return summarize_execute(rows)


def _median(values: Sequence[float]) -> float | None:
    return float(np.median(values)) if values else None


def _present(rows: Sequence[dict[str, Any]], key: str) -> list[float]:
    return [float(r[key]) for r in rows if r.get(key) is not None]


def _rate(rows: Sequence[dict[str, Any]], key: str) -> float | None:
    return float(np.mean([bool(r.get(key)) for r in rows])) if rows else None


def _scaled(value: float | None, factor: float) -> float | None:
    return None if value is None else value * factor


def _group(rows: Sequence[dict[str, Any]], key: str, order: Sequence[str]) -> dict[str, Any]:
    """Per value of ``key`` (catalog order first): n, success rate, median errors and wall."""
    rank = {name: i for i, name in enumerate(order)}
    names = sorted({str(r[key]) for r in rows}, key=lambda n: (rank.get(n, len(rank)), n))
    groups = {}
    for name in names:
        mine = [r for r in rows if str(r[key]) == name]
        groups[name] = {
            "n": len(mine),
            "success_rate": _rate(mine, "success"),
            "slide_error_cm_median": _scaled(_median(_present(mine, "slide_error_m")), 100.0),
            "slide_error_deg_median": _scaled(
                _median(_present(mine, "slide_error_rad")), 180.0 / math.pi
            ),
            "wall_time_s_median": _median(_present(mine, "wall_time_s")),
        }
    return groups


def summarize_execute(results: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Lift (success) and planned rates, wall times, slide errors, per object and per table.

    Medians skip ``None`` (no slide happened, or the scene was rejected before an episode).
    """
    from agents.outcome import failure_counts
    from slide_gym.geometry import OBJECT_NAMES, TABLE_NAMES

    walls = _present(results, "wall_time_s")
    sims = _present(results, "sim_time_s")
    error_rad = _median(_present(results, "slide_error_rad"))
    return {
        "benchmark": "execute",
        "n": len(results),
        "planners": sorted({str(r["planner"]) for r in results if r.get("planner")}),
        "env_ids": sorted({str(r.get("env_id", ENV_ID)) for r in results}),
        "success_rate": _rate(results, "success"),
        "planned_rate": _rate(results, "planned"),
        "wall_time_s_median": _median(walls),
        "wall_time_s_p90": float(np.percentile(walls, 90)) if walls else None,
        "sim_time_s_median": _median(sims),
        **_throughput(results),
        "slide_error_m_median": _median(_present(results, "slide_error_m")),
        "slide_error_rad_median": error_rad,
        "slide_error_deg_median": _scaled(error_rad, 180.0 / math.pi),
        "by_object": _group(results, "object", OBJECT_NAMES),
        "by_table": _group(results, "table", TABLE_NAMES),
        "failures": failure_counts(results),
    }


def _throughput(results: Sequence[dict[str, Any]]) -> dict[str, float | None]:
    """Ratios that hold across machines better than wall times: the real-time factor
    (simulated over wall seconds, all episodes together), the median share of an episode's
    wall time spent planning, and lifted episodes per wall minute of one core (each episode
    runs on one); also the totals behind them (simulated, wall and planning seconds), from
    which the real-time factor outside planning follows."""
    done = [r for r in results if r.get("wall_time_s") and r.get("sim_time_s") is not None]
    wall = sum(float(r["wall_time_s"]) for r in done)
    if not done or wall <= 0.0:
        keys = ("real_time_factor", "planning_share_median", "demos_per_core_min")
        totals = ("sim_time_s_total", "wall_time_s_total", "planning_time_s_total")
        return dict.fromkeys(keys + totals)
    planning = [float(r.get("planning_time_s") or 0.0) for r in done]
    sim = sum(float(r["sim_time_s"]) for r in done)
    return {
        "real_time_factor": sim / wall,
        "planning_share_median": _median(
            [p / float(r["wall_time_s"]) for p, r in zip(planning, done, strict=True)]
        ),
        "demos_per_core_min": sum(bool(r.get("success")) for r in done) / (wall / 60.0),
        "sim_time_s_total": sim,
        "wall_time_s_total": wall,
        "planning_time_s_total": sum(planning),
    }


def _fmt(value: float | None, spec: str, suffix: str = "") -> str:
    return "-" if value is None else f"{value:{spec}}{suffix}"


def execute_markdown_table(summary: dict[str, Any]) -> str:
    """An overall line and markdown tables: per object, per table, and the failures."""
    grasp = all("Grasp" in env_id for env_id in summary.get("env_ids", [ENV_ID]))
    done = "lifted" if grasp else "succeeded"
    lines = [
        f"**Overall** ({', '.join(summary['planners']) or 'no'} planner"
        f"{'' if grasp else ', ' + ', '.join(summary['env_ids'])}): {summary['n']} "
        f"episodes, {done} {_fmt(_scaled(summary['success_rate'], 100.0), '.0f', '%')}, "
        f"planned {_fmt(_scaled(summary['planned_rate'], 100.0), '.0f', '%')}, "
        f"wall median {_fmt(summary['wall_time_s_median'], '.1f', ' s')} "
        f"(p90 {_fmt(summary['wall_time_s_p90'], '.1f', ' s')}), simulated median "
        f"{_fmt(summary['sim_time_s_median'], '.1f', ' s')}, real-time factor "
        f"{_fmt(summary.get('real_time_factor'), '.1f', 'x')}, planning "
        f"{_fmt(_scaled(summary.get('planning_share_median'), 100.0), '.0f', '%')} of wall "
        f"(median), {_fmt(summary.get('demos_per_core_min'), '.1f')} lifted per core-minute, "
        "slide error median "
        f"{_fmt(_scaled(summary['slide_error_m_median'], 100.0), '.1f', ' cm')} / "
        f"{_fmt(summary['slide_error_deg_median'], '.1f', ' deg')}",
    ]
    for kind, key in (("object", "by_object"), ("table", "by_table")):
        lines += [
            "",
            f"| {kind} | n | {done} | slide error (cm) | slide error (deg) | wall (s) |",
            "|---|---:|---:|---:|---:|---:|",
        ]
        for name, row in summary[key].items():
            lines.append(
                f"| {name} | {row['n']} "
                f"| {_fmt(_scaled(row['success_rate'], 100.0), '.0f', '%')} "
                f"| {_fmt(row['slide_error_cm_median'], '.1f')} "
                f"| {_fmt(row['slide_error_deg_median'], '.1f')} "
                f"| {_fmt(row['wall_time_s_median'], '.1f')} |"
            )
    if summary["failures"]:
        lines += ["", "| failure | episodes |", "|---|---:|"]
        lines += [f"| {kind} | {n} |" for kind, n in summary["failures"].items()]
    return "\n".join(lines) + "\n"
