"""Bad input gives a ValueError that names the argument (Python) and one line on stderr with
exit code 2 (``slide-gym``), before any episode runs."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
import shapely

import slide_gym.sim
from agents.episode import run_episode
from slide_gym.cli import main
from slide_gym.envs.top_slide import TopSlideEnv
from slide_gym.geometry import (
    MAX_SIZE,
    MAX_THICKNESS,
    MIN_SIZE,
    MIN_THICKNESS,
    OBJECTS,
    TABLE_HEIGHT_RANGE,
    ObjectShape,
    TableShape,
    get_object,
    get_table,
    load_object_json,
    load_table_json,
)
from slide_gym.sim import Simulation, has_display

CARD = [[0, 0], [0.085, 0], [0.085, 0.054], [0, 0.054]]
DESK = [[0.35, -0.3], [0.8, -0.3], [0.8, 0.3], [0.35, 0.3]]


def _json(folder: Path, name: str, data: dict) -> str:
    path = folder / name
    path.write_text(json.dumps(data))
    return str(path)


def _cli_error(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    """Run ``slide-gym argv``; assert exit code 2 and one line on stderr; return the line."""
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    command = " ".join(argv[:2]) if argv[0] == "bench" else argv[0]
    assert captured.err.startswith(f"slide-gym {command}: error: ")
    assert captured.err.count("\n") == 1 and "Traceback" not in captured.err
    return captured.err


@pytest.fixture
def no_episode(monkeypatch: pytest.MonkeyPatch) -> None:
    """Fail the test if ``run_episode`` got as far as making the episode's environment."""

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the episode started although the input was bad")

    monkeypatch.setattr("agents.episode.gym.make", refuse)


# ------------------------------------------------------------------ scale and size
def test_tiny_scale_names_the_allowed_scales() -> None:
    with pytest.raises(ValueError, match=r"scale 1e-09 .*smaller.*scale must be within \[0\.1"):
        get_object("L", 1e-9)
    with pytest.raises(ValueError, match=r"scale 8 .*larger"):
        get_object("square", 8.0)
    with pytest.raises(ValueError, match="scale"):
        TopSlideEnv(object="L", scale=1e-9)
    size = OBJECTS["L"].size
    get_object("L", MIN_SIZE / size)  # the bounds themselves are allowed
    get_object("L", MAX_SIZE / size)


def test_object_size_bounds(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"1\.41 cm across.*smaller.*2 cm to 50 cm"):
        ObjectShape("chip", shapely.box(0, 0, 0.01, 0.01))
    with pytest.raises(ValueError, match="larger"):
        ObjectShape.from_vertices("tray", [[0, 0], [0.4, 0], [0.4, 0.4], [0, 0.4]])
    big = _json(tmp_path, "mm.json", {"name": "mm", "vertices": [[0, 0], [85, 0], [85, 54]]})
    with pytest.raises(ValueError, match=r"mm\.json.*larger.*metres"):
        load_object_json(big)


@pytest.mark.parametrize("value", [1e200, -1e200, 1e300])
def test_huge_vertices_are_a_value_error(value: float, tmp_path: Path) -> None:
    verts = [[0, 0], [value, 0], [0, value]]
    with pytest.raises(ValueError, match="coordinates"):
        ObjectShape.from_vertices("huge", verts)
    with pytest.raises(ValueError, match="coordinates"):
        TableShape.from_vertices("huge", verts)
    with pytest.raises(ValueError, match="coordinates"):
        ObjectShape.from_vertices("huge", CARD, [verts])
    with pytest.raises(ValueError, match="coordinates"):
        ObjectShape("huge", shapely.Polygon(verts))
    with pytest.raises(ValueError, match="coordinates"):
        TableShape("huge", shapely.Polygon(verts))
    path = _json(tmp_path, "huge.json", {"name": "huge", "vertices": verts})
    with pytest.raises(ValueError, match=r"huge\.json.*coordinates"):
        get_object(path)


