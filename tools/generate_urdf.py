"""Write ``urdf/wam_t42.urdf`` from the numeric model in :mod:`slide_gym.robot.model`.

Run ``python tools/generate_urdf.py`` after changing the model; the test suite checks that
the committed URDF equals :func:`build_urdf`'s output. Inertias are computed from the
collision primitives (uniform density scaled to each link's mass).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from slide_gym.robot import model as m  # noqa: E402

OUTPUT = Path(__file__).resolve().parents[1] / "urdf" / "wam_t42.urdf"
FRAME_MASS = 1e-3  # kg, the massless frames (flange, fingertip) get a token mass
FRAME_INERTIA = 1e-8  # kg m^2
_COLORS = {"wam": "0.75 0.75 0.78 1", "t42": "0.15 0.15 0.15 1", "pad": "0.9 0.45 0.1 1"}


def _f(x: float) -> str:
    s = f"{float(x):.9g}"
    return "0" if s == "-0" else s


def _v(xs: Sequence[float]) -> str:
    return " ".join(_f(x) for x in xs)


def _rot(rpy: Sequence[float]) -> np.ndarray:
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    return rz @ ry @ rx


def _rpy(rot: np.ndarray) -> tuple[float, float, float]:
    """URDF roll-pitch-yaw of a rotation matrix (R = Rz(y) Ry(p) Rx(r))."""
    pitch = float(np.arcsin(np.clip(-rot[2, 0], -1.0, 1.0)))
    roll = float(np.arctan2(rot[2, 1], rot[2, 2]))
    yaw = float(np.arctan2(rot[1, 0], rot[0, 0]))
    return roll, pitch, yaw


def _shape_volume_inertia(s: m.Shape) -> tuple[float, np.ndarray]:
    """Volume and unit-density inertia about the shape's centre, in its own frame."""
    if s.kind == "box":
        x, y, z = s.size
        vol = x * y * z
        diag = vol / 12 * np.array([y * y + z * z, x * x + z * z, x * x + y * y])
    elif s.kind == "cylinder":
        r, h = s.size
        vol = np.pi * r * r * h
        side = vol * (3 * r * r + h * h) / 12
        diag = np.array([side, side, vol * r * r / 2])
    else:
        raise ValueError(f"unknown shape kind {s.kind!r}")
    return vol, np.diag(diag)


def mass_properties(shapes: Sequence[m.Shape], mass: float) -> tuple[np.ndarray, np.ndarray]:
    """Centre of mass (3,) and inertia about it (3, 3) of uniform-density primitives."""
    parts = [(_shape_volume_inertia(s), np.array(s.xyz), _rot(s.rpy)) for s in shapes]
    volume = sum(vol for (vol, _), _, _ in parts)
    com = sum(vol * c for (vol, _), c, _ in parts) / volume
    inertia = np.zeros((3, 3))
    for (vol, i_local), c, rot in parts:
        d = c - com
        inertia += rot @ i_local @ rot.T + vol * (d @ d * np.eye(3) - np.outer(d, d))
    return com, inertia * (mass / volume)


def _geometry(s: m.Shape) -> str:
    if s.kind == "box":
        return f'<box size="{_v(s.size)}"/>'
    return f'<cylinder radius="{_f(s.size[0])}" length="{_f(s.size[1])}"/>'


def _link(name: str, mass: float, shapes: Sequence[m.Shape] = (), color: str = "") -> list[str]:
    out = [f'  <link name="{name}">']
    if shapes:
        com, inertia = mass_properties(shapes, mass)
        off = inertia - np.diag(np.diag(inertia))
        if np.abs(off).max() <= 1e-12 * np.trace(inertia):
            rpy, (ixx, iyy, izz) = (0.0, 0.0, 0.0), np.diag(inertia)
        else:  # principal axes (PyBullet uses the diagonal only)
            values, vectors = np.linalg.eigh(inertia)
            if np.linalg.det(vectors) < 0:
                vectors[:, 0] *= -1
            rpy, (ixx, iyy, izz) = _rpy(vectors), values
    else:
        com, rpy, ixx = np.zeros(3), (0.0, 0.0, 0.0), FRAME_INERTIA
        iyy = izz = ixx
    out += [
        "    <inertial>",
        f'      <origin xyz="{_v(com)}" rpy="{_v(rpy)}"/>',
        f'      <mass value="{_f(mass)}"/>',
        f'      <inertia ixx="{_f(ixx)}" ixy="0" ixz="0" iyy="{_f(iyy)}" iyz="0" izz="{_f(izz)}"/>',
        "    </inertial>",
    ]
    for tag in ("visual", "collision"):
        for s in shapes:
            out.append(f"    <{tag}>")
            out.append(f'      <origin xyz="{_v(s.xyz)}" rpy="{_v(s.rpy)}"/>')
            out.append(f"      <geometry>{_geometry(s)}</geometry>")
            if tag == "visual":
                material = f'<material name="{name}_color"><color rgba="{color}"/></material>'
                out.append(f"      {material}")
            out.append(f"    </{tag}>")
    if name.endswith(("proximal_link", "distal_link")):
        out += [
            "    <contact>",
            f'      <lateral_friction value="{_f(m.PAD_FRICTION)}"/>',
            '      <rolling_friction value="0"/>',
            '      <spinning_friction value="0.003"/>',
            "    </contact>",
        ]
    out.append("  </link>")
    return out


