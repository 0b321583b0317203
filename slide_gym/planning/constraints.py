"""The relaxed top-sliding contact constraints (Eq. 1-3 with the relaxations of IV-C.3).

Fingertip frame F (``fingertip_contact``): X_F along the fingertip width, Z_F out of the tip,
Y_F = Z_F x X_F; finger B sits 52 mm away on the -Y_F side. A configuration is on the relaxed
manifold when

* roll: X_F is horizontal, ``X_F . z = 0`` (a line contact on the plate top);
* pitch: beta = asin(-Z_F . z), the angle between Z_F and the table plane with Z_F pointing
  down, lies in ``[beta0 - dbeta, beta0 + dbeta]``;
* depth: the contact point's height lies in ``[z_s - dz_hi, z_s - dz_lo]`` (z_s = plate top);

and, checked but never projected onto,

* side: ``Y_F . z < 0``, i.e. finger B (on -Y_F) is *above* finger A. The pressing force then
  closes finger A toward finger B, the direction its compliant joints give way in, and the
  idle finger stays clear of the plate and the table;
* finger B's lowest point stays above z_s (the plate top), so the idle finger never touches
  the plate it hovers over;
* the contact's (x, y) lies inside the table polygon.

With X_F horizontal the frame is ``r(alpha, beta)``: X_F = (cos a, sin a, 0),
Z_F = cos(b) (z x X_F) - sin(b) z, see :func:`contact_rotation`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely

from slide_gym.robot.kinematics import FastChain
from slide_gym.robot.model import ARM_LOWER, ARM_UPPER, FINGER_BASE_SPACING, TIP_RADIUS

_Z = np.array([0.0, 0.0, 1.0])


def contact_rotation(alpha: np.ndarray | float, beta: np.ndarray | float) -> np.ndarray:
    """Fingertip orientation(s) r(alpha, beta) (..., 3, 3), columns X_F, Y_F, Z_F."""
    a, b = np.asarray(alpha, dtype=float), np.asarray(beta, dtype=float)
    a, b = np.broadcast_arrays(a, b)
    x = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=-1)
    h = np.stack([-np.sin(a), np.cos(a), np.zeros_like(a)], axis=-1)  # z x X_F
    z = np.cos(b)[..., None] * h - np.sin(b)[..., None] * _Z
    y = -np.cos(b)[..., None] * _Z - np.sin(b)[..., None] * h  # Z_F x X_F
    return np.stack([x, y, z], axis=-1)


def planar_pose(tip: np.ndarray) -> np.ndarray:
    """Gamma(phi) in SE(2): (x, y, yaw of X_F) of fingertip pose(s) (..., 4, 4)."""
    tip = np.asarray(tip, dtype=float)
    yaw = np.arctan2(tip[..., 1, 0], tip[..., 0, 0])
    return np.stack([tip[..., 0, 3], tip[..., 1, 3], yaw], axis=-1)


def finger_b_low(tip: np.ndarray) -> np.ndarray:
    """Height(s) of finger B's lowest tip point for fingertip pose(s) (..., 4, 4), hand at rest.

    Finger B's tip apex is finger A's moved by FINGER_BASE_SPACING along -Y_F; its rounded tip
    (a cylinder along X_F of radius TIP_RADIUS) reaches TIP_RADIUS (1 - sin beta) lower.
    """
    tip = np.asarray(tip, dtype=float)
    apex = tip[..., 2, 3] - FINGER_BASE_SPACING * tip[..., 2, 1]
    sin_beta = np.clip(-tip[..., 2, 2], -1.0, 1.0)
    return apex - TIP_RADIUS * (1.0 - sin_beta)


@dataclass(frozen=True)
class ContactBand:
    """Numbers of the relaxed manifold (SI units, radians)."""

    beta0: float
    dbeta: float
    z_lo: float  # z_s - dz_hi
    z_hi: float  # z_s - dz_lo
    z_surface: float  # z_s, the plate top


class SlideConstraints:
    """Residuals, checks and Newton projection onto the relaxed manifold.

    Args:
        chain: kinematics of the ``fingertip_contact`` frame.
        band: the pitch and height bands.
        table: the table polygon (world xy) the contact must stay inside.
        tolerance: a residual counts as satisfied below this (rad / m).
        max_iters: Newton iterations before a projection gives up.
    """

    def __init__(
        self,
        chain: FastChain,
        band: ContactBand,
        table: shapely.Polygon,
        tolerance: float = 1e-4,
        max_iters: int = 25,
    ):
        self.chain = chain
        self.band = band
        self.table = table
        shapely.prepare(self.table)
        self.tolerance = float(tolerance)
        self.max_iters = int(max_iters)
        self.sin_lo = math.sin(band.beta0 - band.dbeta)
        self.sin_hi = math.sin(band.beta0 + band.dbeta)
        # Newton aims a little inside the inequality bands so results pass the checks.
        inset_s = min(0.5 * self.tolerance, 0.5 * (self.sin_hi - self.sin_lo))
        inset_z = min(0.5 * self.tolerance, 0.5 * (band.z_hi - band.z_lo))
        self._aim = (
            self.sin_lo + inset_s,
            self.sin_hi - inset_s,
            band.z_lo + inset_z,
            band.z_hi - inset_z,
        )

    # ---------------------------------------------------------------- residuals
    def residuals(self, tip: np.ndarray) -> np.ndarray:
        """Violations (..., 3): roll (X_F . z), pitch (on sin beta), depth (m); 0 = satisfied."""
        tip = np.asarray(tip, dtype=float)
        s, z = -tip[..., 2, 2], tip[..., 2, 3]
        return np.stack(
            [
                tip[..., 2, 0],
                s - np.clip(s, self.sin_lo, self.sin_hi),
                z - np.clip(z, self.band.z_lo, self.band.z_hi),
            ],
            axis=-1,
        )

    def hard_ok(self, tip: np.ndarray) -> np.ndarray:
        """The checked-only conditions (side, finger B clearance, contact over the table)."""
        tip = np.asarray(tip, dtype=float)
        side = tip[..., 2, 1] < 0.0
        clear = finger_b_low(tip) >= self.band.z_surface
        inside = shapely.contains_xy(self.table, tip[..., 0, 3], tip[..., 1, 3])
        return side & clear & inside

    def satisfied(self, q: np.ndarray, tol: float | None = None) -> np.ndarray:
        """True where configuration(s) (..., 7) are on the relaxed manifold and pass the checks."""
        q = np.asarray(q, dtype=float)
        tip = self.chain.forward(q)
        tol = self.tolerance if tol is None else tol
        ok = (np.abs(self.residuals(tip)) <= tol).all(axis=-1) & self.hard_ok(tip)
        in_limits = ((q >= ARM_LOWER - 1e-9) & (q <= ARM_UPPER + 1e-9)).all(axis=-1)
        return ok & in_limits

    # --------------------------------------------------------------- projection
    def project(
        self, q: np.ndarray, q_near: np.ndarray | None = None, depth: bool = True
    ) -> np.ndarray | None:
        """Newton / pseudo-inverse iterations onto the manifold; None on failure.

        Only violated inequalities enter the step (an active set re-evaluated every
        iteration); each step is clipped to the joint limits. ``q_near`` is unused (the
        minimum-norm step already stays close to ``q``) and kept for the search interface.
        ``depth=False`` projects the roll and the pitch only: the contact depth is then
        checked (within ``tolerance`` of its band), never moved toward it.
        """
        q = np.minimum(np.maximum(np.asarray(q, dtype=float), ARM_LOWER), ARM_UPPER)
        lo_s, hi_s, lo_z, hi_z = self._aim
        eps = 0.1 * self.tolerance  # what "violated" means inside the loop
        s_lo, s_hi = self.sin_lo - eps, self.sin_hi + eps
        z_lo, z_hi = self.band.z_lo - eps, self.band.z_hi + eps
        for _ in range(self.max_iters):
            tip, jac = self.chain.jacobian(q)
            x0, x1, x2 = tip[:3, 0].tolist()
            z0, z1, z2 = tip[:3, 2].tolist()
            s, z = -z2, float(tip[2, 3])
            jw = jac[3:]
            rows, res = [], []
            if abs(x2) > eps:  # d(X_F . z)/dq = (X_F x z) . J_w
                rows.append(x1 * jw[0] - x0 * jw[1])
                res.append(x2)
            if s < s_lo or s > s_hi:  # d(-Z_F . z)/dq = -(Z_F x z) . J_w
                rows.append(z0 * jw[1] - z1 * jw[0])
                res.append(s - (lo_s if s < lo_s else hi_s))
            if depth and (z < z_lo or z > z_hi):
                rows.append(jac[2])
                res.append(z - (lo_z if z < lo_z else hi_z))
            if not rows:
                if not depth and not (z_lo - self.tolerance <= z <= z_hi + self.tolerance):
                    return None
                return q if self._hard_ok_one(tip) else None
            q = np.minimum(np.maximum(q - _min_norm_step(rows, res), ARM_LOWER), ARM_UPPER)
        return None

    def project_ompl(
        self, q: np.ndarray, q_near: np.ndarray | None = None, max_iters: int = 50
    ) -> np.ndarray | None:
        """OMPL's ``Constraint::project`` on our residuals (None on failure).

        Newton's method with the least-squares (SVD) step ``J^+ f`` on all three residuals
        (a residual inside its band is 0 with a zero gradient), while ``|f|`` >= ``tolerance``
        and at most ``max_iters`` steps (OMPL 2.0.1's defaults: 1e-4 and 50); nothing aims
        inside the bands and no step is clipped, so a result outside the joint limits fails.
        Then the checked-only rules, as in :meth:`project`. ``q_near`` is unused.
        """
        q = np.asarray(q, dtype=float).copy()
        tol2 = self.tolerance * self.tolerance
        for it in range(max_iters + 1):
            tip, jac = self.chain.jacobian(q)
            f = self.residuals(tip)
            if float(f @ f) < tol2:
                break
            if it == max_iters:
                return None
            q = q - np.linalg.lstsq(self.residual_jacobian(tip, jac), f, rcond=None)[0]
        in_limits = bool(((q >= ARM_LOWER) & (q <= ARM_UPPER)).all())
        return q if in_limits and self._hard_ok_one(tip) else None

    def residual_jacobian(self, tip: np.ndarray, jac: np.ndarray) -> np.ndarray:
        """d :meth:`residuals` / dq (3, 7) at one pose ``tip`` with its geometric Jacobian
        ``jac``; a band's row is zero inside the band, where its residual is flat."""
        jw = jac[3:]
        (x0, x1, _), (z0, z1, z2) = tip[:3, 0], tip[:3, 2]
        rows = np.zeros((3, jac.shape[1]))
        rows[0] = x1 * jw[0] - x0 * jw[1]  # d(X_F . z)/dq = (X_F x z) . J_w
        if not self.sin_lo <= -z2 <= self.sin_hi:  # d(-Z_F . z)/dq = -(Z_F x z) . J_w
            rows[1] = z0 * jw[1] - z1 * jw[0]
        if not self.band.z_lo <= tip[2, 3] <= self.band.z_hi:
            rows[2] = jac[2]
        return rows

    def chord_ok(self, a: np.ndarray, b: np.ndarray, pieces: int) -> bool:
        """Do the points splitting the straight joint-space chord ``a``-``b`` into ``pieces``
        equal parts all satisfy the constraints (:meth:`satisfied`)? (The ends are not
        checked: they are tree nodes, already on the manifold.)"""
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        t = np.arange(1, max(int(pieces), 2)) / max(int(pieces), 2)
        return bool(self.satisfied(a + t[:, None] * (b - a)).all())

    def _hard_ok_one(self, tip: np.ndarray) -> bool:
        """:meth:`hard_ok` for one pose, in plain floats."""
        y2, z2 = float(tip[2, 1]), float(tip[2, 2])
        if y2 >= 0.0:
            return False
        low = float(tip[2, 3]) - FINGER_BASE_SPACING * y2 - TIP_RADIUS * (1.0 + z2)
        if low < self.band.z_surface:
            return False
        return bool(shapely.contains_xy(self.table, float(tip[0, 3]), float(tip[1, 3])))


def _min_norm_step(rows: list[np.ndarray], res: list[float]) -> np.ndarray:
    """The minimum-norm dq with A dq = r for 1-3 rows (A A^T solved in closed form)."""
    if len(rows) == 1:
        a = rows[0]
        return a * (res[0] / max(float(a @ a), 1e-300))
    a = np.array(rows)
    g = (a @ a.T).tolist()
    if len(rows) == 2:
        (g00, g01), (_, g11) = g
        det = g00 * g11 - g01 * g01
        if abs(det) < 1e-300:
            return np.zeros(a.shape[1])
        r0, r1 = res
        return a.T @ np.array([(g11 * r0 - g01 * r1) / det, (g00 * r1 - g01 * r0) / det])
    (g00, g01, g02), (_, g11, g12), (_, _, g22) = g
    g00, g11, g22 = g00 + 1e-12, g11 + 1e-12, g22 + 1e-12  # as a tiny ridge
    c00, c01, c02 = g11 * g22 - g12 * g12, g02 * g12 - g01 * g22, g01 * g12 - g02 * g11
    det = g00 * c00 + g01 * c01 + g02 * c02
    if abs(det) < 1e-300:
        return np.zeros(a.shape[1])
    c11, c12, c22 = g00 * g22 - g02 * g02, g01 * g02 - g00 * g12, g00 * g11 - g01 * g01
    r0, r1, r2 = res  # the symmetric adjugate times r, over det
    y = [
        (c00 * r0 + c01 * r1 + c02 * r2) / det,
        (c01 * r0 + c11 * r1 + c12 * r2) / det,
        (c02 * r0 + c12 * r1 + c22 * r2) / det,
    ]
    return a.T @ np.array(y)
