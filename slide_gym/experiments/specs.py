"""The paper's experiments as lists of planning cases, at full size and at ``--quick`` size.

A case is one planning query: a dict of JSON values (see :func:`case`) that is also its
identity when a run resumes (:func:`slide_gym.jobs.case_key`); it carries the code
version, so finished cases of other code never count as done.

Contact depth: the paper's dZ- = 0.5 cm is the least depth of the fingertip contact below the
plate top and dZ* the width of the allowed band, so the planner's
:attr:`~slide_gym.planning.params.SlideParams.dz` is ``(dZ-, dZ- + dZ*)``: dZ* = 0 gives
(0.005, 0.005), 0.5 cm (0.005, 0.01) and 2 cm the default (0.005, 0.025).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from slide_gym.bench.plan import OBJECTS as PAPER_OBJECTS
from slide_gym.geometry import TABLE_NAMES
from slide_gym.jobs import Case
from slide_gym.planning.params import SlideParams

LETTERS = ("Y", "A", "L", "E")
"""fig10's further group of objects."""
DZ_MINUS = 0.005
"""dZ- (m): the least contact depth below the plate top."""
DZ_STARS = (0.0, 0.005, 0.02)
"""fig11's dZ* (m): the width of the contact-depth band."""
DZ_STAR = 0.02
"""dZ* (m) of fig10, fig12 and the baselines of fig11 (the paper's default)."""
N_STAR = 100
"""N* of every experiment but fig12 (the paper's default)."""
N_STARS = (1, 10, 100, 1000, 10000)
"""fig12's N*."""
BASELINES = ("cbirrt", "cbirrt2", "cbirrt-norestart")
"""fig11's other planners, at dZ* = :data:`DZ_STAR` on the same problems (``cbirrt`` with
its default restart period; ``cbirrt-norestart`` for reference)."""
REFERENCE = "ompl"
"""fig11's outside reference (OMPL's RRTConnect on our manifold, the ``ompl`` extra), at
dZ* = :data:`DZ_STAR` on the first :data:`REFERENCE_POSES` poses of the same problems."""
REFERENCE_POSES = 20
"""Poses per object of fig11's OMPL runs (100 queries): OMPL needs its whole 60 s budget on
some queries, and 500 of them would not fit a session on a 2-core machine."""
RESTART_PERIODS = (25, 50, 100, 200, 400)
"""The ``restart`` sweep's cbirrt restart periods (search iterations per start/goal pair)."""
TABLE = "square"
"""The table of fig11 and fig12."""
SCALES = (1.0, 0.5)
"""fig10's object size factors."""
TIME_BUDGET = 60.0
"""Planning seconds per query (the paper's)."""
QUICK_BUDGET = 2.0
"""Planning seconds per query with ``--quick``."""
QUICK_OBJECTS = ("square", "L")
"""``--quick``: one paper object and one letter, one start pose each, square table only."""
QUICK_N_STARS = (1, 100)
"""fig12's N* with ``--quick``."""
POSES = {
    "fig10": 50,
    "fig11": 100,
    "fig12": 20,
    "restart": 20,
    "agents": 10,
    "relaxation": 2,
    "planners": 100,
}
"""Random start poses per object (seeds 0..n-1) at full size; the pose is the outer loop,
so an interrupted run holds a balanced share of every condition. fig12's 20 (the issue gives
none): 5 N* x 5 objects x 20 = 500 queries, a fifth of fig11; the restart sweep's 20: 6
settings x 5 objects x 20 = 600 queries; agents: 10 seeds per object and table; relaxation:
2 expert seeds per object, table and contact band (its planner-variant queries have their
own :data:`VARIANT_POSES`)."""
CUTS = {
    "fig11": f"OMPL on the first {REFERENCE_POSES} of the 100 poses "
    f"({5 * REFERENCE_POSES} queries, not 500)",
}
"""Where an experiment is smaller than the issue asks, and why (the report quotes it)."""
EXPERIMENTS = ("fig10", "fig11", "fig12", "restart", "agents", "relaxation", "planners")
"""The experiments; ``all`` runs them in this order."""
LATER: tuple[str, ...] = ()
"""Experiments of the issue still to come (none)."""


