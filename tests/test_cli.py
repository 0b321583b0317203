"""The ``slide-gym`` command: output formats and exit codes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from slide_gym.cli import main
from slide_gym.geometry import OBJECT_NAMES, TABLE_NAMES


def test_shapes_json_lists_the_catalog(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["shapes", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert {r["name"] for r in rows if r["kind"] == "object"} == set(OBJECT_NAMES)
    assert {r["name"] for r in rows if r["kind"] == "table"} == set(TABLE_NAMES)
    a = next(r for r in rows if r["name"] == "A")
    assert len(a["holes"]) == 1 and len(a["vertices"]) >= 3 and a["thickness"] > 0
    assert all("height" in r for r in rows if r["kind"] == "table")


def test_shapes_text(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["shapes"]) == 0
    out = capsys.readouterr().out
    assert "crescent" in out and "triangle" in out


def test_bad_name_exits_2_with_the_valid_names() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "slide_gym.cli", "render", "--object", "banana"],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2
    assert "banana" in proc.stderr and "square" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert proc.stdout == ""


def test_bad_json_file_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bowtie.json"
    bad.write_text(json.dumps({"name": "bowtie", "vertices": [[0, 0], [1, 1], [1, 0], [0, 1]]}))
    assert main(["render", "--object", str(bad), "--out", str(tmp_path / "x.png")]) == 2
    assert "self-intersect" in capsys.readouterr().err.lower()


def test_demo_runs_and_succeeds(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["demo", "--object", "square", "--seed", "0"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["success"] is True
    assert summary["overhang_m"] >= 0.03
