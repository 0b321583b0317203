"""The code version stamped on every experiment row and dataset: the package version plus,
in a git checkout, the commit and a fingerprint of uncommitted changes to the code."""

from __future__ import annotations

import contextlib
import functools
import hashlib
import subprocess
from pathlib import Path

from slide_gym import __version__

CODE_PATHS = ("slide_gym", "agents", "urdf", "pyproject.toml")
"""What decides a result (relative to the checkout's top): changes elsewhere (README, tests,
results/) leave the version as it is."""


def _git(root: Path, *args: str) -> str:
    """``git args`` in ``root`` (read-only: never takes the index lock the lead may hold)."""
    done = subprocess.run(
        ["git", "--no-optional-locks", *args],
        cwd=root,
        capture_output=True,
        check=True,
        timeout=20,
    )
    return done.stdout.decode(errors="replace")


@functools.cache
def code_version() -> str:
    """``VERSION+COMMIT`` (12 hex digits), then ``+dirty.HASH`` when :data:`CODE_PATHS` have
    uncommitted changes (HASH: 8 hex digits of those changes, so two different edits never
    share a version); just ``VERSION`` outside a git checkout of this package (a wheel)."""
    package = Path(__file__).resolve().parent
    try:
        root = Path(_git(package, "rev-parse", "--show-toplevel").strip()).resolve()
        if root != package.parent:  # e.g. a wheel inside some other repository's venv
            return __version__
        commit = _git(root, "rev-parse", "HEAD").strip()[:12]
        diff = _git(root, "diff", "HEAD", "--binary", "--", *CODE_PATHS)
        untracked = _git(
            root, "ls-files", "--others", "--exclude-standard", "-z", "--", *CODE_PATHS
        )
    except (OSError, subprocess.SubprocessError):
        return __version__
    version = f"{__version__}+{commit}"
    if not diff and not untracked:
        return version
    digest = hashlib.sha256(diff.encode())
    for name in sorted(n for n in untracked.split("\0") if n):
        digest.update(name.encode() + b"\0")
        with contextlib.suppress(OSError):  # removed meanwhile
            digest.update((root / name).read_bytes())
    return f"{version}+dirty.{digest.hexdigest()[:8]}"
