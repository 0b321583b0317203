"""The agent's scene recognition: given shapes win over the catalog; tables match in height."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from agents.scene import SceneLibrary
from slide_gym.envs.observation import OBJECT_OUTLINE_POINTS, TABLE_OUTLINE_POINTS
from slide_gym.geometry import OBJECTS, TABLES


def test_a_given_shape_wins_over_the_catalog_outline_it_shares() -> None:
    card_e = dataclasses.replace(OBJECTS["E"], thickness=0.0008)
    lib = SceneLibrary(objects=[card_e])
    seen = lib.object_from(card_e.descriptor(OBJECT_OUTLINE_POINTS))
    assert seen.thickness == 0.0008
    assert SceneLibrary().object_from(card_e.descriptor(OBJECT_OUTLINE_POINTS)).thickness == 0.004


def test_tables_must_match_the_observed_height() -> None:
    raised = dataclasses.replace(TABLES["square"], height=0.05)
    outline = raised.descriptor(TABLE_OUTLINE_POINTS)
    assert SceneLibrary(tables=[raised]).table_from(outline, 0.05).height == 0.05
    assert SceneLibrary().table_from(outline, 0.0) is TABLES["square"]
    with pytest.warns(UserWarning, match="no known table"):
        observed = SceneLibrary().table_from(outline, np.float32(0.05))
    assert observed.height == pytest.approx(0.05)
