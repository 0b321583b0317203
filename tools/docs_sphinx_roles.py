"""Griffe extension for the documentation site: Sphinx roles in docstrings become links.

The docstrings cite code as ``:class:`~slide_gym.task.TaskParams```, ``:func:`plan_once```
or ``:mod:`.commands```. mkdocstrings renders Markdown, so each role becomes an autorefs
cross-reference (``[`TaskParams`][slide_gym.task.TaskParams]``), resolved in the scope of
the docstring's object (``scoped_crossrefs``, ``relative_crossrefs`` in mkdocs.yml): a
reference to a renamed or removed object then fails ``mkdocs build --strict``. Targets that
are private (a ``_name`` part) or in other packages (:data:`EXTERNAL`) stay plain code.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|data|attr|exc|obj|const):`(~?)([^`]+)`")
EXTERNAL = ("shapely", "numpy", "np", "gymnasium", "gym", "minari", "torch", "pybullet", "ray")
"""Packages whose objects are not in this reference: their names stay plain code."""


def _link(match: re.Match[str]) -> str:
    short, target = match.group(1) == "~", match.group(2).strip()
    text = target.lstrip(".").rsplit(".", 1)[-1] if short else target.lstrip(".")
    parts = target.lstrip(".").split(".")
    private = any(p.startswith("_") and not p.startswith("__") for p in parts)
    if private or parts[0] in EXTERNAL:
        return f"`{text}`"
    return f"[`{text}`][{target}]"


def convert_roles(text: str) -> str:
    """``text`` with every Sphinx role replaced by an autorefs link (or code, if private)."""
    return ROLE.sub(_link, text)


class SphinxRoles(griffe.Extension):
    """Rewrites every loaded object's docstring with :func:`convert_roles`."""

    def on_object(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = convert_roles(obj.docstring.value)
