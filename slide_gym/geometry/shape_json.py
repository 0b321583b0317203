"""Object and table JSON files: the keys they may hold and the loaders (see
:mod:`slide_gym.geometry.shapes` for the format and the bounds). An unknown key is an error
that names the closest valid one."""

from __future__ import annotations

import difflib
import json
from pathlib import Path
from typing import Any

from slide_gym.geometry.shapes import (
    DEFAULT_DENSITY,
    DEFAULT_SLAB_THICKNESS,
    DEFAULT_THICKNESS,
    ObjectShape,
    TableShape,
)

OBJECT_KEYS: tuple[str, ...] = ("name", "vertices", "holes", "thickness", "density")
"""Keys of an object JSON file ("name" and "vertices" required)."""
TABLE_KEYS: tuple[str, ...] = ("name", "vertices", "height", "slab_thickness")
"""Keys of a table JSON file ("name", "vertices" and "height" required)."""


def closest(word: str, choices: tuple[str, ...] | list[str]) -> str | None:
    """The choice most like ``word`` (case-insensitive, difflib; else the one choice that
    starts with it, like "slab" for "slab_thickness"), or None if none is close."""
    lowered = {c.lower(): c for c in choices}
    word = str(word).lower()
    match = difflib.get_close_matches(word, list(lowered), n=1, cutoff=0.6)
    if not match and len(word) >= 3:
        match = [c for c in lowered if c.startswith(word)]
    return lowered[match[0]] if len(match) == 1 else None


def _read_json(
    path: str | Path, required: tuple[str, ...], kind: str
) -> tuple[Path, dict[str, Any]]:
    """Read a JSON object with the required keys and no unknown ones; ValueError naming the
    file (and the closest valid key) otherwise."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise ValueError(f"{path}: file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot read file ({exc})") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a JSON object {{...}}, got {type(data).__name__}")
    allowed, other = (OBJECT_KEYS, TABLE_KEYS) if kind == "object" else (TABLE_KEYS, OBJECT_KEYS)
    for key in data:
        if key in allowed:
            continue
        near = closest(key, allowed)
        if near is not None:
            hint = f"did you mean {near!r}? "
        elif key in other:
            hint = f"{key!r} belongs in {'a table' if kind == 'object' else 'an object'} file; "
        else:
            hint = ""
        raise ValueError(
            f"{path}: unknown key {key!r} in {kind} file; {hint}valid keys: {', '.join(allowed)}"
        )
    missing = [k for k in required if k not in data]
    if missing:
        raise ValueError(f"{path}: missing key(s) {missing}; required keys are {list(required)}")
    if not isinstance(data["name"], str):
        raise ValueError(f"{path}: 'name' must be a string, got {data['name']!r}")
    if not isinstance(data["vertices"], list):
        raise ValueError(f"{path}: 'vertices' must be a list of [x, y] pairs")
    return path, data


def _wrap(path: Path, build: Any) -> Any:
    """Run ``build()`` and prefix any ValueError with the file name."""
    try:
        return build()
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def load_object_json(path: str | Path) -> ObjectShape:
    """Load an object from JSON (see module docstring); vertices are recentred."""
    path, data = _read_json(path, ("name", "vertices"), "object")
    holes = data.get("holes", [])
    if not isinstance(holes, list):
        raise ValueError(f"{path}: 'holes' must be a list of vertex lists")
    return _wrap(
        path,
        lambda: ObjectShape.from_vertices(
            data["name"],
            data["vertices"],
            holes,
            data.get("thickness", DEFAULT_THICKNESS),
            data.get("density", DEFAULT_DENSITY),
        ),
    )


def load_table_json(path: str | Path) -> TableShape:
    """Load a table from JSON (see module docstring)."""
    path, data = _read_json(path, ("name", "vertices", "height"), "table")
    return _wrap(
        path,
        lambda: TableShape.from_vertices(
            data["name"],
            data["vertices"],
            data["height"],
            data.get("slab_thickness", DEFAULT_SLAB_THICKNESS),
        ),
    )
