"""The straight slide on's geometry (agents.takeover.straight_drag): the shortest drag along
a table edge's normal that leaves the plate graspable, the fingertip on the table."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from agents.takeover import TIP_ON_TABLE, straight_drag
from slide_gym.geometry import overhang

TABLE = shapely.box(-0.5, -0.5, 0.5, 0.5)  # CCW exterior
U = 0.035


def _plate(cx: float, cy: float, half: float = 0.05) -> shapely.Polygon:
    return shapely.box(cx - half, cy - half, cx + half, cy + half)


def test_drags_toward_the_nearest_edge_by_what_is_missing() -> None:
    plate = _plate(0.445, 0.0)  # 5 mm inside the +x edge
    shift = straight_drag(plate, TABLE, np.array([0.43, 0.0]), U, 0.01)
    assert shift is not None
    np.testing.assert_allclose(shift, [U + 0.005, 0.0], atol=1e-9)
    moved = shapely.affinity.translate(plate, *shift)
    assert overhang(moved, TABLE).graspable(U - 1e-6)


def test_a_plate_already_over_an_edge_goes_on_over_it() -> None:
    plate = _plate(0.0, -0.46)  # 1 cm over the -y edge
    shift = straight_drag(plate, TABLE, np.array([0.0, -0.44]), U, 0.01)
    assert shift is not None
    np.testing.assert_allclose(shift, [0.0, -(U - 0.01)], atol=1e-9)


def test_a_fingertip_that_would_end_over_the_void_takes_another_edge() -> None:
    plate = _plate(0.40, 0.38)  # near the +x and +y edges
    tip = np.array([0.44, 0.36])  # on the plate's +x side: past the +x edge after the drag
    shift = straight_drag(plate, TABLE, tip, U, 0.01)
    assert shift is not None and shift[0] == 0.0 and shift[1] > 0.0
    assert TABLE.buffer(-TIP_ON_TABLE).contains(shapely.Point(*(tip + shift)))


@pytest.mark.parametrize("margin", [0.03, 0.06])
def test_none_when_the_centroid_cannot_stay_inside_by_the_margin(margin: float) -> None:
    plate = _plate(0.40, 0.0, half=0.04)  # 8 cm across: 3.5 cm over leaves its centroid 5 mm in
    tip = np.array([0.37, 0.0])
    assert straight_drag(plate, TABLE, tip, U, margin) is None
    np.testing.assert_allclose(straight_drag(plate, TABLE, tip, U, 0.004), [0.095, 0.0])
