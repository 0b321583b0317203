"""The top-sliding task: the scene (table + thin object), its start states and its success tests.

The task knows nothing about actions; the environment joins it with the robot.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import shapely
from gymnasium.utils import seeding as gym_seeding
from shapely.geometry import Point, Polygon

from slide_gym.geometry import (
    ObjectShape,
    TableShape,
    get_object,
    overhang,
    quat_yaw,
    transform_points,
    transform_polygon,
)
from slide_gym.geometry.procedural import procedural_object
from slide_gym.robot.model import MIN_CONTACT_SIZE
from slide_gym.sim import Simulation

REACH_MIN = 0.30
"""Closest object centroid to the robot base axis (m): nearer, the arm folds onto itself."""
REACH_MAX = 0.85
"""Farthest object centroid from the robot base axis (m) that the fingertip can press."""


@dataclass(frozen=True)
class TaskParams:
    """Success thresholds and contact materials (SI units)."""

    u_star: float = MIN_CONTACT_SIZE
    """Minimum overhang (m) for a side grasp: the hand's minimum contact size u*
    (:data:`slide_gym.robot.model.MIN_CONTACT_SIZE`, 2 cm)."""
    lift_height: float = 0.05
    """How far (m) the object's lowest point must rise above the table top for a lift."""
    lift_hold_s: float = 1.0
    """How long (s) a lift must last (held in both fingers, off the table) to succeed."""
    rest_speed: float = 0.01
    """Object speed (m/s) below which it counts as resting."""
    object_friction: float = 0.8
    """Lateral friction coefficient of the object (PyBullet multiplies the two bodies')."""
    table_friction: float = 0.4
    spinning_friction: float = 0.003
    start_margin: float = 0.01
    """Random start poses keep the object this far (m) inside the table outline."""

    @classmethod
    def of(cls, params: TaskParams | Mapping[str, Any] | None) -> TaskParams:
        """``params`` itself, the defaults for None, or a TaskParams from a dict of its fields
        (JSON-friendly, as ``gym.make(..., task_params={...})`` passes it); ValueError
        naming an unknown field and the allowed ones."""
        if params is None:
            return cls()
        if isinstance(params, cls):
            return params
        if not isinstance(params, Mapping):
            raise ValueError(f"task_params must be a TaskParams or a dict, got {params!r}")
        fields = [f.name for f in dataclasses.fields(cls)]
        unknown = sorted(set(params) - set(fields))
        if unknown:
            raise ValueError(f"unknown task_params {unknown}; allowed: {', '.join(fields)}")
        return cls(**params)

    def __post_init__(self) -> None:
        positive = ("u_star", "lift_height", "lift_hold_s", "rest_speed")
        for name in (*positive, "object_friction", "table_friction"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"TaskParams.{name} must be a positive number, got {value}")


@dataclass(frozen=True)
class SceneState:
    """What the task reads from the world after a step (plain Python types)."""

    object_pose: tuple[float, float, float]
    object_z: float
    overhang_m: float
    centroid_on_table: bool
    graspable: bool
    object_speed: float
    lift_m: float  # bottom-face centre above the table top
    clearance_m: float  # the object's lowest point above the table top
    touching_robot: bool
    touching_finger_a: bool
    touching_finger_b: bool
    touching_table: bool
    fell_off: bool
    object_position: np.ndarray  # (3,) bottom-face centroid, world
    object_quat: np.ndarray  # (4,) xyzw
    object_velocity: np.ndarray  # (6,) linear, angular


def check_scene(obj: ObjectShape, table: TableShape) -> None:
    """Reject object/table pairs that can never make a valid episode."""
    if obj.area >= table.polygon.area:
        raise ValueError(
            f"object {obj.name!r} ({obj.area * 1e4:.0f} cm^2) is larger than table "
            f"{table.name!r} ({table.polygon.area * 1e4:.0f} cm^2)"
        )
    inscribed = shapely.maximum_inscribed_circle(table.polygon).length / 2.0
    if 2 * obj.circumradius > max(2 * inscribed, *_extent(table.polygon)):
        raise ValueError(
            f"object {obj.name!r} ({2 * obj.circumradius:.3f} m across) does not fit on "
            f"table {table.name!r}"
        )
    annulus = Point(0, 0).buffer(REACH_MAX, 64).difference(Point(0, 0).buffer(REACH_MIN, 64))
    if table.polygon.intersection(annulus).area < 0.5 * table.polygon.area:
        raise ValueError(
            f"table {table.name!r} lies outside the arm's reach: at least half of it must be "
            f"between {REACH_MIN} and {REACH_MAX} m from the robot base (x, y) = (0, 0)"
        )


