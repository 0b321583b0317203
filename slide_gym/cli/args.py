"""Parsing and formatting helpers shared by the subcommands."""

from __future__ import annotations

from pathlib import Path
from typing import Any


def parse_floats(text: str, n: int, what: str) -> tuple[float, ...]:
    """``n`` comma-separated numbers, or a ValueError naming the option ``what``."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != n:
        raise ValueError(f"{what} must be {n} comma-separated numbers, got {text!r}")
    return values


def check_seed(seed: int, what: str = "--seed") -> int:
    """``seed`` if it is a non-negative integer (what Gymnasium and NumPy accept)."""
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"{what} must be a non-negative integer, got {seed!r}")
    return seed


def check_output(path: Path, suffixes: tuple[str, ...], what: str) -> Path:
    """``path`` if it ends in one of ``suffixes`` and its folder exists (checked before any
    work, so a long run never ends on an unwritable path)."""
    if path.suffix.lower() not in suffixes:
        raise ValueError(f"{what} must end in {' or '.join(suffixes)}, got {str(path)!r}")
    folder = path.parent
    if not folder.is_dir():
        raise ValueError(f"{what}: folder {str(folder)!r} does not exist (for {str(path)!r})")
    if path.is_dir():
        raise ValueError(f"{what}: {str(path)!r} is a folder, not a file name")
    return path


def parse_names(text: str) -> list[str]:
    """A comma-separated list of names (empty items dropped)."""
    return [n for n in text.split(",") if n]


def or_na(value: Any, spec: str, suffix: str = "") -> str:
    """``value`` formatted with ``spec`` and ``suffix``, or ``"n/a"`` for None."""
    return "n/a" if value is None else f"{value:{spec}}{suffix}"
