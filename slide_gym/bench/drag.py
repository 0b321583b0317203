"""Press a thin plate with finger A and drag it by friction: sinking, creep, ejection.

The fingertip comes down on a plate lying on the table to a planned contact depth below the
plate's top (the planner's band is 0.5-2.5 cm, the expert's 1.2-2.0 cm; the compliant finger
deflects instead of reaching it), holds, then drags it along a straight line at constant
orientation and holds again. Arm targets come from IK as in the expert's press and slide
(:func:`agents.tracking.cartesian_line`, :func:`agents.trajectory.time_segment`) and go in
through the environment's actions; the plate moves by contact alone. Every physics step is
watched:

- ``sink_m``: how far the plate's lowest point went below the table top (its collision shape
  has the plate's real thickness: ``rest_gap_m``, its lowest point at rest, is ~0);
- ``lag_m``: the fingertip's displacement along the drag minus the plate's (> 0: the plate
  fell behind, the fingertip crept over it; < 0: the plate shot ahead), and ``creep_m``: how
  far the fingertip moved in the plate's frame (its slip over the plate, any direction);
- ``rise_m``: how far the plate's lowest point rose above its rest height (flicked, flipped);
- ``ejected``: the plate shot ahead by more than :data:`EJECT_OVERSHOOT`, rose more than
  :data:`EJECT_RISE` or lost the fingertip by the end of the drag.

``slide-gym bench env --drag`` runs :func:`drag_summary`; ``tests/test_thin_plates.py``
checks single drags.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

CARD_VERTICES = ((0.0, 0.0), (0.0856, 0.0), (0.0856, 0.054), (0.0, 0.054))
"""A credit card's outline (ISO/IEC 7810 ID-1: 85.6 x 54 mm, 0.76 mm thick)."""
CARD_THICKNESS = 0.00076
THICKNESSES = (0.0005, 0.00076, 0.002, 0.004, 0.01)
"""Plate thicknesses (m) of :func:`drag_summary`: 0.5 mm to 10 mm."""
DEPTHS = (0.012, 0.02, 0.025)
"""Planned contact depths (m below the plate top) of :func:`drag_summary`: the expert's band
(1.2-2.0 cm) and the planner's deepest (2.5 cm)."""
HEADINGS = (0.0, math.pi / 2, math.pi, -math.pi / 2)
"""Drag directions (world yaw) of :func:`drag_summary`: away from the robot, to its left,
toward it, to its right."""
LENGTH = 0.20
"""Drag length (m)."""
SPEED = 0.05
"""Fingertip speed while dragging (m/s)."""
BETA = 0.9
"""Fingertip pitch (rad): the planner's ``beta0``."""
MIDPOINT = (0.6, 0.0)
"""Midpoint of the drag (world xy, m) on the square table: the press point starts half the
drag length before it; there is room for 20 cm in all four headings, all in reach."""
EJECT_OVERSHOOT = 0.01
"""A plate that moved more than this (m) further than the fingertip was shot ahead."""
EJECT_RISE = 0.003
"""A plate whose lowest point rose more than this (m) above its rest height flew."""


@dataclass(frozen=True)
class DragResult:
    """One press and drag (SI units; see the module docstring)."""

    thickness_m: float
    depth_m: float
    heading_rad: float
    tip_first: bool
    tip_moved_m: float
    plate_moved_m: float
    lag_m: float
    creep_m: float
    plate_turn_rad: float
    sink_m: float
    sink_press_m: float
    rise_m: float
    rest_gap_m: float
    press_force_n: float
    contact_fraction: float
    ejected: bool
    physics_steps: int

    def to_json_dict(self) -> dict[str, Any]:
        return {k: round(v, 6) if isinstance(v, float) else v for k, v in asdict(self).items()}


def card(thickness: float = CARD_THICKNESS) -> Any:
    """A credit-card plate (:data:`CARD_VERTICES`) of ``thickness`` (m)."""
    from slide_gym.geometry import ObjectShape

    return ObjectShape.from_vertices("card", CARD_VERTICES, thickness=thickness)


