"""Where the package's data files (robot models) live, installed or in a checkout."""

from __future__ import annotations

from pathlib import Path

_PACKAGE_DIR = Path(__file__).resolve().parent


def urdf_dir() -> Path:
    """Directory holding the URDF files.

    A wheel ships them inside the package (``slide_gym/_urdf``); a source checkout or an
    editable install keeps them in the repository's top-level ``urdf/`` folder.
    """
    for candidate in (_PACKAGE_DIR / "_urdf", _PACKAGE_DIR.parent / "urdf"):
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError(f"slide-gym's URDF folder is missing (looked in {_PACKAGE_DIR})")


def robot_urdf() -> Path:
    """Path of the WAM arm + Yale T42 hand model."""
    return urdf_dir() / "wam_t42.urdf"
