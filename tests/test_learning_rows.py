"""The learning table's rows (benchmarks/learning.py): the commands each row cites."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType


def learning() -> ModuleType:
    path = Path(__file__).resolve().parents[1] / "benchmarks" / "learning.py"
    spec = importlib.util.spec_from_file_location("learning_rows", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def test_a_row_that_tests_another_rows_policy_cites_that_rows_data_and_training() -> None:
    rows = learning()
    models = Path("models")
    procedural = rows.command(rows.ROWS["dp-catalog-grasp-procedural"], models)
    catalog = rows.command(rows.ROWS["dp-catalog-grasp"], models)
    collect, train, evaluate = procedural.split("; ")
    assert [collect, train] == catalog.split("; ")[:2]  # the catalog policy's own data
    assert "--object random --table random" in collect and "--iterations 10000" in train
    assert evaluate.startswith("slide-gym evaluate models/dp-catalog-grasp ")
    assert "--object procedural --table random" in evaluate


def test_every_row_names_a_known_method_and_env() -> None:
    rows = learning()
    methods = {"random", "expert", "bc", "dp", "dp-dart", "dp-dagger"}
    for name, row in rows.ROWS.items():
        assert row.name == name and row.method in methods
        assert row.env_id in (rows.SLIDE, rows.GRASP)
        if row.base is not None:
            assert row.base in rows.ROWS, f"{name}: unknown base {row.base}"
