"""The simulator wrapper: concave bodies collide as their real outline, not its hull."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import numpy as np

from slide_gym.geometry import TableShape
from slide_gym.sim import Simulation


def _drop_cube(table: TableShape, xy: tuple[float, float]) -> float:
    """Drop a 2 cm cube above ``xy``; return its height after 1 s."""
    sim = Simulation()
    try:
        sim.create_prism_body(
            "table", table.convex_pieces(), table.height - 0.03, table.height, mass=0.0
        )
        cube = np.array([[-0.01, -0.01], [0.01, -0.01], [0.01, 0.01], [-0.01, 0.01]])
        sim.create_prism_body("cube", [cube], -0.01, 0.01, mass=0.05, position=(*xy, 0.05))
        for _ in range(240):
            sim.step()
        return float(sim.base_pose("cube")[0][2])
    finally:
        sim.close()


def test_concave_table_has_a_real_notch() -> None:
    l_table = TableShape.from_vertices(
        "L", [[0.4, -0.3], [0.8, -0.3], [0.8, -0.1], [0.6, -0.1], [0.6, 0.3], [0.4, 0.3]], 0.0
    )
    assert len(l_table.convex_pieces()) >= 2
    on_top = _drop_cube(l_table, (0.5, 0.0))
    in_notch = _drop_cube(l_table, (0.7, 0.1))  # inside the hull, outside the L
    assert abs(on_top - 0.01) < 0.005
    assert in_notch < -0.1  # fell through the notch


def test_close_twice_is_safe() -> None:
    sim = Simulation()
    sim.close()
    sim.close()


_MANY_PIECES = textwrap.dedent(
    """
    import json
    import numpy as np
    from slide_gym.envs.cameras import Camera, render_frame
    from slide_gym.sim import Simulation

    sim = Simulation("rgb_array")
    pieces = [
        np.array([[x, y], [x + 0.006, y], [x + 0.006, y + 0.006], [x, y + 0.006]])
        for x in np.arange(20) * 0.01 for y in np.arange(15) * 0.01
    ]  # 300 squares, 4 mm apart (PyBullet's collision margin is 1 mm)
    body = sim.create_prism_body("grid", pieces, 0.0, 0.003, mass=0.1, position=(0.5, 0, 0))
    c = sim.client
    def hit(x, y):
        return c.rayTest([0.5 + x, y, 0.1], [0.5 + x, y, -0.1])[0][0] == body
    print(json.dumps({
        "children": len(c.getCollisionShapeData(body, -1)),
        "last_piece_hit": hit(0.193, 0.143),
        "gap_hit": hit(0.098, 0.073),
        "image": list(render_frame(c, Camera(), 64, 48).shape),
    }))
    sim.close()
    """
)


def test_a_body_takes_any_number_of_pieces() -> None:
    """PyBullet's array calls keep 16 shapes (and segfault with colours past 16): 300 pieces
    must all collide and render. In a subprocess, so a crash fails instead of killing pytest."""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    proc = subprocess.run(
        [sys.executable, "-c", _MANY_PIECES], capture_output=True, text=True, env=env
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out == {"children": 300, "last_piece_hit": True, "gap_hit": False, "image": [48, 64, 3]}
