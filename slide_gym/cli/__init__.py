"""The ``slide-gym`` command. Bad input prints one line to stderr and exits with code 2.

Each group of subcommands registers itself from its own module (:mod:`.commands`,
:mod:`.bench`, :mod:`.experiment`, :mod:`.data`); the heavy imports happen inside the
handlers, so ``--help`` stays fast.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from slide_gym import __version__
from slide_gym.cli import bench, commands, data, experiment, learn
from slide_gym.cli.args import HelpFormatter, Parser, check_seed, examples_epilog

EXAMPLES = (
    "slide-gym shapes",
    "slide-gym run --object E --table square --seed 0 --video expert.gif",
    "slide-gym plan --object L --table round --json",
    "slide-gym run --help   (each command's options, units and defaults)",
)


def build_parser() -> argparse.ArgumentParser:
    """The ``slide-gym`` argument parser with every subcommand."""
    parser = Parser(
        prog="slide-gym",
        description="Pre-grasp top-sliding of thin objects: tools.\nEvery command's --help "
        "lists its options with their units and defaults.",
        epilog=examples_epilog(EXAMPLES),
        formatter_class=HelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"slide-gym {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    commands.add_parsers(sub)
    bench.add_parsers(sub)
    experiment.add_parsers(sub)
    data.add_parsers(sub)
    learn.add_parsers(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        if getattr(args, "seed", None) is not None:  # every subcommand's --seed
            check_seed(args.seed)
        return int(args.func(args))
    except ValueError as err:
        command = " ".join(c for c in (args.command, getattr(args, "what", None)) if c)
        message = " ".join(str(err).split())  # always one line
        print(f"slide-gym {command}: error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