# ------------------------------------------------------------------ thickness and height
@pytest.mark.parametrize(
    ("thickness", "match"),
    [
        (0.0002, r"thickness must be within \[0\.0003, 0\.05\] m"),
        (0.06, "thickness"),
        (3, r"thickness.*3 mm is 0\.003 m"),
        (float("inf"), "thickness"),
        ("thin", "thickness must be a number"),
    ],
)
def test_thickness_bounds(thickness: object, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        ObjectShape.from_vertices("card", CARD, thickness=thickness)


def test_thickness_bounds_are_allowed() -> None:
    for t in (MIN_THICKNESS, MAX_THICKNESS):
        assert ObjectShape.from_vertices("card", CARD, thickness=t).thickness == t


@pytest.mark.parametrize("height", [1.5, -0.5, TABLE_HEIGHT_RANGE[1] + 0.01, 750.0])
def test_table_height_out_of_reach(height: float) -> None:
    with pytest.raises(ValueError, match=r"height .* out of the arm's reach"):
        TableShape.from_vertices("desk", DESK, height=height)


def test_table_height_range_is_allowed() -> None:
    for h in TABLE_HEIGHT_RANGE:
        assert TableShape.from_vertices("desk", DESK, height=h).height == h
    assert TABLE_HEIGHT_RANGE[0] < 0.0 < TABLE_HEIGHT_RANGE[1]  # the catalog's tables are at 0


# ------------------------------------------------------------------ JSON keys and names
@pytest.mark.parametrize(
    ("data", "match"),
    [
        ({"thick": 0.003}, r"unknown key 'thick' in object file; did you mean 'thickness'\?"),
        ({"hole": [[[0.02, 0.02], [0.03, 0.02], [0.03, 0.03]]]}, "did you mean 'holes'"),
        ({"Density": 900}, "did you mean 'density'"),
        ({"height": 0.0}, "'height' belongs in a table file"),
        ({"colour": "red"}, "unknown key 'colour'.*valid keys: name, vertices, holes"),
        ({"thickness": 3}, r"thickness.*3 mm is 0\.003 m"),
    ],
)
def test_object_json_keys_and_values(data: dict, match: str, tmp_path: Path) -> None:
    path = _json(tmp_path, "card.json", {"name": "card", "vertices": CARD, **data})
    with pytest.raises(ValueError, match=match):
        load_object_json(path)


@pytest.mark.parametrize(
    ("data", "match"),
    [
        ({"hieght": 0.0, "height": 0.0}, "did you mean 'height'"),
        ({"height": 0.0, "slab": 0.02}, "did you mean 'slab_thickness'"),
        ({"height": 1.5}, r"table\.json.*height 1\.5 m is out of the arm's reach"),
        ({"height": 0.0, "holes": []}, "'holes' belongs in an object file"),
    ],
)
def test_table_json_keys_and_values(data: dict, match: str, tmp_path: Path) -> None:
    path = _json(tmp_path, "table.json", {"name": "desk", "vertices": DESK, **data})
    with pytest.raises(ValueError, match=match):
        load_table_json(path)


def test_catalog_names_suggest_the_closest() -> None:
    with pytest.raises(ValueError, match="unknown object 'l'; did you mean 'L'"):
        get_object("l")
    with pytest.raises(ValueError, match="did you mean 'crescent'"):
        get_object("cresent")
    with pytest.raises(ValueError, match="did you mean 'round'"):
        get_table("Round")
    with pytest.raises(ValueError, match=r"unknown object 'banana'; valid names: square"):
        get_object("banana")


# ------------------------------------------------------------------ seeds, videos, display
def test_negative_seed_is_a_value_error() -> None:
    env = TopSlideEnv()
    try:
        with pytest.raises(ValueError, match="seed must be None or a non-negative integer"):
            env.reset(seed=-1)
        with pytest.raises(ValueError, match="seed"):
            env.reset(seed=1.5)
    finally:
        env.close()
    with pytest.raises(ValueError, match="seed must be a non-negative integer"):
        run_episode("L", "square", seed=-1)


@pytest.mark.parametrize(
    ("video", "match"),
    [("/no/such/dir/x.gif", "folder '/no/such/dir' does not exist"), ("x.avi", r"\.mp4 or \.gif")],
)
def test_bad_video_path_fails_before_the_episode(
    video: str, match: str, no_episode: None, tmp_path: Path
) -> None:
    with pytest.raises(ValueError, match=match):
        run_episode("L", "square", video=Path(video))


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="display variables are X11's")
def test_human_render_mode_without_a_display(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert not has_display()
    with pytest.raises(ValueError, match="render_mode='human'.*no display.*rgb_array"):
        TopSlideEnv(render_mode="human")
    with pytest.raises(ValueError, match="no display"):
        Simulation(render_mode="human")
    with pytest.raises(ValueError, match="render_mode must be"):
        Simulation(render_mode="window")
    monkeypatch.setenv("WAYLAND_DISPLAY", "wayland-0")
    assert has_display()


def test_render_size_is_checked() -> None:
    for width, height in ((0, 10), (10, -1), (10.5, 10), (10**6, 10)):
        with pytest.raises(ValueError, match="render_(width|height)"):
            TopSlideEnv(render_mode="rgb_array", render_width=width, render_height=height)


# ------------------------------------------------------------------ the command line
@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (["render", "--scale", "1e-9"], "scale 1e-09"),
        (["render", "--object", "l"], "did you mean 'L'"),
        (["render", "--table", "squar"], "did you mean 'square'"),
        (["render", "--out", "nodir/x.png"], "--out: folder 'nodir' does not exist"),
        (["render", "--out", "x.txt"], r"--out must end in \.png or \.jpg or \.jpeg"),
        (["render", "--width", "0"], "--width must be 1..4096"),
        (["render", "--seed", "-1"], "--seed must be a non-negative integer, got -1"),
        (["plan", "--object", "L", "--table", "square", "--seed", "-1"], "--seed"),
        (["plan", "--object", "L", "--table", "square", "--scale", "1e-9"], "scale"),
        (["demo", "--out", "x.txt"], r"--out must end in \.gif or \.mp4"),
        (["demo", "--seed", "-3"], "--seed"),
        (["bench", "env", "--seed", "-1"], "--seed"),
    ],
)
def test_cli_bad_arguments_exit_2_with_one_line(
    argv: list[str], match: str, capsys: pytest.CaptureFixture[str], monkeypatch, tmp_path: Path
) -> None:
    monkeypatch.chdir(tmp_path)  # relative --out paths land here, never in the repository
    err = _cli_error(argv, capsys)
    assert re.search(match, err), err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        (["--seed", "-1"], "--seed must be a non-negative integer"),
        (["--video", "/no/such/dir/x.gif"], "--video: folder '/no/such/dir' does not exist"),
        (["--video", "ep.avi"], r"--video must end in .gif or .mp4"),
        (["--scale", "1e-9"], "scale 1e-09"),
        (["--object", "l"], "did you mean 'L'"),
    ],
)
def test_cli_run_rejects_bad_input_before_the_episode(
    extra: list[str], match: str, no_episode: None, capsys: pytest.CaptureFixture[str]
) -> None:
    err = _cli_error(["run", *extra], capsys)
    assert re.search(match, err), err


