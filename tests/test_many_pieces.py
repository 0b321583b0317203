"""Plates whose outline needs many convex pieces (round holes, gears, several holes).

PyBullet 3.2.7's ``create*ShapeArray`` calls keep only their first 16 shapes (and the visual
one with colours segfaults past 16), so such plates used to crash the process or collide
with a truncated shape. The world-building checks run in subprocesses: a regression fails
the test instead of killing pytest.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import shapely

from slide_gym.geometry import ObjectShape

RECT = [[-0.06, -0.03], [0.06, -0.03], [0.06, 0.03], [-0.06, 0.03]]  # 12 x 6 cm


def _ngon(radius: float, n: int, cx: float = 0.0, cy: float = 0.0) -> list[list[float]]:
    t = 2 * np.pi * np.arange(n) / n
    return np.column_stack([cx + radius * np.cos(t), cy + radius * np.sin(t)]).tolist()


def _gear(teeth: int = 20, r_tip: float = 0.05, r_root: float = 0.04) -> list[list[float]]:
    """An 80-vertex gear (20 trapezoid teeth, 4 vertices each)."""
    pts = []
    for k in range(teeth):
        for frac, r in ((0.0, r_root), (0.25, r_tip), (0.5, r_tip), (0.75, r_root)):
            a = 2 * np.pi * (k + frac) / teeth
            pts.append([r * math.cos(a), r * math.sin(a)])
    return pts


PLATES: dict[str, dict] = {
    "hole24": {"vertices": RECT, "holes": [_ngon(0.015, 24)]},
    "hole48": {"vertices": RECT, "holes": [_ngon(0.015, 48)]},
    "gear80": {"vertices": _gear()},
    "three_holes": {
        "vertices": RECT,
        "holes": [_ngon(0.01, 24, -0.035), _ngon(0.01, 24, 0.035), _ngon(0.006, 12)],
    },
}
"""JSON of each plate (3 mm thick): ``name`` and ``thickness`` are added by :func:`_plate`."""

MIN_PIECES = {"hole24": 24, "hole48": 48, "gear80": 21}
"""The fewest convex pieces any exact decomposition can have. A convex piece outside a convex
n-gon hole touches at most one of its edges (a chord between two edges crosses the hole), so
the hole needs n pieces; the gear has 40 reflex vertices, and every piece boundary resolves
at most two of them, so it needs at least 40 / 2 + 1 = 21."""


def _plate(name: str) -> ObjectShape:
    spec = PLATES[name]
    return ObjectShape.from_vertices(name, spec["vertices"], spec.get("holes", ()), 0.003)


def _is_ccw_convex(pts: np.ndarray) -> bool:
    e = np.roll(pts, -1, axis=0) - pts
    ep = np.roll(e, 1, axis=0)
    return bool(np.all(ep[:, 0] * e[:, 1] - ep[:, 1] * e[:, 0] > -1e-12))


@pytest.mark.parametrize("name", list(PLATES))
def test_pieces_are_convex_and_cover_the_plate_exactly(name: str) -> None:
    plate = _plate(name)
    pieces = plate.convex_pieces()
    assert len(pieces) > 16  # past PyBullet's array limit: what the world tests exercise
    assert all(_is_ccw_convex(p) for p in pieces)
    polys = [shapely.Polygon(p) for p in pieces]
    assert sum(p.area for p in polys) == pytest.approx(plate.area, rel=1e-9)  # no overlap
    assert shapely.union_all(polys).symmetric_difference(plate.polygon).area < 1e-12
    if name in MIN_PIECES:
        assert len(pieces) == MIN_PIECES[name]


_WORLD_CHECK = textwrap.dedent(
    """
    import json, sys
    import numpy as np
    import shapely
    from shapely.ops import polylabel
    from slide_gym.envs.top_slide import TopSlideEnv
    from slide_gym.geometry import get_object, get_table
    from slide_gym.planning.collision import CollisionChecker
    from slide_gym.robot.model import READY_ARM_Q

    path = sys.argv[1]
    obj, table = get_object(path), get_table("square")
    n = len(obj.convex_pieces())
    gaps = shapely.get_parts(obj.polygon.convex_hull.difference(obj.polygon))  # holes, notches
    gaps = [polylabel(g, 1e-5) for g in sorted(gaps, key=lambda g: -g.area)[:6]]
    gaps = [g for g in gaps if g.distance(obj.polygon) > 0.002]  # clear of PyBullet's margin
    solid = obj.polygon.representative_point()
    out = {"pieces": n}

    env = TopSlideEnv(object=path, table="square", render_mode="rgb_array")
    env.reset(seed=0, options={"object_pose": (0.6, 0.0, 0.0)})
    for _ in range(5):
        env.step(np.zeros(8, dtype=np.float32))
    c, body = env.sim.client, env.sim.body("object")
    out["env_children"] = len(c.getCollisionShapeData(body, -1))
    pos, _ = env.sim.base_pose("object")
    def ray(x, y):
        hit = c.rayTest([x, y, 0.2], [x, y, -0.2])[0]
        return hit[0] == body
    out["gap_rays_hit"] = [ray(pos[0] + g.x, pos[1] + g.y) for g in gaps]
    out["solid_ray_hit"] = ray(pos[0] + solid.x, pos[1] + solid.y)
    out["resting_z"] = float(pos[2])
    frame = env.render()
    out["frame"] = list(frame.shape)
    env.close()

    checker = CollisionChecker(table, obj)
    out["checker_children"] = len(
        checker.sim.client.getCollisionShapeData(checker.object_id, -1)
    )
    checker.place_object((0.6, 0.0, 0.0))
    out["ready_collides"] = bool(checker.collides(np.asarray(READY_ARM_Q), "full"))
    checker.close()
    print(json.dumps(out))
    """
)


def _write(name: str, folder: Path) -> Path:
    path = folder / f"{name}.json"
    path.write_text(json.dumps({"name": name, "thickness": 0.003, **PLATES[name]}))
    return path


def _run(argv: list[str]) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    return subprocess.run(argv, capture_output=True, text=True, env=env)


@pytest.mark.parametrize("name", list(PLATES))
def test_plate_builds_in_env_checker_and_renderer(name: str, tmp_path: Path) -> None:
    proc = _run([sys.executable, "-c", _WORLD_CHECK, str(_write(name, tmp_path))])
    assert proc.returncode == 0, proc.stderr[-2000:]  # -11 would be a segfault
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    n = out["pieces"]
    assert n > 16
    assert out["env_children"] == n and out["checker_children"] == n  # nothing truncated
    assert out["gap_rays_hit"] and not any(out["gap_rays_hit"])  # holes, notches stay open
    assert out["solid_ray_hit"]
    assert abs(out["resting_z"] - 0.0015) < 0.002  # lies on the table (centre of mass at t/2)
    assert out["frame"] == [360, 480, 3]
    assert out["ready_collides"] is False


def test_cli_render_and_plan_take_a_plate_with_a_round_hole(tmp_path: Path) -> None:
    plate = str(_write("hole24", tmp_path))
    png = tmp_path / "scene.png"
    cli = [sys.executable, "-m", "slide_gym.cli"]
    proc = _run([*cli, "render", "--object", plate, "--out", str(png)])
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert png.stat().st_size > 0
    proc = _run(
        [*cli, "plan", "--object", plate, "--table", "square", "--time-budget", "3", "--json"]
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert json.loads(proc.stdout)["status"] in ("solved", "timeout", "infeasible")