def _joint(
    name: str,
    parent: str,
    child: str,
    xyz: Sequence[float] = (0.0, 0.0, 0.0),
    rpy: Sequence[float] = (0.0, 0.0, 0.0),
    limits: tuple[float, float, float, float] | None = None,
    axis: str = "0 0 1",
) -> list[str]:
    kind = "fixed" if limits is None else "revolute"
    out = [
        f'  <joint name="{name}" type="{kind}">',
        f'    <parent link="{parent}"/>',
        f'    <child link="{child}"/>',
        f'    <origin xyz="{_v(xyz)}" rpy="{_v(rpy)}"/>',
    ]
    if limits is not None:
        lower, upper, effort, velocity = limits
        out += [
            f'    <axis xyz="{axis}"/>',
            f'    <limit lower="{_f(lower)}" upper="{_f(upper)}" effort="{_f(effort)}" '
            f'velocity="{_f(velocity)}"/>',
            '    <dynamics damping="0" friction="0"/>',
        ]
    out.append("  </joint>")
    return out


def _arm() -> list[str]:
    out = _link("wam_base", 10.0, m.LINK_SHAPES["wam_base"], _COLORS["wam"])
    parent, xyz, rpy = "wam_base", (0.0, 0.0, m.BASE_TO_SHOULDER), (0.0, 0.0, 0.0)
    for i, (a, alpha, d) in enumerate(m.DH):
        child = f"wam_link{i + 1}"
        lim = (m.ARM_LOWER[i], m.ARM_UPPER[i], m.ARM_TORQUE_LIMITS[i], m.ARM_VELOCITY_LIMITS[i])
        out += _joint(m.ARM_JOINTS[i], parent, child, xyz, rpy, lim)
        out += _link(child, m.ARM_MASSES[i], m.LINK_SHAPES[child], _COLORS["wam"])
        parent, xyz, rpy = child, (a, 0.0, d), (alpha, 0.0, 0.0)
    out += _joint("wam_flange_joint", parent, "wam_flange", xyz, rpy)
    out += _link("wam_flange", FRAME_MASS)
    return out


def _finger(side: str, y: float, yaw: float) -> list[str]:
    prox, dist = f"t42_{side}_proximal_link", f"t42_{side}_distal_link"
    i = 0 if side == "a" else 2
    lim_p = (m.FINGER_LOWER[i], m.FINGER_UPPER[i], 10.0, 20.0)
    lim_d = (m.FINGER_LOWER[i + 1], m.FINGER_UPPER[i + 1], 10.0, 20.0)
    tip = "fingertip_contact" if side == "a" else "t42_b_fingertip"
    out = _joint(
        f"t42_{side}_proximal",
        "t42_palm",
        prox,
        (0, y, m.PIVOT_HEIGHT),
        (0, 0, yaw),
        lim_p,
        axis="1 0 0",
    )
    out += _link(prox, m.PROXIMAL_MASS, m.LINK_SHAPES["proximal"], _COLORS["t42"])
    out += _joint(
        f"t42_{side}_distal", prox, dist, (0, 0, m.PROXIMAL_LENGTH), limits=lim_d, axis="1 0 0"
    )
    out += _link(dist, m.DISTAL_MASS, m.LINK_SHAPES["distal"], _COLORS["pad"])
    out += _joint(f"{tip}_joint", dist, tip, (0, 0, m.DISTAL_LENGTH))
    out += _link(tip, FRAME_MASS)
    return out


def build_urdf() -> str:
    """The URDF text of the WAM + T42 model."""
    lines = [
        '<?xml version="1.0"?>',
        "<!-- Generated by tools/generate_urdf.py from slide_gym/robot/model.py. -->",
        "<!-- Do not edit by hand: change the model and re-run the generator. -->",
        '<robot name="wam_t42">',
    ]
    lines += _arm()
    lines += _joint("t42_palm_joint", "wam_flange", "t42_palm")
    lines += _link("t42_palm", m.PALM_MASS, m.LINK_SHAPES["t42_palm"], _COLORS["t42"])
    lines += _finger("a", m.FINGER_BASE_SPACING / 2, 0.0)
    lines += _finger("b", -m.FINGER_BASE_SPACING / 2, np.pi)
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


def main() -> None:
    OUTPUT.parent.mkdir(parents=True, exist_ok=True)
    OUTPUT.write_text(build_urdf())
    print(f"wrote {OUTPUT}")


if __name__ == "__main__":
    main()
