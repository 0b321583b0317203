"""Run an experiment's planning cases in parallel into one JSONL file per experiment and code
version, resumably (:func:`slide_gym.jobs.run_cases`: a line per finished query, a
re-run skips finished ones, Ctrl-C keeps them)."""

from __future__ import annotations

import dataclasses
import re
import sys
from pathlib import Path
from typing import Any

from slide_gym.experiments.specs import EXPERIMENTS, LATER, experiment_cases
from slide_gym.jobs import Case, check_backend, load_results, run_cases
from slide_gym.version import code_version

OUT = Path("results/experiments")
"""Default results folder."""
LEFT_OUT = ("path", "transfer_path", "table_polygon")
"""``slide-gym plan --json`` fields not stored per row: the paths (large) and the table's
outline (the same for every row of a table; the catalog has it)."""
REJECTED = "rejected"
"""Row status of a scene the planner refuses before planning (the reason says why)."""


_TAG_PART = re.compile(r"quick|poses[0-9]+|budget[0-9.]+s")
"""One part of a results file's size tag (a code version starts with a digit instead)."""


def size_tag(quick: bool = False, poses: int | None = None, budget: float | None = None) -> str:
    """A run's size in its file name: ``""`` (full size), ``"quick"``, or for a reduced run
    ``"posesN"`` and ``"budgetSs"`` joined by ``-`` (e.g. ``poses10-budget10s``)."""
    if quick:
        return "quick"
    parts = ([] if poses is None else [f"poses{poses}"]) + (
        [] if budget is None else [f"budget{budget:g}s"]
    )
    return "-".join(parts)


def parse_size_tag(tag: str) -> dict[str, Any]:
    """:func:`size_tag`'s inverse, as ``experiment_cases`` keywords (quick, poses,
    time_budget); a ValueError for a tag it does not write."""
    out: dict[str, Any] = {"quick": False, "poses": None, "time_budget": None}
    for part in tag.split("-") if tag else []:
        if part == "quick":
            out["quick"] = True
        elif part.startswith("poses") and _TAG_PART.fullmatch(part):
            out["poses"] = int(part[5:])
        elif part.startswith("budget") and _TAG_PART.fullmatch(part):
            out["time_budget"] = float(part[6:-1])
        else:
            raise ValueError(f"not a size tag: {tag!r}")
    return out


def results_file(
    out: Path,
    name: str,
    version: str,
    quick: bool = False,
    *,
    poses: int | None = None,
    budget: float | None = None,
) -> Path:
    """``OUT/NAME-VERSION.jsonl`` (``NAME-TAG-VERSION.jsonl`` with :func:`size_tag`'s
    ``TAG``, e.g. ``quick``): each code version and size gets its own file, so rows of
    different code or size never mix."""
    tag = size_tag(quick, poses, budget)
    return out / f"{name}{'-' + tag if tag else ''}-{version}.jsonl"


def file_tag(filename: str, name: str) -> str | None:
    """The size tag of results file ``filename`` of experiment ``name`` (``""``: full size),
    or None when the name is not ``NAME-[TAG-]VERSION.jsonl[.gz]``."""
    stem = re.sub(r"\.jsonl(\.gz)?$", "", filename)
    if stem == filename or not stem.startswith(f"{name}-"):
        return None
    parts = stem[len(name) + 1 :].split("-")
    tag = []
    while len(parts) > 1 and _TAG_PART.fullmatch(parts[0]):
        tag.append(parts.pop(0))
    return "-".join(tag)


def experiment_case(case: Case) -> dict[str, Any]:
    """One planning query (runs in a worker process): the ``slide-gym plan --json`` fields but
    :data:`LEFT_OUT`, then the case's own fields (experiment, object, table, scale, planner,
    dz, n_star, restart_iterations, seed, time_budget, code_version, and projection where
    given). A case with an ``env_id`` (agents, the relaxation experiment's expert part) is
    one expert episode instead: the ``slide-gym run --json`` fields, then the case's (its
    ``dz``, if any, is the band the expert plans with)."""
    from slide_gym.planning.runner import make_params, plan_once

    if "env_id" in case:
        from slide_gym.bench.execute import execute_case

        return {**execute_case(case), **case}
    params = make_params(
        dz=(case["dz"][0], case["dz"][1]),
        n_star=case["n_star"],
        restart_iterations=case["restart_iterations"],
    )
    if "projection" in case:
        params = dataclasses.replace(params, projection=case["projection"])
    try:
        report = plan_once(
            case["object"],
            case["table"],
            scale=case["scale"],
            seed=case["seed"],
            planner=case["planner"],
            time_budget=case["time_budget"],
            params=params,
        )
        row = {k: v for k, v in report.items() if k not in LEFT_OUT}
    except ValueError as err:
        row = {"status": REJECTED, "reason": " ".join(str(err).split())}
    return {**row, **case}


