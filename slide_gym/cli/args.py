"""Parsing, checking and formatting helpers shared by the subcommands."""

from __future__ import annotations

import argparse
import contextlib
import json
import re
import sys
import textwrap
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any, NoReturn

from slide_gym.geometry.catalog import unknown_name
from slide_gym.geometry.shape_json import closest


class Parser(argparse.ArgumentParser):
    """argparse's parser that names the closest option of a misspelt one (``--objct``:
    "did you mean --object?"), in the error of the subcommand it was given to, and reports a
    usage error on one line (no usage block; ``--help`` shows it) with exit status 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")

    def parse_args(  # type: ignore[override]
        self, args: Sequence[str] | None = None, namespace: Any = None
    ) -> Any:
        parsed, extras = self.parse_known_args(args, namespace)
        if extras:
            leaf = _subcommand(self, parsed)
            leaf.error(f"unrecognized arguments: {' '.join(extras)}{_option_hint(leaf, extras)}")
        return parsed


def _subcommand(parser: argparse.ArgumentParser, args: Any) -> argparse.ArgumentParser:
    """The innermost (sub)parser that ``args`` went through."""
    for action in parser._actions:  # noqa: SLF001 - argparse keeps its actions here
        if isinstance(action, argparse._SubParsersAction):  # noqa: SLF001
            name = getattr(args, action.dest, None)
            if name in action.choices:
                return _subcommand(action.choices[name], args)
    return parser


def _option_hint(parser: argparse.ArgumentParser, extras: Sequence[str]) -> str:
    """``"; did you mean --object?"`` for the unknown options in ``extras`` near a known one."""
    options = [s for a in parser._actions for s in a.option_strings]  # noqa: SLF001
    pairs = []
    for word in extras:
        flag = word.split("=", 1)[0]
        near = closest(flag, options) if flag.startswith("-") else None
        if near is not None:
            pairs.append((flag, near))
    if not pairs:
        return ""
    if len(pairs) == 1:
        return f"; did you mean {pairs[0][1]}?"
    return "; did you mean " + ", ".join(f"{near} for {flag}" for flag, near in pairs) + "?"


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
    raise unknown_name(kind, spec, (*names, *extra))


def choice(
    choices: Sequence[str], what: str, refused: Mapping[str, str] | None = None
) -> Callable[[str], str]:
    """An argparse ``type`` that accepts one of ``choices`` and otherwise names the closest
    (use with ``choices=``, which lists them in the help); a name in ``refused`` gets its
    message there instead (a known name the command cannot take, and why)."""

    def parse(text: str) -> str:
        if text in choices:
            return text
        if refused and text in refused:
            raise argparse.ArgumentTypeError(refused[text])
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
    refused: Mapping[str, str] | None = None,
) -> None:
    """An option (or positional) taking one of ``choices``, with :func:`choice`'s hint."""
    kwargs = {"default": default} if flag.startswith("-") else {}
    kind = choice(choices, what, refused)
    p.add_argument(flag, type=kind, choices=choices, metavar=metavar, help=help, **kwargs)


def add_env(p: argparse.ArgumentParser, command: str, help: str, default: str) -> None:  # noqa: A002
    """``--env ID``: one of the envs with the state ``Dict`` observation; a registered env
    the command cannot drive (the goal env) is named as such, not mistaken for a typo."""
    from slide_gym import DICT_ENV_IDS, ENV_IDS

    drives = ", ".join(DICT_ENV_IDS)
    refused = {
        env: f"slide-gym {command} cannot drive {env}: its observation is not the state Dict "
        f"that the expert and the policies read (it is the goal-conditioned slide, for HER); "
        f"it drives {drives}"
        for env in ENV_IDS
        if env not in DICT_ENV_IDS
    }
    add_choice(p, "--env", DICT_ENV_IDS, "env", help, default, "ID", refused)


_ANSI_COLOUR = re.compile(r"\x1b\[[0-9;]*m")


@contextlib.contextmanager
def one_line_warnings(command: str) -> Iterator[None]:
    """Within: each warning prints as one line ``slide-gym COMMAND: warning: ...`` on stderr
    (not Python's two lines with a file name; without the terminal colours gymnasium adds)."""

    def show(message: Any, *args: Any, **kwargs: Any) -> None:
        text = " ".join(_ANSI_COLOUR.sub("", str(message)).split())
        print(f"slide-gym {command}: warning: {text}", file=sys.stderr)

    with warnings.catch_warnings():
        warnings.showwarning = show
        yield


def add_backend(p: argparse.ArgumentParser) -> None:
    """``--backend local|ray`` and ``--ray-address`` of the parallel jobs."""
    from slide_gym.jobs import BACKENDS

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


def add_randomization(p: argparse.ArgumentParser) -> None:
    """``--randomization default|JSON``: the env's domain randomisation (see
    :func:`parse_randomization`)."""
    p.add_argument(
        "--randomization",
        metavar="default|JSON",
        help="domain randomisation per episode, drawn from the reset seed: 'default' (ranges "
        "the expert solves) or a JSON object of key: [low, high] or key: value, keys "
        "plate_table_friction, pad_friction, plate_density (kg/m^3), plate_thickness (m), "
        "table_height (m), finger_stiffness (N m/rad) (default: none, the fixed world)",
    )


def add_physics(p: argparse.ArgumentParser) -> None:
    """``--physics NAME=VALUE`` (repeatable): the env's physics settings."""
    p.add_argument(
        "--physics",
        action="append",
        metavar="NAME=VALUE",
        help="override one of the env's physics settings (slide_gym.sim.PhysicsParams other "
        "than timestep), e.g. friction_anchor=1: the robot's contacts keep their friction "
        "anchors; repeatable (default: none)",
    )


def parse_physics(items: list[str] | None) -> dict[str, Any] | None:
    """The value of ``--physics``: None, or checked settings in JSON's own form."""
    from slide_gym.sim import physics_overrides

    return physics_overrides(parse_assignments(items, "--physics"))


def parse_randomization(text: str | None) -> str | dict[str, Any] | None:
    """The value of ``--randomization``: None, ``"default"`` or a checked JSON object."""
    from slide_gym.envs.randomization import DEFAULT, parse

    if text is None or text == DEFAULT:
        return text
    try:
        spec = json.loads(text)
    except json.JSONDecodeError:
        spec = text  # parse() says what is allowed
    parse(spec, "--randomization")
    return spec


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


def parse_assignments(items: list[str] | None, option: str) -> dict[str, float] | None:
    """Repeated ``OPTION NAME=NUMBER`` values as a dict (None if there are none); the names
    are checked by whoever takes them."""
    if not items:
        return None
    out: dict[str, float] = {}
    for item in items:
        name, sep, value = item.partition("=")
        try:
            if not sep:
                raise ValueError
            out[name.strip()] = float(value)
        except ValueError:
            raise ValueError(f"{option} takes NAME=NUMBER, got {item!r}") from None
    return out
