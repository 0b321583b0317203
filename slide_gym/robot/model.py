"""Numeric model of the Barrett WAM 7-DOF arm with a Yale T42 hand (SI units).

Everything the URDF generator (``tools/generate_urdf.py``) and :class:`WamT42` need lives
here, so the URDF follows the DH table exactly.

Frames
------
* World: origin at the WAM base mounting point, z up, x toward the tables.
* ``wam_base``: the URDF root, coincides with the world frame.
* DH frame 0 sits ``BASE_TO_SHOULDER`` above the base, axes parallel to the world.
  URDF joint ``wam_j{i}`` sits at DH frame i-1 and turns about its z axis; its child link
  ``wam_link{i}`` is DH frame i-1 rotated by theta_i. The fixed part of row i
  (Tz(d) Tx(a) Rx(alpha)) is the origin of the next joint.
* ``wam_flange``: exactly DH frame 7 (z = approach direction out of the wrist).
* ``t42_palm``: the flange frame; the palm plate spans z in [0, PALM_SIZE[2]].
  The two finger pivots sit at y = +/- FINGER_BASE_SPACING / 2 (finger A at +y,
  finger B at -y), PIVOT_HEIGHT above the flange face.
* Finger links ``t42_{a,b}_{proximal,distal}_link``: origin on the joint axis, x along the
  joint axis (and the finger width), z along the finger toward the tip, -y toward the other
  finger (the pad side). Finger B's frames are finger A's turned by pi about the palm z.
  Positive joint angles close a finger; at q = 0 both fingers are straight along flange z.
* ``fingertip_contact``: on finger A's distal link, at the apex of the rounded tip, middle of
  the finger width. X_F = joint axis (a positive rotation about X_F closes the finger),
  Z_F = distal long axis out of the tip, Y_F = Z_F x X_F (the back of the finger, so -Y_F
  is the pad normal). ``t42_b_fingertip`` is the same point on finger B.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# ----------------------------------------------------------------------------- WAM arm
ARM_JOINTS: tuple[str, ...] = tuple(f"wam_j{i}" for i in range(1, 8))
BASE_TO_SHOULDER = 0.346
"""Height of the shoulder axes (DH frame 0) above the base mounting face (m)."""

DH = np.array(
    [  # a (m), alpha (rad), d (m): standard (Spong) DH, T = Rz(q) Tz(d) Tx(a) Rx(alpha)
        [0.0, -np.pi / 2, 0.0],
        [0.0, np.pi / 2, 0.0],
        [0.045, -np.pi / 2, 0.55],
        [-0.045, np.pi / 2, 0.0],
        [0.0, -np.pi / 2, 0.30],
        [0.0, np.pi / 2, 0.0],
        [0.0, 0.0, 0.06],
    ]
)
DH.setflags(write=False)

ARM_LOWER = np.array([-2.6, -2.0, -2.8, -0.9, -4.76, -1.6, -3.0])
ARM_UPPER = np.array([2.6, 2.0, 2.8, 3.1, 1.24, 1.6, 3.0])
ARM_TORQUE_LIMITS = np.array([25.0, 20.0, 15.0, 15.0, 5.0, 5.0, 5.0])
"""N m: limit of the joint position controller's output (the motor's correction), Barrett's
``control_signal_limit`` of ``joint_position_control`` for the 7-DOF WAM (libbarrett,
``config/wam7w.conf``). As on the real arm, gravity compensation is added outside this limit:
joint 2 alone needs 21.7 N m at READY_ARM_Q and up to ~28 N m in the expert's episodes."""
ARM_PEAK_TORQUES = np.array([82.1, 109.5, 65.2, 31.2, 12.4, 12.4, 2.2])
"""N m: the most torque a joint can ever take, motor plus gravity feedforward together: the
Pucks' motor current limits through each joint's transmission, as computed in Barrett's
open-source WAM driver OWD (``openwam/Joint.cc``, ``MAX_MECHANICAL_TORQ_EXPECTED``; bounded by
the cables' breaking strength). :class:`~slide_gym.robot.wam_t42.WamT42` caps the motor of
joint i at ``min(ARM_TORQUE_LIMITS[i], ARM_PEAK_TORQUES[i] - |feedforward_i|)``."""
ARM_VELOCITY_LIMITS = np.full(7, 2.0)
ARM_MASSES = (10.77, 3.87, 1.80, 2.17, 0.36, 0.41, 0.08)
BASE_SIZE = (0.36, 0.28, 0.16)
BASE_CENTER = (0.0, 0.0, 0.08)  # x extent -0.18 .. 0.18: clear of the tables (x > 0.25)

