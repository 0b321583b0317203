"""Thin plates in physics: pressed and dragged by finger A, through the environment's actions.

A credit card (0.76 mm) pressed at the planner's deepest contact depth (2.5 cm below its top)
stays on the table top, and dragged 20 cm it follows the fingertip; plates of 0.5 mm and
10 mm too. :func:`slide_gym.bench.drag.drag_plate` watches every physics step. No wall-clock
assertions; each drag simulates about 9 s (about a second of CPU).
"""

from __future__ import annotations

import math

import pytest

from slide_gym.bench.drag import drag_plate
from slide_gym.geometry import get_object
from slide_gym.planning.params import SlideParams

DEEPEST = SlideParams().dz[1]
"""The planner's deepest contact depth below the plate top (m)."""
MAX_SINK = 0.0006
"""How far (m) a plate's lowest point may go below the table top (the solver's penetration;
0.58 mm at most over 24 card drags, README "Performance")."""
MAX_LAG = 0.025
"""How far (m) a dragged plate may fall behind the fingertip over 20 cm (README: creep)."""


@pytest.mark.parametrize("tip_first", [False, True])
def test_a_card_pressed_at_the_deepest_depth_stays_on_the_table_top(tip_first: bool) -> None:
    r = drag_plate(0.00076, DEEPEST, heading=0.0, tip_first=tip_first, length=0.05)
    assert abs(r.rest_gap_m) < 1e-4  # it lies on its real thickness, not on a margin
    assert r.sink_press_m <= MAX_SINK and r.sink_m <= MAX_SINK
    assert r.press_force_n > 0.2 and r.contact_fraction > 0.95  # pressed, not pierced
    assert not r.ejected


@pytest.mark.parametrize(
    ("heading", "tip_first"), [(0.0, False), (math.pi / 2, False), (math.pi, True)]
)
def test_a_card_dragged_20_cm_follows_the_fingertip(heading: float, tip_first: bool) -> None:
    r = drag_plate(0.00076, 0.02, heading=heading, tip_first=tip_first)
    assert r.tip_moved_m == pytest.approx(0.20, abs=0.015)
    assert abs(r.lag_m) <= MAX_LAG, r
    assert r.sink_m <= MAX_SINK and not r.ejected and r.contact_fraction > 0.95


@pytest.mark.parametrize("thickness", [0.0005, 0.01])
def test_plates_from_half_a_millimetre_to_a_centimetre_follow(thickness: float) -> None:
    r = drag_plate(thickness, 0.02, heading=math.pi / 2)
    assert abs(r.rest_gap_m) < 1e-4
    assert abs(r.lag_m) <= MAX_LAG and r.sink_m <= MAX_SINK and not r.ejected, r


def test_a_catalog_letter_is_dragged_too() -> None:
    """A concave plate (several convex pieces in one compound) behaves like the card."""
    r = drag_plate(0.004, 0.015, heading=math.pi / 2, plate=get_object("E"))
    assert abs(r.lag_m) <= MAX_LAG and r.sink_m <= MAX_SINK and not r.ejected, r