def _extent(poly: Polygon) -> tuple[float, float]:
    minx, miny, maxx, maxy = poly.bounds
    return maxx - minx, maxy - miny


def validate_start_pose(obj: ObjectShape, table: TableShape, pose: object) -> np.ndarray:
    """Check a user-given start pose (x, y, yaw); return it as a float array."""
    try:
        arr = np.asarray(pose, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"object_pose must be 3 numbers (x, y, yaw), got {pose!r}") from None
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"object_pose must be 3 finite numbers (x, y, yaw), got {pose!r}")
    placed = transform_polygon(obj.polygon, *arr)
    if not table.polygon.contains(placed):
        out = placed.difference(table.polygon).area / placed.area
        raise ValueError(
            f"object_pose {arr.tolist()} puts {out:.0%} of object {obj.name!r} off table "
            f"{table.name!r}; the start pose must be fully on the table (not overhanging)"
        )
    reach = float(np.hypot(arr[0], arr[1]))
    if not REACH_MIN <= reach <= REACH_MAX:
        raise ValueError(
            f"object_pose {arr.tolist()} is {reach:.2f} m from the robot base; the arm reaches "
            f"objects between {REACH_MIN} and {REACH_MAX} m"
        )
    return arr


def sample_start_pose(
    obj: ObjectShape, table: TableShape, rng: np.random.Generator, margin: float, tries: int = 2000
) -> np.ndarray:
    """A random (x, y, yaw) with the object fully on the table (with a margin) and in reach."""
    inner = table.polygon.buffer(-margin)
    minx, miny, maxx, maxy = inner.bounds if not inner.is_empty else table.polygon.bounds
    for _ in range(tries):
        pose = np.array(
            [rng.uniform(minx, maxx), rng.uniform(miny, maxy), rng.uniform(-np.pi, np.pi)]
        )
        if not REACH_MIN <= np.hypot(pose[0], pose[1]) <= REACH_MAX:
            continue
        if inner.contains(transform_polygon(obj.polygon, *pose)):
            return pose
    raise ValueError(
        f"could not place object {obj.name!r} on table {table.name!r} within the arm's reach "
        f"in {tries} random tries: the object is too large for this table"
    )


def seeded_start_pose(
    obj: ObjectShape, table: TableShape, seed: int, margin: float = TaskParams.start_margin
) -> np.ndarray:
    """The start pose of ``seed``: :func:`sample_start_pose` with the generator Gymnasium makes
    for ``env.reset(seed=seed)``, so ``slide-gym plan``, ``slide-gym run`` and the env draw the
    same pose for the same seed, object and table."""
    rng, _ = gym_seeding.np_random(int(seed))
    return sample_start_pose(obj, table, rng, margin)


PROCEDURAL = "procedural"
"""The object name that draws a random plate per episode (:mod:`slide_gym.geometry.procedural`)."""
RANDOM = "random"
"""The object or table name that draws a catalog shape per episode."""


ADMISSIBLE_CENTROID_MARGIN = 0.005
"""How far (m) inside the table edge an admissible plate's centroid can stay while it
overhangs u*: a plate that reaches u* only with its centroid within a few millimetres of the
edge falls off with a slide error of that size (the expert's are 6-9 mm, median). The expert
plans with at least this margin; its planner answers ``infeasible`` below it."""
MAX_REDRAWS = 100
"""Draws of a procedural seed tried before :func:`fit_procedural_object` gives up (a scale
so small that no plate is admissible)."""


def plate_admissible(
    obj: ObjectShape,
    u_star: float = TaskParams.u_star,
    centroid_margin: float = ADMISSIBLE_CENTROID_MARGIN,
) -> bool:
    """Whether the task admits ``obj``: some pose overhangs a straight table edge by
    ``u_star`` with the centroid ``centroid_margin`` inside (the planner's feasibility test,
    :meth:`~slide_gym.geometry.shapes.ObjectShape.can_overhang`; pure geometry)."""
    return obj.can_overhang(u_star, centroid_margin)