READY_ARM_Q = np.array([0.0, 0.9801, 0.0, 2.1710, 0.0, -0.0096, 1.5708])
"""Hand straight down, finger A's tip 0.12 m above the table top at (0.55, 0).

Found at development time by Gauss-Newton IK on the DH model plus the hand offsets
(joints 1, 3, 5 held at 0, elbow up; flange z = -world z, flange x = world +y so the finger
joint axes lie along world y and finger A sits on the far, +x, side), rounded to 1e-4 rad
and checked in PyBullet (flange at (0.524, 0, 0.254), no contacts).
"""
for _a in (
    ARM_LOWER,
    ARM_UPPER,
    ARM_TORQUE_LIMITS,
    ARM_PEAK_TORQUES,
    ARM_VELOCITY_LIMITS,
    READY_ARM_Q,
):
    _a.setflags(write=False)

# ----------------------------------------------------------------------------- T42 hand
FINGER_JOINTS: tuple[str, ...] = (
    "t42_a_proximal",
    "t42_a_distal",
    "t42_b_proximal",
    "t42_b_distal",
)
FINGER_LOWER = np.array([-0.2, -0.2, -0.2, -0.2])
"""Lower finger limits: the public 0-rad stops less a 0.2 rad margin, so a contact can
push a finger open (outward) instead of meeting a hard stop at the rest pose."""
FINGER_UPPER = np.array([3.0, 1.57, 3.0, 1.57])
for _a in (FINGER_LOWER, FINGER_UPPER):
    _a.setflags(write=False)

PALM_SIZE = (0.088, 0.109, 0.009)  # x (finger width direction), y (finger spacing), z
PALM_MASS = 0.30  # palm plate plus the servo housing it carries (estimate)
FINGER_BASE_SPACING = 0.052
PIVOT_HEIGHT = 0.024  # proximal pivots above the flange face (mounting blocks on the palm)
FINGER_WIDTH = 0.03175
PROXIMAL_LENGTH = 0.0625  # pivot to pivot
PROXIMAL_THICKNESS = 0.020
PROXIMAL_MASS = 0.019
DISTAL_LENGTH = 0.048  # pivot to tip apex
TIP_RADIUS = 0.0105  # rounded tip: half-cylinder whose axis runs along the finger width
DISTAL_THICKNESS = 2 * TIP_RADIUS
PINCH_DEPTH = 0.015
"""How far (m) the fingertips reach onto a plate's overhang in a side pinch: the rounded tip
(arc radius TIP_RADIUS) and a few millimetres of pad behind it."""
PINCH_EDGE_CLEARANCE = 0.005
"""Least gap (m) between the pinching fingertips and the table's edge face."""
MIN_CONTACT_SIZE = PINCH_DEPTH + PINCH_EDGE_CLEARANCE
"""The hand's minimum contact size u* (m): the least overhang past a table edge that a side
pinch can close on. Plates of any size share it (it is the hand's, not the plate's)."""
DISTAL_MASS = 0.024
PAD_FRICTION = 1.25
"""Pad lateral friction. PyBullet multiplies coefficients: with the object's 0.8 this gives
1.0, rubber on plastic; the object on the table gets 0.8 x 0.4 = 0.32, plastic on laminate."""
TENDON_RATIO = np.array([1.0, 0.5])
"""Tendon torque per unit f_max on (proximal, distal) of each finger."""
TENDON_RATIO.setflags(write=False)


