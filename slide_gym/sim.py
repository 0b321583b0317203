"""A thin wrapper around one PyBullet client: bodies addressed by name.

The task and the environment build and read bodies through :class:`Simulation` by name, so
they stay free of client ids and body indices. Two hot paths talk to PyBullet directly on
purpose: :class:`~slide_gym.robot.WamT42` (joint states and torques every physics step) and
the planner's :class:`~slide_gym.planning.collision.CollisionChecker` (raw client calls per
collision check); both still create their bodies through a :class:`Simulation`.
"""

from __future__ import annotations

import contextlib
import ctypes
import dataclasses
import hashlib
import os
import sys
import tempfile
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

_LIBC = ctypes.CDLL(None)


@contextlib.contextmanager
def silenced_stdout(fds: tuple[int, ...] = (1,)) -> Iterator[None]:
    """Send file descriptor 1 (and any other ``fds``) to /dev/null: PyBullet's C code prints
    banners and URDF merge logs there, which would corrupt the JSON that ``slide-gym ...
    --json`` prints (and the one-line errors on stderr)."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(fd) for fd in fds]
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        for fd in fds:
            os.dup2(devnull, fd)
        yield
    finally:
        _LIBC.fflush(None)  # C stdio buffers what it printed; drop it while still silenced
        for fd, copy in zip(fds, saved, strict=True):
            os.dup2(copy, fd)
            os.close(copy)
        os.close(devnull)


with silenced_stdout((1, 2)):  # the import prints its build-time banner on stderr
    import pybullet as pb
    from pybullet_utils.bullet_client import BulletClient

_MESH_CACHE = Path(tempfile.gettempdir()) / "slide_gym_meshes"
RENDER_MODES: tuple[str | None, ...] = (None, "rgb_array", "human")
OBJECT_STATE_SIZE = 13
"""Length of :meth:`Simulation.body_state`: position, quaternion, linear, angular velocity."""
MAX_IMAGE_SIDE = 4096
"""Largest image width or height (pixels) of a rendered image
(:func:`slide_gym.envs.cameras.render_frame`)."""


@dataclass(frozen=True)
class PhysicsParams:
    """Physics engine settings (SI units).

    Thin plates (0.5-10 mm) are pressed, dragged and pinched between the multibody finger
    and the static table. What makes that sound (``slide-gym bench env --drag`` measures it;
    docs/benchmarks.md, "Thin plates"):

    - the table and object prisms carry polyhedral features (PyBullet's
      ``URDF_INITIALIZE_SAT_FEATURES``), so every step Bullet clips face against face and
      gets the whole contact patch (up to 4 points). Without them it adds one GJK point per
      step to a persistent manifold, a pressed plate rests on 1-3 points, the finger tilts it
      about them and squeezes it 4-17 mm into the table, and drags shoot it ahead;
    - ``prism_margin``: PyBullet adds its 1 mm default margin *outside* a convex hull, so a
      0.76 mm card was 2.76 mm thick to the fingertip and the table top 1 mm high;
    - ``solver_iterations`` (100) at ``timestep`` while the robot is within
      ``near_distance`` of the object: fewer iterations let the pressed fingertip creep over
      the plate (50: median lag 1.4 cm on a card, 30: cards lost);
    - ``friction_anchor`` (off here and in the v0 ids, on in v1: :data:`ENV_VERSION_PHYSICS`):
      PyBullet's ``frictionAnchor`` on every link of the robot. Bullet re-creates its
      friction constraints at each step's contact points, so a pressed fingertip's static
      friction drifts and the fingertip creeps over a light plate; the anchor keeps each
      contact's anchor point across steps (docs/benchmarks.md, "Friction anchors");
    - ``solver_residual_threshold`` (PyBullet's 1e-7 by default): a larger one lets the
      solver stop before its ``solver_iterations`` once the contact impulses have settled;
      1e-4 makes a catalog episode's physics about a quarter cheaper
      (docs/benchmarks.md, "A solver that stops when it has converged").

    Farther from the object ("free": the arm moving, the fingers touching each other or the
    table) the world steps ``free_step_factor`` times longer with ``free_solver_iterations``
    and pyramid friction (:meth:`Simulation.adapt`). The control period is unchanged, the
    robot's spring law reads the step length in force (:attr:`Simulation.physics`), the
    environment scales the arm motors' per-step position gain by the step span (free-space
    arm motion stays within 0.3 mrad of the base rate's), and no contact with the object can
    begin within one control step from ``near_distance`` away. ``free_step_factor=1``,
    ``free_solver_iterations=solver_iterations`` and ``free_cone_friction=True`` turn it off.
    """

    timestep: float = 1.0 / 240.0
    solver_iterations: int = 100
    gravity: float = -9.81
    prism_margin: float = 1e-4
    """Collision margin (m) of the table and object prisms (PyBullet's default is 1 mm)."""
    near_distance: float = 0.1
    """Robot-object distance (m) within which ``timestep`` and ``solver_iterations`` apply."""
    free_step_factor: int = 2
    """How many times longer the physics steps are while the robot is free (whole number)."""
    free_solver_iterations: int = 10
    """Solver iterations while the robot is free."""
    free_cone_friction: bool = False
    """PyBullet's implicit friction cone while the robot is free (False: the cheaper pyramid,
    two independent directions); near the object the cone is always on."""
    friction_anchor: bool = False
    """PyBullet's friction anchor on every link of URDF bodies (the robot)."""
    solver_residual_threshold: float = 1e-7
    """PyBullet's ``solverResidualThreshold``: the solver stops iterating once a pass changes
    the impulses by less than this (sum of squares). 1e-7 is PyBullet's own default."""

    @classmethod
    def of(
        cls, params: PhysicsParams | Mapping[str, Any] | None, timestep: float | None = None
    ) -> PhysicsParams:
        """``params`` itself, the defaults for None, or PhysicsParams from a dict of its fields
        (JSON-friendly, as ``gym.make(..., physics={...})`` and ``--physics NAME=VALUE`` pass
        it: whole-number fields take integral floats, flags 0 or 1). ``timestep``, if given,
        replaces the params' (the env sets it from ``physics_hz``). ValueError naming an
        unknown field and the allowed ones."""
        if params is None:
            params = cls()
        if isinstance(params, Mapping):
            fields = {f.name: f for f in dataclasses.fields(cls)}
            if timestep is not None and "timestep" in params:
                raise ValueError("physics cannot set timestep: the env's physics_hz sets it")
            allowed = [name for name in fields if timestep is None or name != "timestep"]
            unknown = sorted(set(params) - set(allowed))
            if unknown:
                names = ", ".join(allowed)
                raise ValueError(f"unknown physics settings {unknown}; allowed: {names}")
            params = cls(**{name: _coerce(fields[name].type, v) for name, v in params.items()})
        if not isinstance(params, cls):
            raise ValueError(f"physics must be a PhysicsParams or a dict, got {params!r}")
        return params if timestep is None else dataclasses.replace(params, timestep=timestep)

    def __post_init__(self) -> None:
        if not (np.isfinite(self.timestep) and 0 < self.timestep <= 0.01):
            raise ValueError(f"physics timestep must be in (0, 0.01] s, got {self.timestep}")
        for name in ("solver_iterations", "free_solver_iterations", "free_step_factor"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"{name} must be a whole number >= 1, got {value!r}")
        threshold = self.solver_residual_threshold
        number = isinstance(threshold, (int, float, np.number)) and not isinstance(threshold, bool)
        if not (number and np.isfinite(threshold) and 0 < threshold <= 0.01):
            raise ValueError(f"solver_residual_threshold must be in (0, 0.01], got {threshold}")
        for name in ("near_distance", "prism_margin"):
            value = getattr(self, name)
            if not (np.isfinite(value) and 0 <= value <= 0.5):
                raise ValueError(f"{name} must be in [0, 0.5] m, got {value}")
        for name in ("free_cone_friction", "friction_anchor"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise ValueError(f"{name} must be True or False, got {getattr(self, name)!r}")


ENV_VERSION_PHYSICS: dict[int, dict[str, Any]] = {0: {}, 1: {"friction_anchor": True}}
"""What each version of the registered environments sets in :class:`PhysicsParams` before
the caller's own settings: v0 the engine's defaults (every figure collected before v1);
v1 friction anchors on the robot's links, which keep a pressed fingertip from creeping over
small and heavy plates (docs/benchmarks.md, "Friction anchors")."""


def versioned_physics(
    version: int, settings: PhysicsParams | Mapping[str, Any] | None
) -> PhysicsParams | dict[str, Any]:
    """The physics of env version ``version`` with ``settings`` on top: a dict of
    PhysicsParams fields overrides single settings of the version's; a PhysicsParams is
    taken whole. ValueError for a version that does not exist."""
    if isinstance(version, bool) or version not in ENV_VERSION_PHYSICS:
        versions = ", ".join(str(v) for v in ENV_VERSION_PHYSICS)
        raise ValueError(f"version must be one of {versions}, got {version!r}")
    if isinstance(settings, PhysicsParams):
        return settings
    if settings is not None and not isinstance(settings, Mapping):
        raise ValueError(f"physics must be a PhysicsParams or a dict, got {settings!r}")
    return {**ENV_VERSION_PHYSICS[version], **(settings or {})}


def physics_overrides(settings: Mapping[str, Any] | None) -> dict[str, Any] | None:
    """``settings`` (PhysicsParams fields other than ``timestep``) checked and in JSON's own
    form (flags as bools, whole numbers as ints), as ``gym.make(..., physics=...)`` takes
    them; None for none. ValueError naming a bad field or value."""
    if not settings:
        return None
    params = PhysicsParams.of(settings, timestep=PhysicsParams.timestep)
    return {name: getattr(params, name) for name in settings}


def _coerce(kind: str, value: Any) -> Any:
    """A dict value for a PhysicsParams field of annotation ``kind``: 0/1 for flags
    and integral floats for whole numbers become bool and int (``--physics`` passes floats)."""
    if kind == "bool" and not isinstance(value, (bool, np.bool_)) and value in (0, 1):
        return bool(value)
    if kind == "int" and isinstance(value, float) and value.is_integer():
        return int(value)
    return value


class Simulation:
    """One PyBullet world. Bodies are created and looked up by name.

    Args:
        render_mode: ``None`` or ``"rgb_array"`` (headless, DIRECT) or ``"human"`` (GUI; a
            ValueError on a machine without a display, see :func:`check_render_mode`).
        physics: engine settings (:attr:`settings`); :attr:`physics` is what is in force
            (its ``timestep`` grows while the robot is free, see :meth:`adapt`).
    """

    def __init__(self, render_mode: str | None = None, physics: PhysicsParams | None = None):
        check_render_mode(render_mode)
        self.settings = physics or PhysicsParams()
        self.physics = self.settings
        self.render_mode = render_mode
        mode = pb.GUI if render_mode == "human" else pb.DIRECT
        with silenced_stdout():
            self.client = BulletClient(connection_mode=mode)
        if render_mode == "human":
            self.client.configureDebugVisualizer(pb.COV_ENABLE_GUI, 0)
        self.bodies: dict[str, int] = {}
        self._step = self.client.stepSimulation  # bound once: BulletClient wraps per access
        self.clear()

    # ------------------------------------------------------------------ world
    def clear(self) -> None:
        """Remove every body and restore the engine settings (a fresh world)."""
        c = self.client
        p = self.physics = self.settings
        c.resetSimulation()
        c.setGravity(0.0, 0.0, p.gravity)
        c.setPhysicsEngineParameter(
            fixedTimeStep=p.timestep,
            numSolverIterations=p.solver_iterations,
            solverResidualThreshold=p.solver_residual_threshold,
            deterministicOverlappingPairs=1,
        )
        self._mode: tuple[bool, int] | None = None  # (free, span) in force
        self.bodies.clear()

    def adapt(self, substeps: int, robot: str = "robot", obj: str = "object") -> int:
        """Settings for the next control period of ``substeps`` base physics steps; return
        how many base steps each physics step spans in it.

        Near (``robot`` within ``near_distance`` of ``obj``, or either body missing): the
        base ``timestep``, ``solver_iterations`` and PyBullet's friction cone; returns 1.
        Free: ``free_solver_iterations`` and ``free_cone_friction``, and steps
        ``free_step_factor`` times longer if that divides ``substeps`` and stays within
        10 ms (else 1); :attr:`physics` carries the timestep in force.
        """
        s = self.settings
        factor = s.free_step_factor
        free = (
            (factor > 1 or s.free_solver_iterations != s.solver_iterations)
            or not s.free_cone_friction
        ) and (
            robot in self.bodies
            and obj in self.bodies
            and not self.client.getClosestPoints(
                self.bodies[robot], self.bodies[obj], s.near_distance
            )
        )
        span = factor if free and substeps % factor == 0 and s.timestep * factor <= 0.01 else 1
        if (free, span) != self._mode:
            self.physics = s if span == 1 else dataclasses.replace(s, timestep=s.timestep * span)
            iterations = s.free_solver_iterations if free else s.solver_iterations
            self.client.setPhysicsEngineParameter(
                fixedTimeStep=self.physics.timestep,
                numSolverIterations=iterations,
                enableConeFriction=int(s.free_cone_friction or not free),
            )
            self._mode = (free, span)
        return span

    def step(self) -> None:
        self._step()

    def close(self) -> None:
        """Disconnect; safe to call twice."""
        if self.client._client >= 0:  # noqa: SLF001 - BulletClient has no public "connected"
            with contextlib.suppress(pb.error):
                self.client.disconnect()
        self.client._client = -1  # noqa: SLF001

    # ----------------------------------------------------------------- bodies
    def load_urdf(
        self,
        name: str,
        path: str | Path,
        position: Sequence[float] = (0.0, 0.0, 0.0),
        fixed_base: bool = True,
        flags: int = 0,
    ) -> int:
        with silenced_stdout():
            body = self.client.loadURDF(
                str(path), basePosition=list(position), useFixedBase=fixed_base, flags=flags
            )
        if self.settings.friction_anchor:
            for link in range(-1, self.client.getNumJoints(body)):
                self.client.changeDynamics(body, link, frictionAnchor=1)
        self.bodies[name] = body
        return body

    def create_prism_body(
        self,
        name: str,
        pieces: Sequence[np.ndarray],
        z_bottom: float,
        z_top: float,
        mass: float,
        position: Sequence[float] = (0.0, 0.0, 0.0),
        yaw: float = 0.0,
        rgba: Sequence[float] = (0.8, 0.3, 0.2, 1.0),
        lateral_friction: float = 0.5,
        spinning_friction: float = 0.0,
    ) -> int:
        """One rigid body whose collision shape is a union of convex prisms.

        ``pieces`` are (k, 2) convex vertex arrays in the body frame; each becomes a prism
        spanning ``z_bottom .. z_top``. The body frame is its centre of mass, so place the
        pieces around the origin. ``mass == 0`` makes a static body (a table).

        Any number of pieces works: they go to PyBullet as one OBJ file with one object per
        piece, which ``createCollisionShape`` turns into one compound of convex hulls (the
        same compound, child for child, as ``createCollisionShapeArray`` builds from one
        file per piece) and ``createVisualShape`` into one coloured mesh. The array calls
        are not used because PyBullet 3.2.7 keeps only their first 16 shapes (its
        ``MAX_COMPOUND_COLLISION_SHAPES``) without a word, and ``createVisualShapeArray``
        with ``rgbaColors`` for more than 16 shapes ends the process (segfault). The
        collision shape carries polyhedral features and ``PhysicsParams.prism_margin``.
        """
        c = self.client
        path = str(_prisms_obj_file(_check_pieces(pieces, name), z_bottom, z_top))
        with silenced_stdout():  # PyBullet's mesh loader prints a banner
            col = c.createCollisionShape(
                pb.GEOM_MESH, fileName=path, flags=pb.URDF_INITIALIZE_SAT_FEATURES
            )
            vis = c.createVisualShape(pb.GEOM_MESH, fileName=path, rgbaColor=list(rgba))
        body = c.createMultiBody(
            baseMass=mass,
            baseCollisionShapeIndex=col,
            baseVisualShapeIndex=vis,
            basePosition=list(position),
            baseOrientation=c.getQuaternionFromEuler([0.0, 0.0, yaw]),
        )
        c.changeDynamics(
            body,
            -1,
            lateralFriction=lateral_friction,
            spinningFriction=spinning_friction,
            rollingFriction=0.0,
            collisionMargin=self.physics.prism_margin,
        )
        self.bodies[name] = body
        return body

    def reset_base_pose(self, name: str, position: Sequence[float], yaw: float) -> None:
        c = self.client
        c.resetBasePositionAndOrientation(
            self.body(name), list(position), c.getQuaternionFromEuler([0.0, 0.0, yaw])
        )

    def body(self, name: str) -> int:
        try:
            return self.bodies[name]
        except KeyError:
            raise KeyError(f"no body named {name!r}; bodies: {sorted(self.bodies)}") from None

    def base_pose(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Position (3,) and quaternion xyzw (4,) of a body's base frame."""
        pos, orn = self.client.getBasePositionAndOrientation(self.body(name))
        return np.array(pos), np.array(orn)

    def base_velocity(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        lin, ang = self.client.getBaseVelocity(self.body(name))
        return np.array(lin), np.array(ang)

    def body_state(self, name: str) -> np.ndarray:
        """A free body's base position (3,), quaternion xyzw (4,), linear and angular
        velocity (3, 3), as one (13,) float64 vector."""
        c, body = self.client, self.body(name)
        pos, orn = c.getBasePositionAndOrientation(body)
        lin, ang = c.getBaseVelocity(body)
        return np.array([*pos, *orn, *lin, *ang], dtype=float)

    def set_body_state(self, name: str, state: np.ndarray) -> None:
        """Put a body in ``state`` (from :meth:`body_state`)."""
        c, body = self.client, self.body(name)
        s = [float(v) for v in state]
        c.resetBasePositionAndOrientation(body, s[:3], s[3:7])
        c.resetBaseVelocity(body, s[7:10], s[10:13])

    def drop_contacts(self) -> None:
        """Run a collision pass with the bodies already moved apart, so that PyBullet frees
        every contact manifold (with its cached points and warm-start impulses). A
        RuntimeError if any contact is left: the caller did not move everything apart."""
        self.client.performCollisionDetection()
        left = self.client.getContactPoints()
        if left:
            pairs = sorted({(p[1], p[3], p[2], p[4]) for p in left})
            raise RuntimeError(f"contacts left after moving the bodies apart: {pairs}")

    def contact_points(self, a: str, b: str, link_a: int | None = None) -> list:
        kwargs = {} if link_a is None else {"linkIndexA": link_a}
        return self.client.getContactPoints(self.body(a), self.body(b), **kwargs)

    def count_constraints(self) -> int:
        return self.client.getNumConstraints()


def check_render_mode(render_mode: str | None) -> None:
    """ValueError unless ``render_mode`` is None, ``"rgb_array"``, or ``"human"`` with a
    display to open a window on (PyBullet's GUI would otherwise end the whole process)."""
    if render_mode not in RENDER_MODES:
        raise ValueError(f"render_mode must be None, 'rgb_array' or 'human', got {render_mode!r}")
    if render_mode == "human" and not has_display():
        raise ValueError(
            "render_mode='human' opens a window, but this machine has no display (neither "
            "DISPLAY nor WAYLAND_DISPLAY is set); use render_mode='rgb_array' to render "
            "headless"
        )


def has_display() -> bool:
    """False on Linux (and other X11 systems) without DISPLAY or WAYLAND_DISPLAY; macOS and
    Windows always have one."""
    if sys.platform in ("darwin", "win32", "cygwin"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def _check_pieces(pieces: Sequence[np.ndarray], name: str) -> list[np.ndarray]:
    """The pieces as finite (k >= 3, 2) float arrays, or a ValueError naming the body."""
    out = []
    for i, piece in enumerate(pieces):
        try:
            arr = np.asarray(piece, dtype=float)
        except (TypeError, ValueError):
            arr = np.empty((0, 0))
        if arr.ndim != 2 or arr.shape[0] < 3 or arr.shape[1] != 2 or not np.isfinite(arr).all():
            raise ValueError(
                f"body {name!r}: piece {i} must be a finite (k >= 3, 2) array of x, y vertices"
            )
        out.append(arr)
    if not out:
        raise ValueError(f"body {name!r}: needs at least one convex piece")
    return out


def _prisms_obj_file(pieces: Sequence[np.ndarray], z_bottom: float, z_top: float) -> Path:
    """Write (once, cached by content) an OBJ file with one object (``o`` line) per convex
    piece, each a prism from ``z_bottom`` to ``z_top``; return its path."""
    if not (np.isfinite(z_bottom) and np.isfinite(z_top) and z_bottom < z_top):
        raise ValueError(f"prism needs finite z_bottom < z_top, got {z_bottom}, {z_top}")
    lines: list[str] = []
    first = 1  # OBJ vertex indices are 1-based and global over the file
    for n, piece in enumerate(pieces):
        k = len(piece)
        bottom = np.column_stack([piece, np.full(k, z_bottom)])
        top = np.column_stack([piece, np.full(k, z_top)])
        lines.append(f"o piece{n}")
        lines += [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in np.vstack([bottom, top])]
        faces = [[0, *range(k - 1, 0, -1)], list(range(k, 2 * k))]  # bottom down, top up
        faces += [[i, (i + 1) % k, (i + 1) % k + k, i + k] for i in range(k)]
        lines += ["f " + " ".join(str(first + v) for v in f) for f in faces]
        first += 2 * k
    text = "\n".join(lines) + "\n"
    digest = hashlib.sha1(text.encode()).hexdigest()[:20]
    path = _MESH_CACHE / f"prisms_{digest}.obj"
    if not path.exists():
        _MESH_CACHE.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(text)
        os.replace(tmp, path)
    return path