@dataclass(frozen=True)
class ProceduralPlate:
    """The plate a procedural seed gives on a table: ``shape`` (named ``procedural-<seed>``)
    and ``redraws``, how many of the seed's draws were not admissible before it (its draw
    number, :func:`slide_gym.geometry.procedural.procedural_object`)."""

    shape: ObjectShape
    redraws: int


def draw_procedural_plate(
    seed: int, table: TableShape, scale: float = 1.0, margin: float = TaskParams.start_margin
) -> ProceduralPlate:
    """The first admissible draw of procedural seed ``seed``, scaled by ``scale`` and shrunk
    by 20 % steps until it can lie on ``table`` within the arm's reach (the same seed, table
    and scale: the same plate). A draw is admissible if :func:`plate_admissible` holds after
    scaling and fitting; ValueError if none of :data:`MAX_REDRAWS` draws is."""
    if isinstance(scale, bool) or not isinstance(scale, int | float) or not 0 < scale < math.inf:
        raise ValueError(f"scale must be a positive number, got {scale!r}")
    for redraw in range(MAX_REDRAWS):
        drawn = procedural_object(seed, redraw)  # ValueError for a bad seed
        try:
            plate = _fit_plate(drawn.scaled(scale), seed, table, margin)
        except ValueError:
            continue  # too small at this scale, or does not fit the table
        if plate_admissible(plate):
            return ProceduralPlate(plate, redraw)
    raise ValueError(
        f"procedural seed {seed}: none of {MAX_REDRAWS} draws at scale {scale:g} fits table "
        f"{table.name!r} and can overhang u* = {TaskParams.u_star:g} m with its centroid "
        f"{ADMISSIBLE_CENTROID_MARGIN:g} m inside the edge (is the scale too small?)"
    )


def fit_procedural_object(
    seed: int, table: TableShape, scale: float = 1.0, margin: float = TaskParams.start_margin
) -> ObjectShape:
    """The plate of procedural seed ``seed`` on ``table``: :func:`draw_procedural_plate`'s
    shape (admissible, fitted to the table, always the same for the same arguments)."""
    return draw_procedural_plate(seed, table, scale, margin).shape


def _fit_plate(plate: ObjectShape, seed: int, table: TableShape, margin: float) -> ObjectShape:
    """``plate`` shrunk by 20 % steps until a start pose on ``table`` exists."""
    rng = np.random.default_rng([int(seed), 0xF17])  # only to test that a start pose exists
    for _ in range(10):
        try:
            check_scene(plate, table)
            sample_start_pose(plate, table, rng, margin, tries=500)
            return plate
        except ValueError:
            plate = plate.scaled(0.8)
    raise ValueError(f"procedural plate {plate.name!r} does not fit on table {table.name!r}")


def scene_object(
    spec: str | ObjectShape,
    table: TableShape,
    *,
    seed: int = 0,
    scale: float = 1.0,
    thickness: float | None = None,
) -> ObjectShape:
    """The object of a scene: a catalog name, JSON path or shape, or ``"procedural"`` (the
    plate of ``seed``, fitted to ``table``); scaled, and with ``thickness`` (m) if given."""
    if isinstance(spec, str) and spec == PROCEDURAL:
        obj = fit_procedural_object(seed, table, scale)
    else:
        obj = get_object(spec, scale)
    return obj if thickness is None else dataclasses.replace(obj, thickness=thickness)


def add_table_body(sim: Simulation, table: TableShape, friction: float = 0.5) -> int:
    """The table as a static body named ``"table"``: its convex pieces as prisms from
    ``slab_thickness`` below the top surface up to it (the env's world and the planner's
    collision world build it the same way)."""
    return sim.create_prism_body(
        "table",
        table.convex_pieces(),
        table.height - table.slab_thickness,
        table.height,
        mass=0.0,
        rgba=(0.72, 0.62, 0.5, 1.0),
        lateral_friction=friction,
    )