def dz_band(dz_star: float) -> list[float]:
    """The planner's contact-depth band ``[dZ-, dZ- + dZ*]`` (m) for width ``dz_star``."""
    return [DZ_MINUS, round(DZ_MINUS + dz_star, 6)]


def case(
    experiment: str,
    obj: str,
    table: str,
    seed: int,
    version: str,
    *,
    scale: float = 1.0,
    planner: str = "regions",
    dz_star: float = DZ_STAR,
    n_star: int = N_STAR,
    time_budget: float = TIME_BUDGET,
    restart_iterations: int = SlideParams.restart_iterations,
    projection: str | None = None,
) -> Case:
    """One planning query of ``experiment`` (seed: the random start pose and planner stream).

    ``projection`` (:attr:`~slide_gym.planning.params.SlideParams.projection`) is a key of the
    case only when given (the relaxation experiment's variants), so the other experiments'
    cases keep their keys."""
    out: Case = {
        "experiment": experiment,
        "object": obj,
        "table": table,
        "scale": scale,
        "planner": planner,
        "dz": dz_band(dz_star),
        "n_star": n_star,
        "restart_iterations": restart_iterations,
        "seed": seed,
        "time_budget": time_budget,
        "code_version": version,
    }
    if projection is not None:
        out["projection"] = projection
    return out


def _fig10(version: str, objects: Sequence[str], tables: Sequence[str], **kw: Any) -> list[Case]:
    """Every scale x table x object (paper objects, then the letters) per pose."""
    return [
        case("fig10", o, t, i, version, scale=s, time_budget=kw["time_budget"])
        for i in range(kw["poses"])
        for s in SCALES
        for t in tables
        for o in objects
    ]


def _fig11(version: str, objects: Sequence[str], tables: Sequence[str], **kw: Any) -> list[Case]:
    """regions at each dZ*, then the baselines at 2 cm, on the same problems (seeds); OMPL on
    the first :data:`REFERENCE_POSES` poses."""
    runs = [("regions", d) for d in DZ_STARS] + [(p, DZ_STAR) for p in BASELINES]
    reference = [(REFERENCE, DZ_STAR)]
    return [
        case("fig11", o, TABLE, i, version, planner=p, dz_star=d, time_budget=kw["time_budget"])
        for i in range(kw["poses"])
        for o in objects
        for p, d in runs + (reference if i < REFERENCE_POSES else [])
    ]


def _fig12(version: str, objects: Sequence[str], tables: Sequence[str], **kw: Any) -> list[Case]:
    """regions at each N*, dZ* = 2 cm."""
    return [
        case("fig12", o, TABLE, i, version, n_star=n, time_budget=kw["time_budget"])
        for i in range(kw["poses"])
        for o in objects
        for n in kw.get("n_stars", N_STARS)
    ]


def _restart(version: str, objects: Sequence[str], tables: Sequence[str], **kw: Any) -> list[Case]:
    """cbirrt at each restart period and without restarts, dZ* = 2 cm, fig11's problems."""
    runs = [("cbirrt", r) for r in RESTART_PERIODS] + [("cbirrt-norestart", 100)]
    return [
        case(
            "restart",
            o,
            TABLE,
            i,
            version,
            planner=p,
            restart_iterations=r,
            time_budget=kw["time_budget"],
        )
        for i in range(kw["poses"])
        for o in objects
        for p, r in runs
    ]


AGENT_PLANNERS = ("regions", "cbirrt", "cbirrt2")
"""The agents experiment's planners, each driving the expert."""
PLANNERS = ("regions", "cbirrt", "cbirrt2")
"""The ``planners`` experiment's planners (fig11's three, all at dZ* = :data:`DZ_STAR`)."""