@dataclass(frozen=True)
class HandParams:
    """Spring/tendon model of each finger joint (SI units).

    Per finger: ``tau = R * f_max * u - K (q - q0) - D dq`` with ``R = TENDON_RATIO``,
    ``K = (k_proximal, 2 k_proximal)`` and ``D = (d_proximal, d_distal)``. ``u`` here is the
    servo's tendon level, which follows the commanded u at ``u_rate`` per second.
    """

    k_proximal: float = 1.2  # N m/rad (tuning): 2-4 N up on a 60-deg tip -> 1.1-2.2 cm
    distal_stiffness_ratio: float = 2.0  # K_d / K_p, as public T42 simulations use
    d_proximal: float = 0.05  # N m s/rad (tuning): relaxation time D/K about 40 ms
    d_distal: float = 0.05  # N m s/rad (tuning): about 20 ms
    f_max: float = 2.4  # N m tendon torque at u = 1 (tuning): free proximal angle 2 rad
    u_rate: float = 4.0  # 1/s (tuning): servo speed, u reaches a new command at this rate
    q0_proximal: float = 0.0  # rest angles (rad)
    q0_distal: float = 0.0
    implicit: bool = True  # integrate spring and damper implicitly (see wam_t42.py)

    def __post_init__(self) -> None:
        values = (self.k_proximal, self.distal_stiffness_ratio, self.f_max)
        if not all(np.isfinite(v) and v > 0 for v in values):
            raise ValueError(f"stiffness, ratio and f_max must be > 0: {self}")
        if min(self.d_proximal, self.d_distal) < 0 or not self.u_rate > 0:
            raise ValueError(f"damping must be >= 0 and u_rate > 0: {self}")

    @property
    def stiffness(self) -> np.ndarray:
        """Joint stiffness (4,) in FINGER_JOINTS order."""
        k = np.array([self.k_proximal, self.k_proximal * self.distal_stiffness_ratio])
        return np.tile(k, 2)

    @property
    def damping(self) -> np.ndarray:
        """Joint damping (4,) in FINGER_JOINTS order."""
        return np.tile([self.d_proximal, self.d_distal], 2)

    @property
    def rest(self) -> np.ndarray:
        """Rest angles q0 (4,) in FINGER_JOINTS order."""
        return np.tile([self.q0_proximal, self.q0_distal], 2)

    @property
    def tendon(self) -> np.ndarray:
        """Tendon torque at u = 1, R * f_max (4,), in FINGER_JOINTS order."""
        return np.tile(TENDON_RATIO * self.f_max, 2)


@dataclass(frozen=True)
class ArmGains:
    """Arm control: PyBullet position motors plus optional gravity compensation.

    Each step a motor drives its joint velocity toward
    ``position_gain * (q_target - q) / dt + velocity_gain * (dq_target - dq)`` (plus dq),
    within the controller's output limit ``ARM_TORQUE_LIMITS``. With
    ``gravity_compensation`` the gravity torque, computed at each new arm target, is added as
    a feedforward every physics step, as libbarrett adds gravity compensation outside its
    controller's limit: joint 2 needs about 21.7 N m at READY_ARM_Q, more than its 20 N m
    controller limit, so without it the arm sags. The feedforward is clipped to
    ``ARM_TORQUE_LIMITS`` too (an unclipped one, up to ~28 N m on joint 2, changes the
    expert's episodes), and the motor's cap shrinks by the feedforward's size wherever the
    sum would pass the joint's ``ARM_PEAK_TORQUES``: motor and feedforward together never
    exceed it (with these limits that binds on joint 7 only, whose peak is 2.2 N m).
    """

    position_gains: tuple[float, ...] = (0.3,) * 7
    velocity_gains: tuple[float, ...] = (1.0,) * 7
    gravity_compensation: bool = True


