"""A pull-back keeps a small plate graspable: it drags the plate past the centroid margin it
restores only as far as the overhang stays above the grasp threshold."""

from __future__ import annotations

import dataclasses
import re

from agents.episode import run_episode
from agents.params import ExpertParams


def test_a_half_scale_circle_pulled_back_stays_graspable():
    """Round table, seed 3: the slide left the centroid 1 mm past the edge. Pulled back with
    the whole 5 mm of slack the circle landed at 1.7 cm of overhang, under its 1.75 cm
    threshold, and was slid again twice to the same end (in v0's physics and with the 0.3 s
    press hold, where it was found: at the shorter default hold the same seed's slide ends
    elsewhere, its pull-back lands the circle at 1.6 cm, and it is slid again once and
    lifted)."""
    params = dataclasses.replace(ExpertParams(), press_hold_s=0.3)
    record = run_episode(
        "circle", "round", scale=0.5, seed=3, env_id="SlideGym/TopSlideGrasp-v0", params=params
    )
    events = record.expert.events
    assert any("pulled back" in e for e in events)
    slid = [float(m.group(1)) for e in events if (m := re.search(r"slid: overhang ([\d.]+)", e))]
    assert slid and slid[0] >= ExpertParams().pinch_u_star
    assert record.success
