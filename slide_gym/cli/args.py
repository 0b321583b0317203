"""Parsing, checking and formatting helpers shared by the subcommands."""

from __future__ import annotations

import argparse
import textwrap
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from slide_gym.geometry.shape_json import closest


class HelpFormatter(argparse.RawDescriptionHelpFormatter, argparse.ArgumentDefaultsHelpFormatter):
    """Help lines end with ``(default: ...)`` unless the default is None or False (their help
    says what happens instead) or the help already names it; the description and the
    ``Examples:`` epilog keep their line breaks."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        if action.default is None or action.default is False or "default:" in text:
            return text
        return super()._get_help_string(action)


def add_command(
    sub: Any,
    name: str,
    help: str,
    description: str,
    examples: Sequence[str],  # noqa: A002
) -> argparse.ArgumentParser:
    """A subcommand of ``sub`` whose help shows defaults and ends with ``examples``."""
    return sub.add_parser(
        name,
        help=help,
        description=textwrap.fill(description, width=79),
        epilog=examples_epilog(examples),
        formatter_class=HelpFormatter,
    )


def examples_epilog(examples: Sequence[str]) -> str:
    """The ``Examples:`` block that ends a help text."""
    return "Examples:\n" + "\n".join(f"  {line}" for line in examples)


def check_name(spec: str, kind: str, names: Sequence[str], extra: Sequence[str] = ()) -> str:
    """``spec`` if it is one of ``names`` or ``extra`` or a ``.json`` path (the loader checks
    the file); else a ValueError naming the closest name (``l`` -> ``L``) and every valid one.

    Checked before any work, so a typo never waits for an episode to start."""
    if spec in names or spec in extra or spec.lower().endswith(".json"):
        return spec
    choices = (*names, *extra)
    near = closest(spec, choices)
    hint = f"did you mean {near!r}? " if near is not None else ""
    raise ValueError(
        f"unknown {kind} {spec!r}; {hint}valid names: {', '.join(choices)} "
        "(or a path to a .json file)"
    )


def choice(choices: Sequence[str], what: str) -> Callable[[str], str]:
    """An argparse ``type`` that accepts one of ``choices`` and otherwise names the closest
    (use with ``choices=``, which lists them in the help)."""

    def parse(text: str) -> str:
        if text in choices:
            return text
        near = closest(text, choices)
        hint = f"did you mean {near!r}? " if near is not None else ""
        raise argparse.ArgumentTypeError(
            f"unknown {what} {text!r}; {hint}choose from {', '.join(choices)}"
        )

    parse.__name__ = what  # argparse names the type in some messages
    return parse


def add_choice(
    p: argparse.ArgumentParser,
    flag: str,
    choices: Sequence[str],
    what: str,
    help: str,  # noqa: A002 - argparse's name
    default: str | None = None,
    metavar: str | None = None,
) -> None:
    """An option (or positional) taking one of ``choices``, with :func:`choice`'s hint."""
    kwargs = {"default": default} if flag.startswith("-") else {}
    p.add_argument(
        flag, type=choice(choices, what), choices=choices, metavar=metavar, help=help, **kwargs
    )


def add_backend(p: argparse.ArgumentParser) -> None:
    """``--backend local|ray`` and ``--ray-address`` of the parallel jobs."""
    from slide_gym.bench.jobs import BACKENDS

    add_choice(
        p,
        "--backend",
        BACKENDS,
        "backend",
        "local: a process pool on this machine (--workers); ray: Ray tasks, one CPU each "
        "(the ray extra)",
        "local",
        "NAME",
    )
    p.add_argument(
        "--ray-address",
        metavar="ADDR",
        help="the Ray cluster to use with --backend ray (default: start a local Ray instance "
        "with --workers CPUs)",
    )


def add_only_success(p: argparse.ArgumentParser, note: str = "") -> None:
    """``--only-success`` (the default) / ``--no-only-success`` of the trainers."""
    p.add_argument(
        "--only-success",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="train only on the episodes the expert solved (the default: a failed or idle "
        "episode teaches the wrong moves); --no-only-success trains on every episode" + note,
    )


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


def fmt_pose(pose: Sequence[float] | None) -> str:
    """A planar pose ``(x, y, yaw)`` for plain text: metres and radians to 3 decimals."""
    if pose is None:
        return "n/a"
    x, y, yaw = (float(v) for v in pose)
    return f"(x {x:.3f} m, y {y:.3f} m, yaw {yaw:.3f} rad)"