def _planners(version: str, objects: Sequence[str], tables: Sequence[str], **kw: Any) -> list[Case]:
    """fig11's three planners at dZ* = 2 cm on fig11's problems, at each of :data:`SCALES`
    (same seeds at both scales; no OMPL reference)."""
    return [
        case("planners", o, TABLE, i, version, scale=s, planner=p, time_budget=kw["time_budget"])
        for i in range(kw["poses"])
        for s in SCALES
        for o in objects
        for p in PLANNERS
    ]


EXPERIMENT_ENV_ID = "SlideGym/TopSlideGrasp-v0"
"""The env of the experiments' expert episodes: the physics their committed rows ran in."""
AGENT_BUDGET = 10.0
"""The agents' planning seconds per episode (the expert's default)."""


def episode_case(
    experiment: str,
    obj: str,
    table: str,
    seed: int,
    version: str,
    planner: str,
    time_budget: float,
    dz: list[float] | None = None,
) -> Case:
    """One expert episode on :data:`EXPERIMENT_ENV_ID` (``dz``, if given, replaces the
    expert's contact band for every plan of the episode)."""
    return {
        "experiment": experiment,
        "object": obj,
        "table": table,
        "scale": 1.0,
        "planner": planner,
        **({} if dz is None else {"dz": dz}),
        "seed": seed,
        "time_budget": time_budget,
        "env_id": EXPERIMENT_ENV_ID,
        "code_version": version,
    }


def _agents(version: str, objects: Sequence[str], tables: Sequence[str], **kw: Any) -> list[Case]:
    """The expert with each planner on every object and table (episode seed = pose seed)."""
    budget = min(kw["time_budget"], AGENT_BUDGET)
    return [
        episode_case("agents", o, t, i, version, p, budget)
        for i in range(kw["poses"])
        for t in tables
        for o in objects
        for p in AGENT_PLANNERS
    ]


EXPERT_DZ = (0.012, 0.02)
"""The expert's own contact band (m, ``agents.params.EXPERT_SLIDE_PARAMS.dz``: dZ- = 1.2 cm,
dZ* = 0.8 cm), the relaxation experiment's reference condition."""
VARIANTS = ("steps", "nodes", "orientation")
"""The relaxation experiment's planner variants (:attr:`SlideParams.projection`): our
projection at every extension step (the reference, fig11's planner), projection only at tree
nodes with straight edges checked, and a projection of the orientation alone (the contact
depth only checked). ``"ompl"`` (OMPL's default projection) is left out: in a scratch run it
behaved as ``"steps"`` at every dZ*."""
VARIANT_POSES = 10
"""Start poses per object of the relaxation experiment's planner-variant queries (fig11 has
100): 3 variants x 3 dZ* x 5 objects x 10 poses = 450 queries."""
VARIANT_BUDGET = 20.0
"""Planning seconds per planner-variant query (the paper's 60 s, cut: failing queries spend
the whole budget)."""


def _relaxation(
    version: str, objects: Sequence[str], tables: Sequence[str], **kw: Any
) -> list[Case]:
    """Two parts, pose by pose (pose ``i``'s variant queries, then seed ``i``'s episodes):

    * the expert (``regions``) on every object and table planning with the band of each dZ*
      (``dz_band``, dZ- = 0.5 cm), and with its own band :data:`EXPERT_DZ` for reference: the
      case's ``dz`` replaces the expert's for every plan of the episode (first, relaxed
      fallback, replans), nothing else changes;
    * ``regions`` with each of :data:`VARIANTS` at each dZ* on fig11's problems (the square
      table, the paper's objects, same seeds).
    """
    budget = min(kw["time_budget"], AGENT_BUDGET)
    bands = [dz_band(d) for d in DZ_STARS] + [list(EXPERT_DZ)]
    expert = [
        [
            episode_case("relaxation", o, t, i, version, "regions", budget, dz)
            for t in tables
            for o in objects
            for dz in bands
        ]
        for i in range(kw["poses"])
    ]
    plan_budget = min(kw["time_budget"], VARIANT_BUDGET)
    paper = [o for o in objects if o in PAPER_OBJECTS]
    plans = [
        [
            case(
                "relaxation",
                o,
                TABLE,
                i,
                version,
                dz_star=d,
                time_budget=plan_budget,
                projection=v,
            )
            for o in paper
            for v in VARIANTS
            for d in DZ_STARS
        ]
        for i in range(kw.get("variant_poses", kw["poses"]))
    ]
    return [
        c
        for i in range(max(len(expert), len(plans)))
        for part in (plans, expert)
        if i < len(part)
        for c in part[i]
    ]


