"""benchmarks/slide_sides.py: where a recorded slide ends and which side it went."""

from __future__ import annotations

from collections.abc import Callable
from types import ModuleType

import numpy as np

from slide_gym.envs.observation import TABLE_OUTLINE_POINTS
from slide_gym.geometry import get_table


class _Episode:
    """A recorded episode's fields that slide_sides reads, on the square table."""

    def __init__(self, xy: list[tuple[float, float]], overhang: list[float], lifted: int):
        square = get_table("square")
        n = len(xy)
        z = square.height + np.where(np.arange(n) >= lifted, 0.05, 0.0)
        pose = np.column_stack([np.asarray(xy), z, np.zeros((n, 4))])
        self.observations = {
            "table_outline": np.tile(square.descriptor(TABLE_OUTLINE_POINTS).ravel(), (n, 1)),
            "table_height": np.full((n, 1), square.height),
            "object_pose": pose,
        }
        self.infos = {"overhang_m": np.asarray(overhang + [0.0])}


def test_a_slide_ends_where_the_overhang_peaked_before_the_lift(
    load_benchmark: Callable[[str], ModuleType],
) -> None:
    sides = load_benchmark("slide_sides")
    z = np.array([0.0, 0.0, 0.0, 0.0, 0.02, 0.05])
    overhang = np.array([0.0, 0.01, 0.03, 0.025, 0.01, 0.0])
    assert sides.slide_end(z, overhang, 0.0) == 2
    assert sides.slide_end(np.zeros(6), overhang, 0.0) == 2  # never lifted: the whole episode


def test_a_slide_to_the_other_side_is_counted_as_such(
    load_benchmark: Callable[[str], ModuleType],
) -> None:
    sides = load_benchmark("slide_sides")
    to_own_side = _Episode([(0.55, 0.05), (0.5, 0.15), (0.45, 0.22)], [0.0, 0.0, 0.03], 3)
    to_far_side = _Episode([(0.55, 0.05), (0.5, -0.1), (0.45, -0.22)], [0.0, 0.0, 0.03], 3)
    assert sides.toward_nearest(to_own_side)
    assert not sides.toward_nearest(to_far_side)