class TopSlideTask:
    """Builds the table and object in a :class:`Simulation` and reads the scene state."""

    def __init__(self, params: TaskParams | Mapping[str, Any] | None = None):
        self.params = TaskParams.of(params)
        self.object: ObjectShape | None = None
        self.table: TableShape | None = None

    def build(self, sim: Simulation, obj: ObjectShape, table: TableShape, pose: np.ndarray) -> None:
        """Create the table (static) and the object resting on it at ``pose``."""
        self.object, self.table = obj, table
        self._outline = np.asarray(obj.polygon.exterior.coords)[:-1]
        n, half = len(self._outline), obj.thickness / 2.0
        rim = np.vstack([np.c_[self._outline, np.full(n, z)] for z in (-half, half)])
        self._rim = rim.T  # (3, 2n) outline corners in the body frame (centre of mass at 0)
        shapely.prepare(table.polygon)
        self._table_convex = table.polygon.convex_hull.area - table.polygon.area < 1e-12
        self._placement_key: tuple[float, float, float] | None = None
        self._placement_value = (0.0, True, False)
        p = self.params
        add_table_body(sim, table, p.table_friction)
        sim.create_prism_body(
            "object",
            obj.convex_pieces(),
            -half,
            half,
            mass=obj.mass,
            position=(pose[0], pose[1], table.height + half),
            yaw=float(pose[2]),
            rgba=(0.15, 0.45, 0.85, 1.0),
            lateral_friction=p.object_friction,
            spinning_friction=p.spinning_friction,
        )

    def object_pose(self, sim: Simulation) -> tuple[np.ndarray, np.ndarray]:
        """Object frame position (bottom face centre) and quaternion xyzw in the world."""
        pos, quat = sim.base_pose("object")
        assert self.object is not None
        pos = pos.copy()
        pos[2] -= self.object.thickness / 2.0  # body frame is the centre of mass
        return pos, quat

    def scene_state(
        self, sim: Simulation, finger_a_links: list[int], finger_b_links: list[int]
    ) -> SceneState:
        assert self.object is not None and self.table is not None
        pos, quat = self.object_pose(sim)
        yaw = quat_yaw(quat)
        u, centroid_inside, graspable = self._placement(float(pos[0]), float(pos[1]), yaw)
        lin, ang = sim.base_velocity("object")
        contacts = sim.contact_points("object", "robot")
        links = {c[4] for c in contacts}
        lift = float(pos[2] - self.table.height)
        x, y, z, w = quat
        z_row = np.array([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)])
        lowest = float((z_row @ self._rim).min()) + pos[2] + self.object.thickness / 2.0
        return SceneState(
            object_pose=(float(pos[0]), float(pos[1]), yaw),
            object_z=float(pos[2]),
            overhang_m=u,
            centroid_on_table=centroid_inside,
            graspable=bool(graspable),
            object_speed=float(np.linalg.norm(lin)),
            lift_m=lift,
            clearance_m=lowest - self.table.height,
            touching_robot=bool(contacts),
            touching_finger_a=bool(links.intersection(finger_a_links)),
            touching_finger_b=bool(links.intersection(finger_b_links)),
            touching_table=bool(sim.contact_points("object", "table")),
            fell_off=bool(lift < -0.02),
            object_position=pos,
            object_quat=quat,
            object_velocity=np.concatenate([lin, ang]),
        )

    def _placement(self, x: float, y: float, yaw: float) -> tuple[float, bool, bool]:
        """Overhang u, centroid on the table, graspable: for the object at (x, y, yaw)."""
        key = (round(x, 7), round(y, 7), round(yaw, 6))
        if key == self._placement_key:  # a resting object: nothing to recompute
            return self._placement_value
        assert self.object is not None and self.table is not None
        corners = transform_points(self._outline, x, y, yaw)
        inside = shapely.contains_xy(self.table.polygon, corners[:, 0], corners[:, 1]).all()
        if inside and self._table_convex:  # exact fast path: no vertex out, so nothing is out
            value = (0.0, True, False)
        else:
            over = overhang(transform_polygon(self.object.polygon, x, y, yaw), self.table.polygon)
            value = (float(over.u), bool(over.centroid_inside), over.graspable(self.params.u_star))
        self._placement_key, self._placement_value = key, value
        return value

    def slide_success(self, s: SceneState) -> bool:
        """Graspable, resting on the table, and the fingertip has let go."""
        resting = s.object_speed < self.params.rest_speed and abs(s.lift_m) < 0.005
        return s.graspable and resting and not s.touching_robot

    def lifted(self, s: SceneState) -> bool:
        """Held between the two fingers, off the table, its lowest point ``lift_height`` up.

        A grasp episode succeeds once this has held for ``lift_hold_s`` (the env counts it).
        """
        return (
            s.clearance_m >= self.params.lift_height
            and s.touching_finger_a
            and s.touching_finger_b
            and not s.touching_table
        )
