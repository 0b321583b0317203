"""Procedural plates: one plate per seed, in the stated ranges, usable in every env."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from shapely.ops import polylabel

import slide_gym  # noqa: F401 - registers the environments
from slide_gym.geometry import TABLES, diameter
from slide_gym.geometry.procedural import (
    MIN_INRADIUS,
    MIN_WIDTH,
    SIZE_RANGE,
    THICKNESS_RANGE,
    _box_sides,
    procedural_object,
)
from slide_gym.task import fit_procedural_object

PLATES = [procedural_object(seed) for seed in range(120)]


def test_the_same_seed_gives_the_same_plate() -> None:
    again = procedural_object(7)
    assert again.polygon.equals_exact(PLATES[7].polygon, 0.0)
    assert again.thickness == PLATES[7].thickness and again.name == "procedural-7"
    assert not PLATES[8].polygon.equals(PLATES[7].polygon)


def test_plates_stay_in_their_ranges_and_leave_room_for_a_fingertip() -> None:
    for plate in PLATES:
        assert plate.polygon.is_valid
        assert SIZE_RANGE[0] * 0.99 <= diameter(plate.polygon) <= SIZE_RANGE[1] * 1.1
        assert THICKNESS_RANGE[0] <= plate.thickness <= THICKNESS_RANGE[1]
        assert _box_sides(plate.polygon)[1] >= 0.99 * MIN_WIDTH
        disc = polylabel(plate.polygon, 1e-4).distance(plate.polygon.boundary)
        assert disc >= 0.99 * MIN_INRADIUS


def test_plates_vary_convex_concave_with_and_without_holes() -> None:
    holes = sum(bool(p.polygon.interiors) for p in PLATES)
    concave = sum(p.polygon.convex_hull.area - p.polygon.area > 1e-8 for p in PLATES)
    sizes = [diameter(p.polygon) for p in PLATES]
    assert 20 <= holes <= 70
    assert 40 <= concave <= len(PLATES) - 20
    assert min(sizes) < 0.06 and max(sizes) > 0.2


@pytest.mark.parametrize("seed", [-1, 1.5, True, "3"])
def test_bad_seed_is_a_value_error(seed: object) -> None:
    with pytest.raises(ValueError, match="seed"):
        procedural_object(seed)  # type: ignore[arg-type]


def test_large_plates_shrink_to_fit_the_narrow_table() -> None:
    big = next(s for s, p in enumerate(PLATES) if diameter(p.polygon) > 0.25)
    fitted = fit_procedural_object(big, TABLES["long"])
    assert diameter(fitted.polygon) <= diameter(PLATES[big].polygon)
    assert fitted.name == PLATES[big].name


def test_the_env_draws_the_plate_of_the_reset_seed() -> None:
    env = gym.make("SlideGym/TopSlide-v0", object="procedural", table="random")
    try:
        obs_a, info_a = env.reset(seed=11)
        obs_b, info_b = env.reset(seed=11)
        assert info_a["object"] == info_b["object"] == "procedural-11"
        np.testing.assert_array_equal(obs_a["object_outline"], obs_b["object_outline"])
        _, info_c = env.reset(seed=12)
        assert info_c["object"] == "procedural-12"
        _, info_d = env.reset()  # no seed: a plate drawn from the env's own generator
        assert info_d["object"].startswith("procedural-")
        for _ in range(5):
            obs, *_ = env.step(env.action_space.sample())
            assert env.observation_space.contains(obs)
    finally:
        env.close()
