"""The learning table's rows (benchmarks/learning.py): the commands each row cites."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from types import ModuleType


def test_a_row_that_tests_another_rows_policy_cites_that_rows_data_and_training(
    load_benchmark: Callable[[str], ModuleType],
) -> None:
    rows = load_benchmark("learning")
    models = Path("models")
    procedural = rows.command(rows.ROWS["dp-catalog-grasp-procedural"], models)
    catalog = rows.command(rows.ROWS["dp-catalog-grasp"], models)
    collect, train, evaluate = procedural.split("; ")
    assert [collect, train] == catalog.split("; ")[:2]  # the catalog policy's own data
    assert "--object random --table random" in collect and "--iterations 10000" in train
    assert evaluate.startswith("slide-gym evaluate models/dp-catalog-grasp ")
    assert "--object procedural --table random" in evaluate


def test_every_row_names_a_known_method_and_env(
    load_benchmark: Callable[[str], ModuleType],
) -> None:
    rows = load_benchmark("learning")
    methods = {"random", "expert", "bc", "dp", "dp-dart", "dp-dagger"}
    for name, row in rows.ROWS.items():
        assert row.name == name and row.method in methods
        assert row.env_id in (rows.SLIDE, rows.GRASP)
        if row.base is not None:
            assert row.base in rows.ROWS, f"{name}: unknown base {row.base}"


def test_rows_in_anchored_physics_collect_train_and_test_in_it(
    load_benchmark: Callable[[str], ModuleType],
) -> None:
    from slide_gym.datasets.config import CollectConfig

    rows = load_benchmark("learning")
    row = rows.ROWS["dp-ee-square-slide-stop-anchor-b256-10k"]
    collect, _, evaluate = rows.command(row, Path("models")).split("; ")
    assert "--physics friction_anchor=1" in collect and "--physics friction_anchor=1" in evaluate
    config = CollectConfig(env_id=row.env_id, **row.scene)  # as run() collects
    assert config.env_kwargs()["physics"] == {"friction_anchor": True}
    plain = rows.ROWS["dp-ee-square-slide-stop-b256-10k"]
    assert "--physics" not in rows.command(plain, Path("models"))
