"""Long batch jobs (benchmarks, experiments): run cases in parallel, write each result as one
JSON line the moment it is done, skip cases already in the file on a re-run, and stop cleanly
on Ctrl-C without losing finished work.

A case is a dict of JSON values; :func:`case_key` is the one identity of a case, used both to
skip finished cases and to pick this run's results out of a file that may hold others.
"""

from __future__ import annotations

import json
import multiprocessing as mp
import os
import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from tqdm import tqdm

Case = dict[str, Any]


def case_key(case: Case) -> str:
    """A stable identity for a case (its parameters as sorted JSON)."""
    return json.dumps(case, sort_keys=True)


def load_results(path: Path) -> list[dict[str, Any]]:
    """Every complete JSON line of a results file (a torn last line from a kill is skipped)."""
    if not path.exists():
        return []
    rows = []
    for line in path.read_text().splitlines():
        try:
            rows.append(json.loads(line))
        except json.JSONDecodeError:
            continue
    return rows


def _init_worker() -> None:
    os.environ["OMP_NUM_THREADS"] = "1"


def run_cases(
    fn: Callable[[Case], dict[str, Any]],
    cases: Iterable[Case],
    out: Path,
    workers: int | None = None,
    desc: str = "cases",
) -> list[dict[str, Any]]:
    """Run ``fn(case)`` for every case not yet in ``out``; return the results of ``cases``.

    Each result is stored as ``{"case": case, **fn(case)}``. The returned rows are those in
    ``out`` (finished before or now, in file order) whose case is one of ``cases``; rows of
    other cases in the file are kept there but not returned. ``fn`` must be a module-level
    function (it is pickled to worker processes) and must not raise for a failed case: it
    reports failures in its result.
    """
    cases = list(cases)
    wanted = {case_key(c) for c in cases}
    out.parent.mkdir(parents=True, exist_ok=True)
    done = {case_key(r["case"]) for r in load_results(out) if "case" in r}
    todo = [c for c in cases if case_key(c) not in done]
    workers = workers or os.cpu_count() or 1
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    if todo:
        print(
            f"{len(done)} done already, {len(todo)} to run on {workers} worker(s)", file=sys.stderr
        )
    if out.exists() and out.stat().st_size and not out.read_bytes().endswith(b"\n"):
        with out.open("a") as f:  # end a line torn by a kill, so new results start clean
            f.write("\n")
    try:
        with out.open("a") as f, tqdm(total=len(todo), desc=desc, file=sys.stderr) as bar:
            if workers == 1:
                for case in todo:
                    _write(f, case, fn(case))
                    bar.update()
            else:
                ctx = mp.get_context("spawn")
                with ctx.Pool(workers, initializer=_init_worker, maxtasksperchild=20) as pool:
                    for case, result in pool.imap_unordered(_Call(fn), todo):
                        _write(f, case, result)
                        bar.update()
    except KeyboardInterrupt:
        print(f"\ninterrupted: finished results are in {out}; re-run to resume", file=sys.stderr)
        raise
    return [r for r in load_results(out) if "case" in r and case_key(r["case"]) in wanted]


class _Call:
    """Picklable wrapper returning the case with its result."""

    def __init__(self, fn: Callable[[Case], dict[str, Any]]):
        self.fn = fn

    def __call__(self, case: Case) -> tuple[Case, dict[str, Any]]:
        return case, self.fn(case)


def _write(f: Any, case: Case, result: dict[str, Any]) -> None:
    f.write(json.dumps({"case": case, **result}) + "\n")
    f.flush()
