"""Kinematics of the WAM arm with the T42 hand at rest, read from the URDF the simulator loads.

* :func:`urdf_joints` is the one URDF joint reader (also used by :mod:`slide_gym.robot.wam_t42`
  for the frames of merged fixed links), so the NumPy kinematics and PyBullet agree by
  construction.
* :class:`Chain` is the reference implementation: the serial chain from the URDF root to a
  tip link, evaluated joint by joint. Joints that are not active (the fingers) stay at zero.
* :class:`FastChain` compiles a :class:`Chain` for the planner's hot loops: every joint axis is
  turned onto z by a constant rotation folded into the neighbouring fixed transforms, so a
  joint rotation only mixes two rows of the transform that follows it. Results equal the
  reference to rounding, about ten times faster for one configuration.
* :func:`fingertip_chain` (finger A's contact frame) and :func:`grasp_chain` (between the
  resting fingertips) are the two frames the planner and the expert use, and ``SHOULDER``,
  ``WRIST_REACH``, ``WRIST_TO_GRASP`` bound the arm's reach.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from slide_gym.assets import robot_urdf
from slide_gym.robot.model import (
    ARM_JOINTS,
    BASE_TO_SHOULDER,
    DH,
    DISTAL_LENGTH,
    PIVOT_HEIGHT,
    PROXIMAL_LENGTH,
)

GRASP_DEPTH_IN_HAND = PIVOT_HEIGHT + PROXIMAL_LENGTH + DISTAL_LENGTH
"""Distance (m) along the flange z axis from the flange to the resting fingertips' apexes."""
WRIST_TO_GRASP = float(DH[6, 2]) + GRASP_DEPTH_IN_HAND
"""Distance (m) from the wrist centre (joints 5-7 axes) to the grasp frame, along the approach."""
SHOULDER = np.array([0.0, 0.0, BASE_TO_SHOULDER])
SHOULDER.setflags(write=False)
WRIST_REACH = float(np.hypot(DH[2, 0], DH[2, 2]) + np.hypot(DH[3, 0], DH[4, 2]))
"""Largest shoulder-to-wrist-centre distance (m) of the WAM (an upper bound)."""


# ----------------------------------------------------------------------------- URDF
@dataclass(frozen=True)
class UrdfJoint:
    """One ``<joint>`` of a URDF: its type, links, origin (xyz, rpy) and unit axis."""

    name: str
    type: str
    parent: str
    child: str
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]
    axis: tuple[float, float, float]

    @property
    def origin(self) -> np.ndarray:
        """The (4, 4) transform from the parent link frame to the joint frame."""
        t = np.eye(4)
        t[:3, :3] = rpy_matrix(*self.rpy)
        t[:3, 3] = self.xyz
        return t


def _floats(text: str | None, default: str) -> tuple[float, float, float]:
    x, y, z = (float(v) for v in (text or default).split())
    return x, y, z


@lru_cache(maxsize=4)
def urdf_joints(path: str | Path) -> tuple[UrdfJoint, ...]:
    """Every joint of the URDF at ``path``, in file order."""
    joints = []
    for j in ET.parse(path).getroot().findall("joint"):
        origin, axis = j.find("origin"), j.find("axis")
        xyz = _floats(None if origin is None else origin.get("xyz"), "0 0 0")
        rpy = _floats(None if origin is None else origin.get("rpy"), "0 0 0")
        a = np.array(_floats(None if axis is None else axis.get("xyz"), "0 0 1"))
        ax, ay, az = (float(v) for v in a / np.linalg.norm(a))
        joints.append(
            UrdfJoint(
                j.get("name"),
                j.get("type"),
                j.find("parent").get("link"),
                j.find("child").get("link"),
                xyz,
                rpy,
                (ax, ay, az),
            )
        )
    return tuple(joints)