_BUILDERS = {
    "fig10": _fig10,
    "fig11": _fig11,
    "fig12": _fig12,
    "restart": _restart,
    "agents": _agents,
    "relaxation": _relaxation,
    "planners": _planners,
}


def experiment_cases(
    name: str,
    version: str,
    quick: bool = False,
    poses: int | None = None,
    time_budget: float | None = None,
) -> list[Case]:
    """The cases of experiment ``name`` (one of :data:`EXPERIMENTS`), stamped ``version``.

    Full size: fig10 2 scales x 4 tables x 9 objects x 50 poses (3600); fig11 5 objects x 100
    poses x (3 dZ* + 3 baselines) plus OMPL on 20 poses (3100); fig12 5 N* x 5 objects x 20
    poses (500); restart 6 settings x 5 objects x 20 poses (600); planners 3 planners x 2
    scales x 5 objects x 100 poses (3000); 60 s each; agents 3 planners x
    9 objects x 4 tables x 10 seeds (1080 episodes, 10 s planning each); relaxation 4 contact
    bands (dZ* = 0, 0.5, 2 cm and the expert's own) x 9 objects x 4 tables x 2 seeds (288
    episodes, 10 s planning each) and 3 planner variants x 3 dZ* x 5 objects x 10 poses (450
    queries, 20 s each; about 25 min with 2 workers). ``quick``: the square table, objects
    :data:`QUICK_OBJECTS`, one pose, 2 s, fig12 at N* = 1 and 100 only (fig10 4, fig11 14, fig12
    4, restart 12 queries, planners 12, agents 6 episodes, relaxation 8 episodes and 9 queries
    on the paper object: a CI smoke test).

    A reduced run (not with ``quick``): ``poses`` keeps the first start poses of the full size
    (fewer, never more), ``time_budget`` replaces the planning seconds per query (expert
    episodes keep their own cap).
    """
    if name not in _BUILDERS:
        raise ValueError(f"unknown experiment {name!r}; implemented: {', '.join(EXPERIMENTS)}")
    if quick and (poses is not None or time_budget is not None):
        raise ValueError("--quick has its own size; leave out --poses and --budget")
    if poses is not None and not 1 <= poses <= POSES[name]:
        raise ValueError(f"--poses must be 1 to {POSES[name]} for {name}, got {poses}")
    if time_budget is not None and not time_budget > 0:
        raise ValueError(f"--budget must be > 0 s, got {time_budget:g}")
    if quick:
        kw: dict[str, Any] = {"poses": 1, "time_budget": QUICK_BUDGET, "n_stars": QUICK_N_STARS}
        return _BUILDERS[name](version, QUICK_OBJECTS, (TABLE,), **kw)
    objects = (
        PAPER_OBJECTS + LETTERS if name in ("fig10", "agents", "relaxation") else PAPER_OBJECTS
    )
    n = POSES[name] if poses is None else poses
    kw = {
        "poses": n,
        "time_budget": TIME_BUDGET if time_budget is None else float(time_budget),
        "variant_poses": VARIANT_POSES if poses is None else min(poses, VARIANT_POSES),
    }
    return _BUILDERS[name](version, objects, TABLE_NAMES, **kw)