def drag_plate(
    thickness: float = CARD_THICKNESS,
    depth: float = 0.02,
    heading: float = 0.0,
    *,
    tip_first: bool = False,
    length: float = LENGTH,
    speed: float = SPEED,
    plate: Any = None,
    table: str = "square",
    midpoint: Sequence[float] = MIDPOINT,
    configure: Callable[[Any], None] | None = None,
) -> DragResult:
    """Press ``plate`` (default: a credit card) of ``thickness`` (m) at ``depth`` below its
    top, drag it ``length`` m along world yaw ``heading``, and report what happened.

    The fingertip's X_F lies across the drag; ``tip_first`` points the tip (Z_F) along the
    drag, otherwise the finger trails. The press point is the plate's pole of
    inaccessibility (its centroid for convex plates). ``configure(env)``, if given, runs
    right after the reset (to try other engine settings).
    """
    from shapely.ops import polylabel

    from agents.tracking import cartesian_line
    from agents.trajectory import Segment, time_segment
    from slide_gym.envs.top_slide import TopSlideEnv
    from slide_gym.planning.constraints import contact_rotation
    from slide_gym.planning.ik import IKTarget, solve_ik
    from slide_gym.planning.regions import nominal_seed
    from slide_gym.robot.kinematics import fingertip_chain

    obj = card(thickness) if plate is None else dataclasses.replace(plate, thickness=thickness)
    inner = polylabel(obj.polygon, 1e-4)
    direction = np.array([math.cos(heading), math.sin(heading), 0.0])
    press = np.array([midpoint[0], midpoint[1], 0.0]) - direction * length / 2.0
    pose = (press[0] - inner.x, press[1] - inner.y, 0.0)
    env = TopSlideEnv(object=obj, table=table)
    try:
        obs, _ = env.reset(seed=0, options={"object_pose": pose})
        if configure is not None:
            configure(env)
        sim, task = env.sim, env.task
        c = sim.client
        robot_id, plate_id = sim.body("robot"), sim.body("object")
        top = task.table.height
        outline = np.asarray(obj.polygon.exterior.coords)[:-1]
        half = thickness / 2.0
        rim = np.vstack([np.c_[outline, np.full(len(outline), z)] for z in (-half, half)]).T
        finger = set(env.robot.finger_a_links)
        lowest: list[float] = []
        force: list[float] = []
        step = sim.step

        def watched_step() -> None:  # the robot's step_physics() calls sim.step()
            step()
            pos, (x, y, z, w) = c.getBasePositionAndOrientation(plate_id)
            z_row = np.array([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)])
            lowest.append(float((z_row @ rim).min()) + pos[2] - top)
            points = c.getContactPoints(robot_id, plate_id)
            force.append(sum(p[9] for p in points if p[3] in finger))

        sim.step = watched_step

        chain = fingertip_chain()
        rng = np.random.default_rng(0)
        alpha = heading - math.pi / 2 if tip_first else heading + math.pi / 2  # yaw of X_F
        press[2] = top + thickness - depth
        q_press = solve_ik(
            chain,
            IKTarget(press, contact_rotation(alpha, BETA)),
            rng,
            nominal_seed(press, alpha)[None],
        )
        if q_press is None:
            raise ValueError(f"no IK solution for a press at {press.round(3).tolist()}")
        down = cartesian_line(chain, q_press, np.array([0.0, 0.0, 0.03 + depth]), rng)
        line = cartesian_line(chain, q_press, direction * length, rng)
        if down is None or line is None:
            raise ValueError("the press or the drag leaves the arm's reach")

        q = np.asarray(obs["arm_qpos"], dtype=float)
        step_max = env.max_joint_step

        def follow(segment: Segment, timed_chain: Any = None) -> None:
            nonlocal q
            for target in time_segment(segment, env.dt, timed_chain):
                a = np.clip((target - q) / step_max, -1.0, 1.0)
                q = q + step_max * a
                env.step(np.r_[a, -1.0].astype(np.float32))  # hand open (u = 0)

        follow(Segment("approach", np.array([q, down[-1]]), 0.6))
        n_free = len(lowest)
        follow(Segment("press", down[::-1], 1.0, 0.02, hold_s=0.5), chain)
        n_press = len(lowest)
        tip0, plate0, yaw0 = _tip_and_plate(env)
        follow(Segment("drag", line, 1.0, speed, hold_s=0.5), chain)
        tip1, plate1, yaw1 = _tip_and_plate(env)
    finally:
        env.close()

    low = np.array(lowest[n_free:])
    drag_force = np.array(force[n_press:])
    touching = drag_force > 0.0
    rest = lowest[n_free - 1]
    tip_moved = float(direction[:2] @ (tip1 - tip0))
    plate_moved = float(direction[:2] @ (plate1 - plate0))
    lag = tip_moved - plate_moved
    rise = max(0.0, float(low.max()) - rest)
    creep = np.linalg.norm(_rotate(tip1 - plate1, -yaw1) - _rotate(tip0 - plate0, -yaw0))
    return DragResult(
        thickness_m=float(thickness),
        depth_m=float(depth),
        heading_rad=float(heading),
        tip_first=bool(tip_first),
        tip_moved_m=tip_moved,
        plate_moved_m=plate_moved,
        lag_m=lag,
        creep_m=float(creep),
        plate_turn_rad=float(math.remainder(yaw1 - yaw0, math.tau)),
        sink_m=max(0.0, -float(low.min())),
        sink_press_m=max(0.0, -float(low[: n_press - n_free].min())),
        rise_m=rise,
        rest_gap_m=float(rest),
        press_force_n=float(np.median(drag_force[touching])) if touching.any() else 0.0,
        contact_fraction=float(touching.mean()),
        ejected=bool(-lag > EJECT_OVERSHOOT or rise > EJECT_RISE or not touching[-20:].any()),
        physics_steps=len(lowest),
    )


