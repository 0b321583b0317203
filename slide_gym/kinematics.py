"""Vectorised forward kinematics and Jacobians of a serial URDF chain (hand at rest).

The chain is read from the URDF that the simulator loads, so the NumPy kinematics and
PyBullet agree by construction. Joints that are not listed as active (the finger joints) are
held at zero, the hand's rest configuration.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from slide_gym.assets import robot_urdf


def _rpy_matrix(r: float, p: float, y: float) -> np.ndarray:
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


@dataclass(frozen=True)
class _Joint:
    name: str
    origin: np.ndarray  # (4, 4) parent link -> joint frame
    axis: np.ndarray  # (3,) in the joint frame
    active: int  # index into q, or -1 for a joint held at zero / fixed


class Chain:
    """The serial chain from the URDF root to ``tip``; ``active`` joints are the inputs."""

    def __init__(self, joints: list[_Joint], n_active: int, tip: str):
        self.joints = joints
        self.n_active = n_active
        self.tip = tip

    @classmethod
    def from_urdf(cls, path: str | Path, tip: str, active: tuple[str, ...]) -> Chain:
        root = ET.parse(path).getroot()
        by_child = {j.find("child").get("link"): j for j in root.findall("joint")}
        chain: list[ET.Element] = []
        link = tip
        while link in by_child:
            joint = by_child[link]
            chain.append(joint)
            link = joint.find("parent").get("link")
        chain.reverse()
        names = [j.get("name") for j in chain]
        missing = [a for a in active if a not in names]
        if missing:
            raise ValueError(f"joints {missing} are not on the chain to {tip!r}")
        joints = []
        for j in chain:
            origin = j.find("origin")
            xyz = [
                float(v)
                for v in (origin.get("xyz", "0 0 0") if origin is not None else "0 0 0").split()
            ]
            rpy = [
                float(v)
                for v in (origin.get("rpy", "0 0 0") if origin is not None else "0 0 0").split()
            ]
            t = np.eye(4)
            t[:3, :3] = _rpy_matrix(*rpy)
            t[:3, 3] = xyz
            axis_el = j.find("axis")
            axis = (
                np.array([float(v) for v in axis_el.get("xyz").split()])
                if axis_el is not None
                else np.array([0.0, 0.0, 1.0])
            )
            is_active = j.get("type") in ("revolute", "continuous") and j.get("name") in active
            joints.append(
                _Joint(
                    j.get("name"),
                    t,
                    axis / np.linalg.norm(axis),
                    active.index(j.get("name")) if is_active else -1,
                )
            )
        return cls(joints, len(active), tip)

    def _check(self, q: np.ndarray) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        if q.shape[-1] != self.n_active:
            raise ValueError(
                f"expected {self.n_active} joint angles in the last axis, got {q.shape}"
            )
        return q

    def forward(self, q: np.ndarray) -> np.ndarray:
        """Pose (..., 4, 4) of the tip frame in the root frame for joint angles (..., n)."""
        q = self._check(q)
        t = np.broadcast_to(np.eye(4), (*q.shape[:-1], 4, 4)).copy()
        for j in self.joints:
            t = t @ j.origin
            if j.active >= 0:
                rot = np.zeros((*q.shape[:-1], 4, 4))
                rot[..., :3, :3] = _axis_rotations(j.axis, q[..., j.active])
                rot[..., 3, 3] = 1.0
                t = t @ rot
        return t

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
                rot = np.zeros((*batch, 4, 4))
                rot[..., :3, :3] = _axis_rotations(j.axis, q[..., j.active])
                rot[..., 3, 3] = 1.0
                t = t @ rot
        tip = t[..., None, :3, 3]
        jac = np.concatenate([np.cross(axes, tip - points), axes], axis=-1)  # (..., n, 6)
        return t, np.swapaxes(jac, -1, -2)


@lru_cache(maxsize=4)
def robot_chain(tip: str = "fingertip_contact") -> Chain:
    """The WAM arm chain to ``tip`` (default the sliding finger's contact frame), hand at rest."""
    from slide_gym.robot.model import ARM_JOINTS

    return Chain.from_urdf(robot_urdf(), tip, tuple(ARM_JOINTS))
