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
import hashlib
import os
import sys
import tempfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

_LIBC = ctypes.CDLL(None)


@contextlib.contextmanager
def silenced_stdout() -> Iterator[None]:
    """Send file descriptor 1 to /dev/null: PyBullet's C code prints banners and URDF
    merge logs there, which would corrupt the JSON that ``slide-gym ... --json`` prints."""
    sys.stdout.flush()
    saved = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        yield
    finally:
        _LIBC.fflush(None)  # C stdio buffers what it printed; drop it while still silenced
        os.dup2(saved, 1)
        os.close(saved)
        os.close(devnull)


with silenced_stdout():
    import pybullet as pb
    from pybullet_utils.bullet_client import BulletClient

_MESH_CACHE = Path(tempfile.gettempdir()) / "slide_gym_meshes"


@dataclass(frozen=True)
class PhysicsParams:
    """Physics engine settings (SI units)."""

    timestep: float = 1.0 / 240.0
    # At PyBullet's default 50 iterations the friction solve does not converge: the pressed
    # fingertip creeps over the plate while dragging it, and expert slides lose the plate.
    solver_iterations: int = 100
    gravity: float = -9.81

    def __post_init__(self) -> None:
        if not (np.isfinite(self.timestep) and 0 < self.timestep <= 0.01):
            raise ValueError(f"physics timestep must be in (0, 0.01] s, got {self.timestep}")
        if self.solver_iterations < 1:
            raise ValueError(f"solver_iterations must be >= 1, got {self.solver_iterations}")


class Simulation:
    """One PyBullet world. Bodies are created and looked up by name.

    Args:
        render_mode: ``None`` or ``"rgb_array"`` (headless, DIRECT) or ``"human"`` (GUI).
        physics: engine settings.
    """

    def __init__(self, render_mode: str | None = None, physics: PhysicsParams | None = None):
        self.physics = physics or PhysicsParams()
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
        c.resetSimulation()
        c.setGravity(0.0, 0.0, self.physics.gravity)
        c.setPhysicsEngineParameter(
            fixedTimeStep=self.physics.timestep,
            numSolverIterations=self.physics.solver_iterations,
            deterministicOverlappingPairs=1,
        )
        self.bodies.clear()

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
        """
        c = self.client
        files = [str(_prism_obj_file(np.asarray(p, dtype=float), z_bottom, z_top)) for p in pieces]
        n = len(files)
        with silenced_stdout():  # PyBullet's mesh loader prints a banner
            col = c.createCollisionShapeArray(shapeTypes=[pb.GEOM_MESH] * n, fileNames=files)
            vis = c.createVisualShapeArray(
                shapeTypes=[pb.GEOM_MESH] * n, fileNames=files, rgbaColors=[list(rgba)] * n
            )
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

    def contact_points(self, a: str, b: str, link_a: int | None = None) -> list:
        kwargs = {} if link_a is None else {"linkIndexA": link_a}
        return self.client.getContactPoints(self.body(a), self.body(b), **kwargs)

    def count_constraints(self) -> int:
        return self.client.getNumConstraints()

    # ---------------------------------------------------------------- render
    def render(
        self,
        width: int = 480,
        height: int = 360,
        target: Sequence[float] = (0.45, 0.0, 0.15),
        distance: float = 1.35,
        yaw: float = 60.0,
        pitch: float = -30.0,
    ) -> np.ndarray:
        """An RGB image (height, width, 3) uint8 from the TinyRenderer (works headless)."""
        c = self.client
        view = c.computeViewMatrixFromYawPitchRoll(list(target), distance, yaw, pitch, 0.0, 2)
        proj = c.computeProjectionMatrixFOV(45.0, width / height, 0.05, 10.0)
        _, _, rgba, _, _ = c.getCameraImage(
            width, height, view, proj, renderer=pb.ER_TINY_RENDERER, shadow=1
        )
        return np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)[:, :, :3].copy()


def _prism_obj_file(piece: np.ndarray, z_bottom: float, z_top: float) -> Path:
    """Write (once, cached by content) an OBJ file of a convex prism; return its path."""
    k = len(piece)
    bottom = np.column_stack([piece, np.full(k, z_bottom)])
    top = np.column_stack([piece, np.full(k, z_top)])
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in np.vstack([bottom, top])]
    faces = [[1, *range(k, 1, -1)], list(range(k + 1, 2 * k + 1))]  # bottom down, top up
    faces += [[i + 1, (i + 1) % k + 1, (i + 1) % k + k + 1, i + k + 1] for i in range(k)]
    lines += ["f " + " ".join(map(str, f)) for f in faces]
    text = "\n".join(lines) + "\n"
    digest = hashlib.sha1(text.encode()).hexdigest()[:20]
    path = _MESH_CACHE / f"prism_{digest}.obj"
    if not path.exists():
        _MESH_CACHE.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(text)
        os.replace(tmp, path)
    return path
