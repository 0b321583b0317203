"""The wheel ships the URDFs, and the installed package finds them."""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from slide_gym.assets import robot_urdf

ROOT = Path(__file__).resolve().parents[1]


def test_robot_urdf_found() -> None:
    assert robot_urdf().is_file()


def test_wheel_contains_urdf(tmp_path: Path) -> None:
    pytest.importorskip("hatchling")
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--no-deps",
            "--no-build-isolation",
            "-q",
            "-w",
            str(tmp_path),
            str(ROOT),
        ],
        check=True,
    )
    (wheel,) = tmp_path.glob("slide_gym-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    assert "slide_gym/_urdf/wam_t42.urdf" in names
    assert "agents/__init__.py" in names
    assert any(n.endswith("entry_points.txt") for n in names)
