"""Domain randomisation: per-episode physics and scene parameters drawn from the reset seed.

``TopSlideEnv(randomization=...)`` takes ``None`` (nothing drawn: the fixed world),
``"default"`` (:data:`DEFAULT_RANGES`, ranges the expert still solves) or a dict that maps
keys of :data:`PARAMETERS` to a ``(low, high)`` range (drawn uniformly) or to one number (that
exact value). ``reset(options={"randomization": {...}})`` takes the same forms for one
episode, over the env's own (keys it names replace the env's; the others stay).

Draws come from a generator seeded with the reset's seed (:func:`episode_rng`), apart from
the env's ``np_random``: a seed gives the same scene and start pose with or without
randomisation, and each parameter the same uniform variate whatever the other keys are.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from slide_gym.geometry.shape_json import closest
from slide_gym.geometry.shapes import (
    MAX_THICKNESS,
    MIN_THICKNESS,
    TABLE_HEIGHT_RANGE,
    ObjectShape,
    TableShape,
)
from slide_gym.robot.model import HandParams
from slide_gym.robot.wam_t42 import WamT42
from slide_gym.sim import Simulation

DEFAULT = "default"
"""The name of :data:`DEFAULT_RANGES` where a spec is given."""
STREAM = 0xD0A1
"""Mixed with the reset seed into the seed of the randomisation generator."""


@dataclass(frozen=True)
class Parameter:
    """One randomisable quantity: its allowed values and its ``"default"`` range."""

    name: str
    unit: str
    bounds: tuple[float, float]
    default: tuple[float, float]
    meaning: str


PARAMETERS: tuple[Parameter, ...] = (
    Parameter(
        "plate_table_friction",
        "",
        (0.01, 2.0),
        (0.24, 0.40),
        "friction coefficient of the plate on the table (PyBullet uses the product of the "
        "two bodies' coefficients; 0.32 without randomisation); the table's own coefficient "
        "is set to this over the plate's",
    ),
    Parameter(
        "pad_friction",
        "",
        (0.05, 3.0),
        (0.8, 1.2),
        "friction coefficient of the finger pads on the plate (1.0 without randomisation); "
        "every finger link's coefficient is set to this over the plate's",
    ),
    Parameter(
        "plate_density",
        "kg/m^3",
        (100.0, 10000.0),
        (800.0, 1600.0),
        "plate density (the plate's own without randomisation, 1200 for the catalog)",
    ),
    Parameter(
        "plate_thickness",
        "m",
        (MIN_THICKNESS, MAX_THICKNESS),
        (0.003, 0.005),
        "plate thickness (the plate's own without randomisation, 4 mm for the catalog)",
    ),
    Parameter(
        "table_height",
        "m",
        TABLE_HEIGHT_RANGE,
        (-0.05, 0.03),
        "world z of the table top (the table's own without randomisation, 0 for the catalog)",
    ),
    Parameter(
        "finger_stiffness",
        "N m/rad",
        (0.3, 6.0),
        (0.9, 1.5),
        "stiffness of the proximal finger springs (1.2 without randomisation); the distal "
        "springs keep twice it",
    ),
)
KEYS: tuple[str, ...] = tuple(p.name for p in PARAMETERS)
"""The randomisable keys, in the order their variates are drawn."""
DEFAULT_RANGES: dict[str, tuple[float, float]] = {p.name: p.default for p in PARAMETERS}
"""``randomization="default"``: every key over its range that the expert still solves."""

Ranges = dict[str, tuple[float, float]]


def parse(spec: Any, what: str = "randomization") -> Ranges:
    """``spec`` (None, ``"default"``, or a dict of key -> number or (low, high)) as key ->
    (low, high), an exact value as (v, v); a ValueError naming the key and what it allows."""
    if spec is None:
        return {}
    if isinstance(spec, str) and spec == DEFAULT:
        return dict(DEFAULT_RANGES)
    if not isinstance(spec, Mapping):
        raise ValueError(
            f"{what} must be None, {DEFAULT!r} or a dict of key -> number or (low, high) "
            f"with keys {', '.join(KEYS)}; got {spec!r}"
        )
    params = {p.name: p for p in PARAMETERS}
    ranges: Ranges = {}
    for key, value in spec.items():
        if key not in params:
            near = closest(str(key), KEYS)
            hint = f"did you mean {near!r}? " if near is not None else ""
            raise ValueError(f"unknown {what} key {key!r}; {hint}allowed: {', '.join(KEYS)}")
        ranges[key] = _range(params[key], value, f"{what}[{key!r}]")
    return {k: ranges[k] for k in KEYS if k in ranges}


def _range(p: Parameter, value: Any, what: str) -> tuple[float, float]:
    """``value`` (a number or a (low, high) pair) as a checked (low, high)."""
    if _is_number(value):
        low = high = float(value)
    elif (
        isinstance(value, (list, tuple, np.ndarray))
        and len(value) == 2
        and all(_is_number(v) for v in value)
    ):
        low, high = float(value[0]), float(value[1])
    else:
        raise ValueError(f"{what} must be a number or a (low, high) pair of numbers, got {value!r}")
    if not (math.isfinite(low) and math.isfinite(high)):
        raise ValueError(f"{what} must be finite, got {value!r}")
    if low > high:
        raise ValueError(f"{what}: low {low:g} is above high {high:g}; give (low, high)")
    lo, hi = p.bounds
    if low < lo or high > hi:
        unit = f" {p.unit}" if p.unit else ""
        raise ValueError(f"{what} = {value!r} is outside the allowed [{lo:g}, {hi:g}]{unit}")
    return low, high


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
        value, (bool, np.bool_)
    )


def episode_rng(seed: int) -> np.random.Generator:
    """The randomisation generator of reset seed ``seed`` (not the env's ``np_random``)."""
    return np.random.default_rng([int(seed), STREAM])


def draw(ranges: Ranges, rng: np.random.Generator) -> dict[str, float]:
    """One value per key of ``ranges``: ``low + U (high - low)``, with one variate ``U`` per
    key of :data:`KEYS` drawn every time (so a key's value does not depend on the others)."""
    u = rng.random(len(KEYS))
    return {
        k: float(ranges[k][0] + u[i] * (ranges[k][1] - ranges[k][0]))
        for i, k in enumerate(KEYS)
        if k in ranges
    }


def to_json(ranges: Ranges) -> dict[str, list[float]]:
    """``ranges`` as JSON values (dataset metadata)."""
    return {k: [float(lo), float(hi)] for k, (lo, hi) in ranges.items()}


def apply_to_scene(
    values: Mapping[str, float], obj: ObjectShape, table: TableShape
) -> tuple[ObjectShape, TableShape]:
    """The episode's plate and table with the drawn thickness, density and table height."""
    fields = (("thickness", "plate_thickness"), ("density", "plate_density"))
    changes = {field: values[key] for field, key in fields if key in values}
    if changes:
        obj = dataclasses.replace(obj, **changes)
    if "table_height" in values:
        table = dataclasses.replace(table, height=values["table_height"])
    return obj, table


def apply_to_world(
    values: Mapping[str, float], sim: Simulation, robot: WamT42, plate_friction: float
) -> None:
    """Set the drawn pair frictions in the built world: PyBullet multiplies the two bodies'
    coefficients, so the table's and each finger link's become the pair's over the plate's
    ``plate_friction``."""
    c = sim.client
    if "plate_table_friction" in values:
        table = sim.body("table")
        c.changeDynamics(table, -1, lateralFriction=values["plate_table_friction"] / plate_friction)
    if "pad_friction" in values:
        pad = values["pad_friction"] / plate_friction
        for link in (*robot.finger_a_links, *robot.finger_b_links):
            c.changeDynamics(robot.body, link, lateralFriction=pad)


def hand_params(values: Mapping[str, float], hand: HandParams) -> HandParams:
    """``hand`` with the drawn finger stiffness (itself if none was drawn)."""
    if "finger_stiffness" not in values:
        return hand
    return dataclasses.replace(hand, k_proximal=values["finger_stiffness"])