def _tip_and_plate(env: Any) -> tuple[np.ndarray, np.ndarray, float]:
    """Fingertip xy, plate xy (bottom-face centroid) and plate yaw, world."""
    from slide_gym.geometry import quat_yaw

    tip, _ = env.robot.fingertip_pose()
    pos, quat = env.task.object_pose(env.sim)
    return tip[:2].copy(), pos[:2].copy(), float(quat_yaw(quat))


def _rotate(v: np.ndarray, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def drag_summary(
    thicknesses: Sequence[float] = THICKNESSES,
    depths: Sequence[float] = DEPTHS,
    headings: Sequence[float] = HEADINGS,
    tip_first: Sequence[bool] = (False, True),
    with_results: bool = False,
) -> dict[str, Any]:
    """Press and drag a credit-card outline of every thickness at every depth, heading and
    finger direction (120 drags of 20 cm by default, about 100 s of CPU): the deepest sinking,
    the lag (signed median; 90th percentile and maximum of its size), the ejections; overall
    and per thickness, and with ``with_results`` every drag's :class:`DragResult` (lengths in
    the units
    the keys say)."""
    rows = [
        drag_plate(t, d, h, tip_first=f)
        for t in thicknesses
        for d in depths
        for h in headings
        for f in tip_first
    ]

    def stats(group: list[DragResult]) -> dict[str, Any]:
        lag = 100.0 * np.array([r.lag_m for r in group])
        sink = 1e3 * np.array([r.sink_m for r in group])
        return {
            "drags": len(group),
            "sink_mm_median": round(float(np.median(sink)), 2),
            "sink_mm_max": round(float(sink.max()), 2),
            "sinking_over_1mm": int((sink > 1.0).sum()),
            "rest_gap_mm_max": round(1e3 * max(abs(r.rest_gap_m) for r in group), 3),
            "lag_cm_median": round(float(np.median(lag)), 2),
            "lag_cm_p90": round(float(np.percentile(np.abs(lag), 90)), 2),
            "lag_cm_max": round(float(np.abs(lag).max()), 2),
            "ejected": sum(r.ejected for r in group),
        }

    return {
        "plate": "credit-card outline, 85.6 x 54 mm",
        "length_m": LENGTH,
        "depths_m": list(depths),
        "all": stats(rows),
        "by_thickness_mm": {
            f"{1e3 * t:g}": stats([r for r in rows if r.thickness_m == t]) for t in thicknesses
        },
    } | ({"drag_results": [r.to_json_dict() for r in rows]} if with_results else {})
