"""The JSON shapes the documentation shows (docs/examples/) load as objects and tables."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from slide_gym.geometry import load_object_json, load_table_json

EXAMPLES = Path(__file__).resolve().parents[1] / "docs" / "examples"


@pytest.mark.parametrize("path", sorted(EXAMPLES.glob("*.json")), ids=lambda p: p.name)
def test_every_example_shape_loads(path: Path) -> None:
    is_table = "height" in json.loads(path.read_text())
    shape = load_table_json(path) if is_table else load_object_json(path)
    assert shape.name == path.stem
    assert shape.polygon.is_valid and shape.polygon.area > 0


def test_there_are_objects_and_tables() -> None:
    kinds = {"height" in json.loads(p.read_text()) for p in EXAMPLES.glob("*.json")}
    assert kinds == {True, False}