@pytest.mark.parametrize(
    ("kind", "data", "match"),
    [
        ("object", {"thick": 0.003}, "did you mean 'thickness'"),
        ("object", {"hole": []}, "did you mean 'holes'"),
        ("object", {"thickness": 3}, "3 mm is 0.003 m"),
        ("object", {"vertices": [[0, 0], [1e200, 0], [0, 1e200]]}, "coordinates"),
        ("table", {"height": 1.5}, "out of the arm's reach"),
        ("table", {"height": 0.0, "heigth": 0.0}, "did you mean 'height'"),
    ],
)
def test_cli_bad_json_exits_2_naming_the_key(
    kind: str, data: dict, match: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = {"name": "x", "vertices": CARD if kind == "object" else DESK}
    path = _json(tmp_path, f"{kind}.json", {**base, **data})
    out = ["--out", str(tmp_path / "x.png")]
    err = _cli_error(["render", f"--{kind}", path, *out], capsys)
    assert match in err and str(tmp_path) in err
    assert not (tmp_path / "x.png").exists()


def test_cli_exit_code_in_a_real_process(tmp_path: Path) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "slide_gym.cli", "run", "--seed", "-1"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr == "slide-gym run: error: --seed must be a non-negative integer, got -1\n"


def test_display_check_is_used_by_the_simulation() -> None:
    assert slide_gym.sim.check_render_mode(None) is None
    assert slide_gym.sim.check_render_mode("rgb_array") is None


def test_unknown_env_id_names_the_registered_ones(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(ValueError, match="env_id must be one of SlideGym/TopSlide-v0"):
        run_episode("square", "square", env_id="SlideGym/Nope-v0")
    with pytest.raises(SystemExit) as exc:
        main(["bench", "execute", "--env", "SlideGym/Nope-v0"])
    assert exc.value.code == 2 and "SlideGym/TopSlideGrasp-v0" in capsys.readouterr().err
