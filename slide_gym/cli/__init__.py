"""The ``slide-gym`` command. Bad input prints one line to stderr and exits with code 2.

Each group of subcommands registers itself from its own module (:mod:`.commands`,
:mod:`.bench`); the heavy imports happen inside the handlers, so ``--help`` stays fast.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from slide_gym.cli import bench, commands


def build_parser() -> argparse.ArgumentParser:
    """The ``slide-gym`` argument parser with every subcommand."""
    parser = argparse.ArgumentParser(
        prog="slide-gym", description="Pre-grasp top-sliding of thin objects: tools."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    commands.add_parsers(sub)
    bench.add_parsers(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except ValueError as err:
        command = " ".join(c for c in (args.command, getattr(args, "what", None)) if c)
        print(f"slide-gym {command}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130

