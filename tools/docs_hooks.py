"""MkDocs hooks for the documentation site (``hooks:`` in mkdocs.yml).

- ``<!-- slide-gym help -->`` in a page becomes the ``--help`` text of every ``slide-gym``
  command, generated from the argparse parsers (:func:`slide_gym.cli.build_parser`), so the
  Command line page cannot drift from the code.
- The build warns (and so ``mkdocs build --strict`` fails) when a module of ``slide_gym`` or
  ``agents`` is missing from the API reference (``::: module`` in ``docs/reference/``).
"""

from __future__ import annotations

import argparse
import logging
import os
import re
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
HELP_MARKER = "<!-- slide-gym help -->"
HELP_WIDTH = "88"
REFERENCE = ROOT / "docs" / "reference"
PACKAGES = ("slide_gym", "agents")

log = logging.getLogger("mkdocs.hooks.slide_gym")


def _subcommands(
    parser: argparse.ArgumentParser, prefix: tuple[str, ...]
) -> Iterator[tuple[tuple[str, ...], argparse.ArgumentParser]]:
    yield prefix, parser
    for action in parser._actions:  # argparse keeps subparsers only here
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _subcommands(sub, (*prefix, name))


def cli_help_markdown() -> str:
    """A section with the ``--help`` text of every command and subcommand."""
    if str(ROOT) not in sys.path:  # the checkout's code, also when run as the `mkdocs` script
        sys.path.insert(0, str(ROOT))
    from slide_gym.cli import build_parser

    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = HELP_WIDTH  # argparse wraps to the terminal's width
    try:
        sections = []
        for path, parser in _subcommands(build_parser(), ("slide-gym",)):
            title = " ".join(path)
            sections.append(f"### `{title}`\n\n```text\n{parser.format_help().rstrip()}\n```\n")
    finally:
        if old is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = old
    return "\n".join(sections)


def on_page_markdown(markdown: str, **kwargs: Any) -> str:
    if HELP_MARKER in markdown:
        markdown = markdown.replace(HELP_MARKER, cli_help_markdown())
    return markdown


def modules() -> list[str]:
    """Every module of :data:`PACKAGES` (``__main__`` aside)."""
    names = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            if parts[-1] == "__main__":
                continue
            names.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return names


def on_pre_build(config: Any, **kwargs: Any) -> None:
    shown = set()
    for page in REFERENCE.glob("*.md"):
        shown |= set(re.findall(r"^::: ([\w.]+)", page.read_text(), flags=re.MULTILINE))
    for name in modules():
        if name not in shown:
            log.warning(f"module {name} is not in the API reference (docs/reference/*.md)")
