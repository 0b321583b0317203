"""Parsing and formatting helpers shared by the subcommands."""

from __future__ import annotations

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


def parse_names(text: str) -> list[str]:
    """A comma-separated list of names (empty items dropped)."""
    return [n for n in text.split(",") if n]


def or_na(value: Any, spec: str, suffix: str = "") -> str:
    """``value`` formatted with ``spec`` and ``suffix``, or ``"n/a"`` for None."""
    return "n/a" if value is None else f"{value:{spec}}{suffix}"
