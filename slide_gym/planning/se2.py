"""SE(2) poses (x, y, yaw) and the object motion of Eq. 2 restricted to the table plane."""

from __future__ import annotations

import math

import numpy as np


def se2_compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a * b: apply pose ``b`` in the frame of pose ``a``."""
    ax, ay, at = (float(v) for v in a)
    bx, by, bt = (float(v) for v in b)
    c, s = math.cos(at), math.sin(at)
    return np.array(
        [ax + c * bx - s * by, ay + s * bx + c * by, math.remainder(at + bt, 2 * math.pi)]
    )


def se2_inverse(a: np.ndarray) -> np.ndarray:
    """The inverse pose of ``a``."""
    ax, ay, at = (float(v) for v in a)
    c, s = math.cos(at), math.sin(at)
    return np.array([-(c * ax + s * ay), s * ax - c * ay, math.remainder(-at, 2 * math.pi)])


def slid_object_pose(gamma_s: np.ndarray, gamma_g: np.ndarray, kappa_s: np.ndarray) -> np.ndarray:
    """Eq. 2 in the plane: kappa_g = Gamma(phi_g) * inv(Gamma(phi_s)) * kappa_s.

    The fingertip keeps its contact on the plate, so the plate follows the fingertip's planar
    motion; ``gamma_*`` are the fingertip's (x, y, yaw of X_F), ``kappa_s`` the plate's start.
    """
    return se2_compose(gamma_g, se2_compose(se2_inverse(gamma_s), kappa_s))
