"""The documentation's build helpers: Sphinx roles become links, the command line's help is
generated for every command, and the README stays a short landing page."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _load(name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(name, ROOT / "tools" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_sphinx_roles_become_links_and_private_or_outside_names_stay_code() -> None:
    pytest.importorskip("griffe")
    convert = _load("docs_sphinx_roles").convert_roles
    assert convert(":class:`~slide_gym.task.TaskParams`") == (
        "[`TaskParams`][slide_gym.task.TaskParams]"
    )
    assert convert("see :func:`plan_once` and :mod:`.commands`") == (
        "see [`plan_once`][plan_once] and [`commands`][.commands]"
    )
    assert convert(":meth:`_initial_roots`") == "`_initial_roots`"
    assert convert(":class:`shapely.Polygon`") == "`shapely.Polygon`"
    assert convert("no roles here") == "no roles here"


def test_cli_help_covers_every_command() -> None:
    text = _load("docs_hooks").cli_help_markdown()
    for command in ("run", "plan", "collect", "train-dp", "dagger", "bench execute", "report"):
        assert f"### `slide-gym {command}`" in text
    assert text.count("usage: slide-gym") == text.count("### `slide-gym")


def test_every_module_is_named_by_the_hook() -> None:
    names = _load("docs_hooks").modules()
    assert "slide_gym.envs.top_slide" in names and "agents.learned.policy" in names
    assert "slide_gym" in names and not any(n.endswith("__main__") for n in names)


def test_readme_is_a_short_landing_page() -> None:
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= 200, f"README.md has {len(lines)} lines; move detail to docs/"
