"""The simulator wrapper: concave bodies collide as their real outline, not its hull."""

from __future__ import annotations

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
