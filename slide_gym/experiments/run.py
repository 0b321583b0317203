"""Run an experiment's planning cases in parallel into one JSONL file per experiment and code
version, resumably (:func:`slide_gym.jobs.run_cases`: a line per finished query, a
re-run skips finished ones, Ctrl-C keeps them)."""

from __future__ import annotations

import dataclasses
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


def results_file(out: Path, name: str, version: str, quick: bool = False) -> Path:
    """``OUT/NAME-VERSION.jsonl`` (``NAME-quick-VERSION.jsonl`` with ``quick``): each code
    version and size gets its own file, so rows of different code never mix."""
    return out / f"{name}{'-quick' if quick else ''}-{version}.jsonl"


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


def other_versions(out: Path, name: str, version: str, quick: bool = False) -> list[Path]:
    """Result files of ``name`` (same size) by other code versions in ``out``: not reused."""
    mine = results_file(out, name, version, quick)
    head = results_file(out, name, "", quick).name[: -len(".jsonl")]
    return sorted(
        p
        for p in out.glob(f"{head}*.jsonl")
        if p != mine and (quick or not p.name.startswith(f"{name}-quick-"))
    )


def run_experiment(
    name: str,
    quick: bool = False,
    workers: int | None = None,
    backend: str = "local",
    out: Path = OUT,
    address: str | None = None,
) -> dict[str, Any]:
    """Run (or resume) experiment ``name`` into :func:`results_file`; a summary of its rows.
    ``backend`` and ``address``: see :func:`~slide_gym.jobs.run_cases`."""
    check_backend(backend, address)
    if name in LATER:
        implemented = ", ".join(EXPERIMENTS)
        raise ValueError(f"experiment {name!r} is not implemented yet; run one of {implemented}")
    version = code_version()
    cases = experiment_cases(name, version, quick)
    path = results_file(out, name, version, quick)
    check_file(path, version)
    for old in other_versions(out, name, version, quick):
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
) -> list[dict[str, Any]]:
    """:func:`run_experiment` for each of ``names`` in turn (``all``: every implemented one)."""
    check_backend(backend, address)
    if workers is not None and workers < 1:
        raise ValueError(f"--workers must be >= 1, got {workers}")
    expanded = [n for name in names for n in (EXPERIMENTS if name == "all" else (name,))]
    return [run_experiment(n, quick, workers, backend, out, address) for n in expanded]
