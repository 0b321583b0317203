"""Long batch jobs (benchmarks, experiments, dataset collection): run cases in parallel,
write each result as one JSON line the moment it is done, skip cases already in the file on
a re-run, and stop cleanly on Ctrl-C without losing finished work.

A case is a dict of JSON values; :func:`case_key` is the one identity of a case, used both to
skip finished cases and to pick this run's results out of a file that may hold others.
"""

from __future__ import annotations

import gzip
import json
import multiprocessing as mp
import os
import sys
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

from tqdm import tqdm

Case = dict[str, Any]


def case_key(case: Case) -> str:
    """A stable identity for a case (its parameters as sorted JSON)."""
    return json.dumps(case, sort_keys=True)


def load_results(path: Path) -> list[dict[str, Any]]:
    """Every complete JSON line of a results file (a torn last line from a kill is skipped);
    ``*.gz`` files (committed results are stored compressed) are read through gzip."""
    if not path.exists():
        return []
    rows = []
    text = gzip.decompress(path.read_bytes()).decode() if path.suffix == ".gz" else None
    for line in (text if text is not None else path.read_text()).splitlines():
        try:
            rows.append(json.loads(line))
        except json.JSONDecodeError:
            continue
    return rows


BACKENDS = ("local", "ray")
"""Where cases run: ``local`` (a process pool on this machine) or ``ray`` (Ray tasks on a
local Ray instance or a cluster; the ``ray`` extra)."""


def _init_worker() -> None:
    os.environ["OMP_NUM_THREADS"] = "1"


Store = Callable[[Case, dict[str, Any]], dict[str, Any]]
"""``store(case, result) -> row``: runs in this process before a result's line is written
(e.g. saves a large payload to its own file and returns the JSON-able rest)."""


def check_backend(backend: str, address: str | None = None) -> None:
    """A ValueError unless ``backend`` is known and can run here (Ray installed for ``ray``)."""
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; choose from {', '.join(BACKENDS)}")
    if backend == "ray":
        try:
            import ray  # noqa: F401
        except ImportError:
            raise ValueError(
                "--backend ray needs Ray: pip install 'slide-gym[ray]' (or use --backend local)"
            ) from None
    elif address is not None:
        raise ValueError("--ray-address goes with --backend ray")


def run_cases(
    fn: Callable[[Case], dict[str, Any]],
    cases: Iterable[Case],
    out: Path,
    workers: int | None = None,
    desc: str = "cases",
    *,
    backend: str = "local",
    address: str | None = None,
    store: Store | None = None,
    success_key: str | None = None,
) -> list[dict[str, Any]]:
    """Run ``fn(case)`` for every case not yet in ``out``; return the results of ``cases``.

    Each result is stored as ``{"case": case, **row}``, where ``row`` is ``fn(case)`` passed
    through ``store`` if given. The returned rows are those in ``out`` (finished before or
    now, in file order) whose case is one of ``cases``; rows of other cases in the file are
    kept there but not returned. ``fn`` must be a module-level function (it is pickled to
    worker processes) and must not raise for a failed case: it reports failures in its
    result. ``backend="ray"`` runs the cases as Ray tasks (one CPU each) on the cluster at
    ``address`` (None: a local Ray instance with ``workers`` CPUs). ``success_key``: a
    boolean result entry whose running rate the progress bar shows.
    """
    check_backend(backend, address)
    cases = list(cases)
    wanted = {case_key(c) for c in cases}
    out.parent.mkdir(parents=True, exist_ok=True)
    done = {case_key(r["case"]) for r in load_results(out) if "case" in r}
    todo = [c for c in cases if case_key(c) not in done]
    workers = workers or os.cpu_count() or 1
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    if todo:
        where = f"{workers} worker(s)" if backend == "local" else f"Ray ({address or 'local'})"
        print(f"{len(done)} done already, {len(todo)} to run on {where}", file=sys.stderr)
    if out.exists() and out.stat().st_size and not out.read_bytes().endswith(b"\n"):
        with out.open("a") as f:  # end a line torn by a kill, so new results start clean
            f.write("\n")
    wins = [0, 0]

    def finish(f: Any, bar: Any, case: Case, result: dict[str, Any]) -> None:
        row = store(case, result) if store is not None else result
        _write(f, case, row)
        if success_key is not None:
            wins[0] += bool(row.get(success_key))
            wins[1] += 1
            bar.set_postfix_str(f"{success_key} {wins[0]}/{wins[1]}", refresh=False)
        bar.update()

    try:
        with out.open("a") as f, tqdm(total=len(todo), desc=desc, file=sys.stderr) as bar:
            if not todo:
                pass
            elif backend == "ray":
                for case, result in _ray_results(fn, todo, workers, address):
                    finish(f, bar, case, result)
            elif workers == 1:
                for case in todo:
                    finish(f, bar, case, fn(case))
            else:
                ctx = mp.get_context("spawn")
                with ctx.Pool(workers, initializer=_init_worker, maxtasksperchild=20) as pool:
                    for case, result in pool.imap_unordered(_Call(fn), todo):
                        finish(f, bar, case, result)
    except KeyboardInterrupt:
        print(f"\ninterrupted: finished results are in {out}; re-run to resume", file=sys.stderr)
        raise
    return [r for r in load_results(out) if "case" in r and case_key(r["case"]) in wanted]


def _ray_results(
    fn: Callable[[Case], dict[str, Any]], todo: list[Case], workers: int, address: str | None
) -> Iterator[tuple[Case, dict[str, Any]]]:
    """``(case, fn(case))`` as Ray tasks finish; Ray is started here and shut down after."""
    import ray

    if address is None:
        ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
    else:
        ray.init(address=address, log_to_driver=False)
    try:
        task = ray.remote(num_cpus=1)(_ray_call)
        pending = [task.remote(fn, case) for case in todo]
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            yield ray.get(ready[0])
    finally:
        ray.shutdown()


def _ray_call(fn: Callable[[Case], dict[str, Any]], case: Case) -> tuple[Case, dict[str, Any]]:
    os.environ["OMP_NUM_THREADS"] = "1"
    return case, fn(case)


class _Call:
    """Picklable wrapper returning the case with its result."""

    def __init__(self, fn: Callable[[Case], dict[str, Any]]):
        self.fn = fn

    def __call__(self, case: Case) -> tuple[Case, dict[str, Any]]:
        return case, self.fn(case)


def _write(f: Any, case: Case, result: dict[str, Any]) -> None:
    f.write(json.dumps({"case": case, **result}) + "\n")
    f.flush()
