"""Procedural plates: one plate per seed, in the stated ranges, usable in every env."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from shapely.ops import polylabel

import slide_gym  # noqa: F401 - registers the environments
from slide_gym.geometry import TABLES, diameter, get_object, overhang, transform_polygon
from slide_gym.geometry.procedural import (
    MIN_INRADIUS,
    MIN_WIDTH,
    SIZE_RANGE,
    THICKNESS_RANGE,
    _box_sides,
    procedural_object,
)
from slide_gym.task import (
    ADMISSIBLE_CENTROID_MARGIN,
    TaskParams,
    draw_procedural_plate,
    fit_procedural_object,
    plate_admissible,
    scene_object,
)

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


def _overhang_with_farthest_point_out(plate, table, margin: float):
    """The plate on ``table`` with its farthest vertex pointing straight out of the square
    table's +x edge and its centroid ``margin`` inside: the best overhang it can reach."""
    ring = np.asarray(plate.polygon.exterior.coords)
    far = ring[int(np.argmax(np.linalg.norm(ring, axis=1)))]
    yaw = -np.arctan2(far[1], far[0])  # turn the farthest vertex onto +x
    edge_x = table.polygon.bounds[2]
    placed = transform_polygon(plate.polygon, edge_x - margin, 0.0, yaw)
    return overhang(placed, table.polygon)


def test_a_plate_that_cannot_overhang_u_star_is_redrawn_from_its_seed() -> None:
    first = procedural_object(3)  # 4.4 cm across: its farthest point is 2.2 cm out
    assert not plate_admissible(first)
    drawn = draw_procedural_plate(3, TABLES["square"])
    assert drawn.redraws == 1 and plate_admissible(drawn.shape)
    assert drawn.shape.name == "procedural-3"
    assert drawn.shape.polygon.equals_exact(procedural_object(3, 1).polygon, 0.0)
    assert not drawn.shape.polygon.equals(first.polygon)
    # an admissible first draw is kept as it was
    kept = draw_procedural_plate(7, TABLES["square"])
    assert kept.redraws == 0 and kept.shape.polygon.equals_exact(PLATES[7].polygon, 0.0)


def test_the_redrawn_plate_of_a_seed_is_always_the_same() -> None:
    a, b = (draw_procedural_plate(37, TABLES["round"]) for _ in range(2))
    assert a.redraws == b.redraws == 2  # seed 37 needs two redraws
    assert a.shape.polygon.equals_exact(b.shape.polygon, 0.0)
    assert a.shape.thickness == b.shape.thickness
    again = fit_procedural_object(37, TABLES["square"])  # small: the table does not matter
    assert again.polygon.equals_exact(a.shape.polygon, 0.0)


@pytest.mark.parametrize("table", ["square", "round", "long", "triangle"])
def test_every_plate_of_seeds_0_to_49_is_admissible(table: str) -> None:
    u_star = TaskParams.u_star
    for seed in range(50):
        plate = fit_procedural_object(seed, TABLES[table])
        assert plate_admissible(plate), plate.name
        # checked by the overhang itself, not only by the circumradius
        over = _overhang_with_farthest_point_out(
            plate, TABLES["square"], ADMISSIBLE_CENTROID_MARGIN
        )
        assert over.graspable(u_star - 1e-9), (plate.name, over.u)


def test_an_inadmissible_plate_does_reach_less_than_u_star() -> None:
    first = procedural_object(3)
    over = _overhang_with_farthest_point_out(first, TABLES["square"], ADMISSIBLE_CENTROID_MARGIN)
    assert over.u < TaskParams.u_star


def test_half_scale_plates_are_admissible_after_scaling() -> None:
    for seed in range(10):
        drawn = draw_procedural_plate(seed, TABLES["square"], 0.5)
        assert plate_admissible(drawn.shape)
        unscaled = procedural_object(seed, drawn.redraws)
        assert diameter(drawn.shape.polygon) == pytest.approx(0.5 * diameter(unscaled.polygon))


@pytest.mark.parametrize("scale", [0.0, -1.0, float("nan"), True])
def test_a_bad_scale_is_a_value_error(scale: float) -> None:
    with pytest.raises(ValueError, match="scale must be a positive number"):
        draw_procedural_plate(0, TABLES["square"], scale)


def test_no_admissible_draw_at_a_tiny_scale_is_a_value_error() -> None:
    with pytest.raises(ValueError, match="none of 100 draws at scale 0.07"):
        draw_procedural_plate(0, TABLES["square"], 0.07)


def test_user_plates_are_never_redrawn() -> None:
    small = scene_object("circle", TABLES["square"], scale=0.4)  # 4 cm across: 2 cm out
    assert not plate_admissible(small)
    assert small.name == "circle"
    assert small.polygon.equals_exact(get_object("circle", 0.4).polygon, 0.0)
