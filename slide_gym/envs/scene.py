"""What an episode's scene is drawn from, and the per-reset options that change it.

:class:`SceneChoice` holds the environment's object and table specifications (a catalog name,
a JSON path, a shape, ``"random"``, or for objects ``"procedural"``), the object scale and an
optional thickness. :meth:`SceneChoice.with_options` applies ``reset(options=...)``;
:meth:`SceneChoice.draw` picks the episode's object and table.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from slide_gym.geometry import (
    OBJECT_NAMES,
    TABLE_NAMES,
    ObjectShape,
    TableShape,
    get_object,
    get_table,
)
from slide_gym.geometry.catalog import unknown_name
from slide_gym.geometry.shapes import check_thickness
from slide_gym.task import PROCEDURAL, RANDOM, check_scene, fit_procedural_object

RESET_OPTIONS = (
    "object",
    "table",
    "scale",
    "thickness",
    "object_pose",
    "arm_qpos",
    "randomization",
)
"""Keys ``reset(options=...)`` accepts."""


@dataclasses.dataclass(frozen=True)
class SceneChoice:
    """The object and table an episode draws from (validated on construction).

    Every object a ``"random"`` spec can give is checked against every table it can meet,
    so a bad combination fails here, not in some later episode.
    """

    object: str | ObjectShape
    table: str | TableShape
    scale: float = 1.0
    thickness: float | None = None

    def __post_init__(self) -> None:
        if isinstance(self.scale, bool) or not (
            isinstance(self.scale, (int, float)) and math.isfinite(self.scale) and self.scale > 0
        ):
            raise ValueError(f"scale must be a positive number, got {self.scale!r}")
        _check("object", self.object)
        _check("table", self.table)
        if self.thickness is not None:
            check_thickness(self.thickness)
        objects = _candidates(self.object, OBJECT_NAMES, self._load_object)  # thickness too
        for table in _candidates(self.table, TABLE_NAMES, get_table):
            for obj in objects:
                check_scene(obj, table)

    def _load_object(self, spec: str | ObjectShape) -> ObjectShape:
        return _thick(get_object(spec, self.scale), self.thickness)

    def with_options(self, options: dict[str, Any]) -> SceneChoice:
        """This choice with the ``object``, ``table``, ``scale`` and ``thickness`` options of a
        reset applied (the others stay); itself if there are none."""
        changes = {k: options[k] for k in ("object", "table", "scale", "thickness") if k in options}
        return dataclasses.replace(self, **changes) if changes else self

    def draw(self, rng: np.random.Generator, seed: int | None, margin: float) -> tuple[Any, Any]:
        """The episode's ``(object, table)``: ``"random"`` draws a catalog shape from ``rng``
        (the table first); ``"procedural"`` is the plate of ``seed`` (or of a seed drawn from
        ``rng``), fitted to the table and admissible
        (:func:`~slide_gym.task.fit_procedural_object`)."""
        table = _pick(self.table, TABLE_NAMES, get_table, rng)
        if self.object == PROCEDURAL:
            plate_seed = seed if seed is not None else int(rng.integers(2**31))
            plate = fit_procedural_object(plate_seed, table, self.scale, margin)
            obj = _thick(plate, self.thickness)
        else:
            obj = _pick(self.object, OBJECT_NAMES, self._load_object, rng)
        check_scene(obj, table)
        return obj, table


def scene_names(kind: str) -> tuple[str, ...]:
    """Every name the env takes for ``kind`` (``"object"`` or ``"table"``): the catalog's,
    ``"random"`` and, for objects, ``"procedural"``."""
    if kind == "object":
        return (*OBJECT_NAMES, RANDOM, PROCEDURAL)
    return (*TABLE_NAMES, RANDOM)


def _check(kind: str, spec: Any) -> None:
    """ValueError unless ``spec`` is one of :func:`scene_names` or a path or shape that loads
    (the shapes themselves are loaded per episode, at the scale then)."""
    names = scene_names(kind)
    if spec is None:
        raise ValueError(f"{kind} must be one of {', '.join(names)} or a .json path")
    if isinstance(spec, str) and spec in names and spec in (RANDOM, PROCEDURAL):
        return  # drawn per episode
    if isinstance(spec, str) and spec not in names and not spec.lower().endswith(".json"):
        raise unknown_name(kind, spec, names)
    get_object(spec) if kind == "object" else get_table(spec)


def _thick(obj: ObjectShape, thickness: float | None) -> ObjectShape:
    return obj if thickness is None else dataclasses.replace(obj, thickness=thickness)


def _candidates(spec: Any, names: tuple[str, ...], load: Any) -> list[Any]:
    if isinstance(spec, str) and spec == PROCEDURAL:
        return []  # drawn per episode, shrunk to fit the table
    if isinstance(spec, str) and spec == RANDOM:
        return [load(n) for n in names]
    return [load(spec)]


def _pick(spec: Any, names: tuple[str, ...], load: Any, rng: np.random.Generator) -> Any:
    if isinstance(spec, str) and spec == RANDOM:
        return load(names[int(rng.integers(len(names)))])
    return load(spec)