def row_status(row: dict[str, Any]) -> str:
    """A row's outcome for the summary: a planning query's ``status``; for an expert episode
    (no ``status``), ``"success"`` or ``"failure"`` (the env's ``is_success``)."""
    if "status" in row:
        return str(row["status"])
    return "success" if row.get("success") else "failure"


def check_file(path: Path, version: str) -> None:
    """A ValueError if ``path`` holds a row of another code version (a renamed or merged
    file): such rows are never counted as done, nor mixed into this version's results."""
    for row in load_results(path):
        other = row.get("case", {}).get("code_version")
        if other != version:
            raise ValueError(
                f"{path} holds rows of code version {other!r}, not {version!r}; move it "
                "away: each code version writes its own file"
            )


def other_versions(
    out: Path,
    name: str,
    version: str,
    quick: bool = False,
    *,
    poses: int | None = None,
    budget: float | None = None,
) -> list[Path]:
    """Result files of ``name`` (same size) by other code versions in ``out``: not reused."""
    mine = results_file(out, name, version, quick, poses=poses, budget=budget)
    tag = size_tag(quick, poses, budget)
    return sorted(
        p for p in out.glob(f"{name}-*.jsonl") if p != mine and file_tag(p.name, name) == tag
    )


def run_experiment(
    name: str,
    quick: bool = False,
    workers: int | None = None,
    backend: str = "local",
    out: Path = OUT,
    address: str | None = None,
    poses: int | None = None,
    budget: float | None = None,
) -> dict[str, Any]:
    """Run (or resume) experiment ``name`` into :func:`results_file`; a summary of its rows.
    ``backend`` and ``address``: see :func:`~slide_gym.jobs.run_cases`; ``poses`` and
    ``budget``: a reduced run (the first start poses, seconds per query), into its own file."""
    check_backend(backend, address)
    if name in LATER:
        implemented = ", ".join(EXPERIMENTS)
        raise ValueError(f"experiment {name!r} is not implemented yet; run one of {implemented}")
    version = code_version()
    cases = experiment_cases(name, version, quick, poses, budget)
    path = results_file(out, name, version, quick, poses=poses, budget=budget)
    check_file(path, version)
    for old in other_versions(out, name, version, quick, poses=poses, budget=budget):
        print(f"{name}: not reusing {old} (another code version)", file=sys.stderr)
    rows = run_cases(
        experiment_case, cases, path, workers, desc=name, backend=backend, address=address
    )
    statuses: dict[str, int] = {}
    for row in rows:
        status = row_status(row)
        statuses[status] = statuses.get(status, 0) + 1
    return {
        "experiment": name,
        "quick": quick,
        "size": size_tag(quick, poses, budget) or "full",
        "code_version": version,
        "file": str(path),
        "runs": len(rows),
        "of": len(cases),
        "status": dict(sorted(statuses.items())),
    }


def run_experiments(
    names: list[str],
    quick: bool = False,
    workers: int | None = None,
    backend: str = "local",
    out: Path = OUT,
    address: str | None = None,
    poses: int | None = None,
    budget: float | None = None,
) -> list[dict[str, Any]]:
    """:func:`run_experiment` for each of ``names`` in turn (``all``: every implemented one);
    a reduced size (``poses``, ``budget``) is checked for every one before any runs."""
    check_backend(backend, address)
    if workers is not None and workers < 1:
        raise ValueError(f"--workers must be >= 1, got {workers}")
    expanded = [n for name in names for n in (EXPERIMENTS if name == "all" else (name,))]
    for n in expanded:
        if n in EXPERIMENTS:
            experiment_cases(n, "check", quick, poses, budget)  # a bad size: before any work
    return [
        run_experiment(n, quick, workers, backend, out, address, poses, budget) for n in expanded
    ]