def dh_transform(a: float, alpha: float, d: float, theta: float) -> np.ndarray:
    """Homogeneous transform Rz(theta) Tz(d) Tx(a) Rx(alpha) (4, 4)."""
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array(
        [
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def flange_pose_dh(q: np.ndarray) -> np.ndarray:
    """World pose (4, 4) of the flange (DH frame 7) for arm angles q (7,)."""
    t = np.eye(4)
    t[2, 3] = BASE_TO_SHOULDER
    for (a, alpha, d), theta in zip(DH, np.asarray(q, dtype=float), strict=True):
        t = t @ dh_transform(a, alpha, d, theta)
    return t


# ------------------------------------------------------------------- link geometry
@dataclass(frozen=True)
class Shape:
    """A collision/visual primitive in its link frame.

    ``size``: box (x, y, z) edge lengths, cylinder (radius, length along its own z).
    """

    kind: str
    size: tuple[float, ...]
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)


_ALONG_X = (0.0, np.pi / 2, 0.0)  # turns a cylinder's axis onto the link x axis
_ALONG_Y = (np.pi / 2, 0.0, 0.0)  # ... onto the link y axis

LINK_SHAPES: dict[str, tuple[Shape, ...]] = {
    "wam_base": (Shape("box", BASE_SIZE, BASE_CENTER),),
    # Shoulder column from the base top (z = 0.16) up to just under the shoulder axes.
    "wam_link1": (Shape("cylinder", (0.09, 0.17), (0.0, 0.0, -0.101)),),
    # Shoulder pitch housing around the joint-2 axis (link z).
    "wam_link2": (Shape("cylinder", (0.08, 0.16)),),
    # Upper arm along link z up to the elbow (0.55 m).
    "wam_link3": (Shape("cylinder", (0.048, 0.46), (0.0, 0.0, 0.30)),),
    # Elbow housing on the joint-4 axis, forearm tube along -y from (-0.045, 0, 0).
    "wam_link4": (
        Shape("cylinder", (0.05, 0.10)),
        Shape("cylinder", (0.05, 0.20), (-0.045, -0.14, 0.0), _ALONG_Y),
    ),
    # Wrist yaw housing at the end of the forearm (wrist centre at z = 0.3).
    "wam_link5": (Shape("cylinder", (0.045, 0.06), (0.0, 0.0, 0.25)),),
    # Wrist pitch housing around the joint-6 axis.
    "wam_link6": (Shape("cylinder", (0.045, 0.09)),),
    # Wrist roll output up to the flange (z = 0.06).
    "wam_link7": (Shape("cylinder", (0.045, 0.05), (0.0, 0.0, 0.035)),),
    "t42_palm": (
        Shape("box", PALM_SIZE, (0.0, 0.0, PALM_SIZE[2] / 2)),
        *(
            Shape(
                "box",
                (FINGER_WIDTH, 0.02, PIVOT_HEIGHT - PALM_SIZE[2]),
                (0.0, s * FINGER_BASE_SPACING / 2, (PIVOT_HEIGHT + PALM_SIZE[2]) / 2),
            )
            for s in (1.0, -1.0)
        ),
    ),
    "proximal": (
        Shape(
            "box",
            (FINGER_WIDTH, PROXIMAL_THICKNESS, PROXIMAL_LENGTH),
            (0.0, 0.0, PROXIMAL_LENGTH / 2),
        ),
    ),
    "distal": (
        Shape(
            "box",
            (FINGER_WIDTH, DISTAL_THICKNESS, DISTAL_LENGTH - TIP_RADIUS),
            (0.0, 0.0, (DISTAL_LENGTH - TIP_RADIUS) / 2),
        ),
        Shape(
            "cylinder",
            (TIP_RADIUS, FINGER_WIDTH),
            (0.0, 0.0, DISTAL_LENGTH - TIP_RADIUS),
            _ALONG_X,
        ),
    ),
}
"""Primitives per link; ``proximal``/``distal`` apply to both fingers (in finger frames)."""