def rpy_matrix(r: float, p: float, y: float) -> np.ndarray:
    """The rotation (3, 3) of URDF roll-pitch-yaw angles (Rz(y) Ry(p) Rx(r))."""
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def _axis_rotations(axis: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Rodrigues rotation matrices (..., 3, 3) about a unit ``axis`` by angles ``q`` (...)."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    s, c = np.sin(q)[..., None, None], np.cos(q)[..., None, None]
    return np.eye(3) + s * k + (1 - c) * (k @ k)


# ----------------------------------------------------------------------------- reference
@dataclass(frozen=True)
class ChainJoint:
    """A joint on a :class:`Chain`: origin, axis, and its index in q (-1: held at zero)."""

    name: str
    origin: np.ndarray  # (4, 4) parent link -> joint frame
    axis: np.ndarray  # (3,) unit, in the joint frame
    active: int


class Chain:
    """The serial chain from the URDF root to ``tip``; ``active`` joints are the inputs."""

    def __init__(self, joints: list[ChainJoint], n_active: int, tip: str):
        self.joints = joints
        self.n_active = n_active
        self.tip = tip

    @classmethod
    def from_urdf(cls, path: str | Path, tip: str, active: tuple[str, ...]) -> Chain:
        by_child = {j.child: j for j in urdf_joints(str(path))}
        chain: list[UrdfJoint] = []
        link = tip
        while link in by_child:
            chain.append(by_child[link])
            link = by_child[link].parent
        chain.reverse()
        missing = [a for a in active if a not in {j.name for j in chain}]
        if missing:
            raise ValueError(f"joints {missing} are not on the chain to {tip!r}")
        joints = [
            ChainJoint(
                j.name,
                j.origin,
                np.array(j.axis),
                active.index(j.name)
                if j.type in ("revolute", "continuous") and j.name in active
                else -1,
            )
            for j in chain
        ]
        return cls(joints, len(active), tip)

    def _check(self, q: np.ndarray) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        if q.shape[-1] != self.n_active:
            raise ValueError(
                f"expected {self.n_active} joint angles in the last axis, got {q.shape}"
            )
        return q

    def _rotation(self, j: ChainJoint, q: np.ndarray) -> np.ndarray:
        rot = np.zeros((*q.shape[:-1], 4, 4))
        rot[..., :3, :3] = _axis_rotations(j.axis, q[..., j.active])
        rot[..., 3, 3] = 1.0
        return rot

    def forward(self, q: np.ndarray) -> np.ndarray:
        """Pose (..., 4, 4) of the tip frame in the root frame for joint angles (..., n)."""
        return self.jacobian(q)[0]

    def jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Tip pose (..., 4, 4) and geometric Jacobian (..., 6, n), rows [v; omega], root frame."""
        q = self._check(q)
        batch = q.shape[:-1]
        t = np.broadcast_to(np.eye(4), (*batch, 4, 4)).copy()
        axes = np.zeros((*batch, self.n_active, 3))
        points = np.zeros((*batch, self.n_active, 3))
        for j in self.joints:
            t = t @ j.origin
            if j.active >= 0:
                axes[..., j.active, :] = t[..., :3, :3] @ j.axis
                points[..., j.active, :] = t[..., :3, 3]
                t = t @ self._rotation(j, q)
        tip = t[..., None, :3, 3]
        jac = np.concatenate([np.cross(axes, tip - points), axes], axis=-1)  # (..., n, 6)
        return t, np.swapaxes(jac, -1, -2)


# ----------------------------------------------------------------------------- compiled
def _align_z(axis: np.ndarray) -> np.ndarray:
    """A rotation (3, 3) whose z column is the unit ``axis``."""
    z = axis / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


class FastChain:
    """Compiled kinematics of ``chain`` (tip pose in the root frame), optional tip offset.

    Args:
        chain: the URDF chain (joints not listed as active are held at zero).
        tip_offset: a fixed (4, 4) transform appended after the chain's tip frame.
    """

    def __init__(self, chain: Chain, tip_offset: np.ndarray | None = None):
        self.n = chain.n_active
        self.tip = chain.tip
        fixed: list[np.ndarray] = []  # fixed[i]: transform before active joint i (z-aligned)
        acc = np.eye(4)
        order: list[int] = []
        for j in chain.joints:
            acc = acc @ j.origin
            if j.active >= 0:
                align = np.eye(4)
                align[:3, :3] = _align_z(j.axis)
                fixed.append(acc @ align)
                acc = align.T.copy()
                order.append(j.active)
        if sorted(order) != list(range(self.n)):
            raise ValueError("FastChain needs each active joint exactly once along the chain")
        self.order = np.array(order)
        self._in_order = bool((self.order == np.arange(self.n)).all())
        if tip_offset is not None:
            acc = acc @ np.asarray(tip_offset, dtype=float)
        self.fixed = np.array(fixed)
        self.tip_tf = acc
        self._after = np.concatenate([self.fixed[1:], acc[None]])  # (n, 4, 4)
        # Plain-float copies for one configuration at a time (see _run_one).
        self._order_list: list[int] = self.order.tolist()
        self._first_rows: list[list[float]] = self.fixed[0][:3].tolist()
        self._after_rows: list[list[list[float]]] = self._after[:, :3].tolist()

    def forward(self, q: np.ndarray) -> np.ndarray:
        """Tip pose (..., 4, 4) for joint angles (..., n)."""
        return self._run(q, want_jac=False)[0]

    def jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Tip pose (..., 4, 4) and geometric Jacobian (..., 6, n), rows [v; omega]."""
        t, jac = self._run(q, want_jac=True)
        assert jac is not None
        return t, jac

    def _run(self, q: np.ndarray, want_jac: bool) -> tuple[np.ndarray, np.ndarray | None]:
        q = np.asarray(q, dtype=float)
        if q.shape[-1] != self.n:
            raise ValueError(f"expected {self.n} joint angles in the last axis, got {q.shape}")
        if q.ndim == 1:
            return self._run_one(q.tolist(), want_jac)
        qs = q if self._in_order else q[..., self.order]
        c, s = np.cos(qs), np.sin(qs)
        # Rz(q_k) @ after_k only mixes the first two rows of the fixed part after joint k.
        after = self._after
        links = np.empty((*q.shape[:-1], self.n, 4, 4))
        c, s = c[..., None], s[..., None]
        links[..., 0, :] = c * after[:, 0, :] - s * after[:, 1, :]
        links[..., 1, :] = s * after[:, 0, :] + c * after[:, 1, :]
        links[..., 2:, :] = after[:, 2:, :]
        t = self.fixed[0]
        batch = q.shape[:-1]
        frames = np.empty((*batch, self.n, 3, 2)) if want_jac else None
        for k in range(self.n):
            if frames is not None:
                frames[..., k, :, :] = t[..., :3, 2:]  # joint axis (z) and origin
            t = t @ links[..., k, :, :]
        if frames is None:
            return t, None
        a = frames[..., 0]
        d = t[..., None, :3, 3] - frames[..., 1]
        jac = np.empty((*batch, 6, self.n))
        ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
        dx, dy, dz = d[..., 0], d[..., 1], d[..., 2]
        o = slice(None) if self._in_order else self.order
        jac[..., 0, o] = ay * dz - az * dy
        jac[..., 1, o] = az * dx - ax * dz
        jac[..., 2, o] = ax * dy - ay * dx
        jac[..., 3:, o] = np.swapaxes(a, -1, -2)
        return t, jac

    def _run_one(self, q: list[float], want_jac: bool) -> tuple[np.ndarray, np.ndarray | None]:
        """:meth:`_run` for one configuration in plain floats: NumPy's per-call overhead
        dominates 4x4 products, so this is ~2.5x faster than a batch of one (the planner's
        projection calls it once per Newton step)."""
        (a00, a01, a02, a03), (a10, a11, a12, a13), (a20, a21, a22, a23) = self._first_rows
        axes: list[tuple[float, ...]] = []
        for k, j in enumerate(self._order_list):
            axes.append((a02, a12, a22, a03, a13, a23))  # joint k's axis (z) and origin
            c, s = math.cos(q[j]), math.sin(q[j])
            b00, b01 = c * a00 + s * a01, c * a01 - s * a00  # (t @ Rz(q)) first two columns
            b10, b11 = c * a10 + s * a11, c * a11 - s * a10
            b20, b21 = c * a20 + s * a21, c * a21 - s * a20
            (m00, m01, m02, m03), (m10, m11, m12, m13), (m20, m21, m22, m23) = self._after_rows[k]
            a00, a01, a02, a03 = (
                b00 * m00 + b01 * m10 + a02 * m20,
                b00 * m01 + b01 * m11 + a02 * m21,
                b00 * m02 + b01 * m12 + a02 * m22,
                b00 * m03 + b01 * m13 + a02 * m23 + a03,
            )
            a10, a11, a12, a13 = (
                b10 * m00 + b11 * m10 + a12 * m20,
                b10 * m01 + b11 * m11 + a12 * m21,
                b10 * m02 + b11 * m12 + a12 * m22,
                b10 * m03 + b11 * m13 + a12 * m23 + a13,
            )
            a20, a21, a22, a23 = (
                b20 * m00 + b21 * m10 + a22 * m20,
                b20 * m01 + b21 * m11 + a22 * m21,
                b20 * m02 + b21 * m12 + a22 * m22,
                b20 * m03 + b21 * m13 + a22 * m23 + a23,
            )
        t = np.array(
            [[a00, a01, a02, a03], [a10, a11, a12, a13], [a20, a21, a22, a23], [0.0, 0.0, 0.0, 1.0]]
        )
        if not want_jac:
            return t, None
        jac = [[0.0] * self.n for _ in range(6)]
        for (zx, zy, zz, px, py, pz), j in zip(axes, self._order_list, strict=True):
            dx, dy, dz = a03 - px, a13 - py, a23 - pz
            jac[0][j] = zy * dz - zz * dy
            jac[1][j] = zz * dx - zx * dz
            jac[2][j] = zx * dy - zy * dx
            jac[3][j], jac[4][j], jac[5][j] = zx, zy, zz
        return t, np.array(jac)


# ----------------------------------------------------------------------------- the robot
@lru_cache(maxsize=4)
def robot_chain(tip: str = "fingertip_contact") -> Chain:
    """The reference arm chain to a URDF link (default finger A's contact frame), hand at rest."""
    return Chain.from_urdf(robot_urdf(), tip, tuple(ARM_JOINTS))


@lru_cache(maxsize=8)
def fast_chain(tip: str = "fingertip_contact") -> FastChain:
    """The compiled arm chain to a URDF link (hand at rest), cached per tip."""
    return FastChain(robot_chain(tip))


def fingertip_chain() -> FastChain:
    """Kinematics of the ``fingertip_contact`` frame (finger A's contact, hand at rest)."""
    return fast_chain("fingertip_contact")


@lru_cache(maxsize=1)
def grasp_chain() -> FastChain:
    """Kinematics of the grasp frame: flange axes, origin midway between the fingertip apexes.

    Its y axis is the finger-spacing axis (finger A at +y), z the approach direction.
    """
    offset = np.eye(4)
    offset[2, 3] = GRASP_DEPTH_IN_HAND
    return FastChain(robot_chain("wam_flange"), offset)


MIRROR_SIGNS = np.array([-1.0, 1.0, -1.0, 1.0, -1.0, 1.0, -1.0])
"""Negating joints 1, 3, 5 and 7 mirrors the WAM's pose in the base's xz plane."""


def mirrored_postures(q: np.ndarray) -> np.ndarray:
    """``q`` (7,), its mirror image in the base's xz plane, and both with the hand turned half
    a revolution about its approach axis (joint 7 +- pi, palm up and down): (4, 7).

    Side grasps of a plate on either side of the base, palm up or down, each have one of these
    postures nearby, so "the IK solution nearest them" picks the same branch for all.
    """
    q = np.asarray(q, dtype=float)
    if q.shape != (7,) or not np.isfinite(q).all():
        raise ValueError(f"a posture is 7 finite joint angles, got {q!r}")
    both = np.stack([q, q * MIRROR_SIGNS])
    turned = both.copy()
    turned[:, 6] -= np.copysign(math.pi, turned[:, 6])  # the half turn that stays in +-pi
    return np.vstack([both, turned])
