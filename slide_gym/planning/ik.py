"""Damped-least-squares inverse kinematics, batched over random restarts.

All restarts iterate together as one NumPy batch; each step is clipped to the joint limits.
Targets give a position and, optionally, some or all axes of an orientation. The chains to
solve for (:func:`~slide_gym.robot.kinematics.fingertip_chain`,
:func:`~slide_gym.robot.kinematics.grasp_chain`) live with the robot.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np

from slide_gym.robot.kinematics import FastChain
from slide_gym.robot.model import ARM_LOWER, ARM_UPPER


@dataclass(frozen=True)
class IKTarget:
    """A tip pose to reach: ``position`` (3,) and optionally ``rotation`` (3, 3).

    ``axes`` lists which columns (0 = x, 1 = y, 2 = z) of ``rotation`` the tip's matching
    axes must equal; all three give a full orientation, one or two a partial one.
    """

    position: np.ndarray
    rotation: np.ndarray | None = None
    axes: tuple[int, ...] = (0, 1, 2)

    def __post_init__(self) -> None:
        pos = np.asarray(self.position, dtype=float)
        if pos.shape != (3,) or not np.isfinite(pos).all():
            raise ValueError(f"IK target position must be 3 finite numbers, got {self.position}")
        object.__setattr__(self, "position", pos)
        if self.rotation is not None:
            rot = np.asarray(self.rotation, dtype=float)
            if rot.shape != (3, 3) or not np.allclose(rot.T @ rot, np.eye(3), atol=1e-6):
                raise ValueError("IK target rotation must be a 3x3 rotation matrix")
            object.__setattr__(self, "rotation", rot)
            if not self.axes or not set(self.axes) <= {0, 1, 2}:
                raise ValueError(f"IK target axes must be a subset of (0, 1, 2), got {self.axes}")


NEAREST_EXTRA_ITERS = 10
"""Iterations a ``nearest`` IK batch runs on after its first restart converges."""


@dataclass(frozen=True)
class IKParams:
    """Solver settings: restarts, iterations, damping, step limit and tolerances.

    ``patience``: every that many iterations the solver gives up if no restart has cut its
    error (position m + orientation rad) by a tenth since the last check. Targets out of
    reach then cost ~10 iterations instead of ``max_iters``; a converging restart shrinks its
    error far faster than that.
    """

    n_restarts: int = 8
    max_iters: int = 50
    patience: int = 10
    damping: float = 0.03
    max_step: float = 0.4  # rad, largest joint change per iteration
    pos_tol: float = 1e-5  # m
    rot_tol: float = 1e-4  # rad

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"IKParams.{name} must be a finite positive number, got {value}")
        if self.n_restarts < 1 or self.max_iters < 1:
            raise ValueError("IKParams.n_restarts and max_iters must be >= 1")
        if self.patience < 1:
            raise ValueError("IKParams.patience must be >= 1")


def pose_error(tip: np.ndarray, target: IKTarget) -> np.ndarray:
    """Errors (..., 6): position (m) and orientation (rad-like) from tip pose(s) to target."""
    err = np.zeros((*tip.shape[:-2], 6))
    err[..., :3] = target.position - tip[..., :3, 3]
    if target.rotation is not None:
        # sum_k tip_k x target_k over the matched axes k, read off m = sum_k tip_k target_k^T
        axes = list(target.axes)
        m = tip[..., :3, axes] @ target.rotation[:, axes].T
        err[..., 3] = m[..., 1, 2] - m[..., 2, 1]
        err[..., 4] = m[..., 2, 0] - m[..., 0, 2]
        err[..., 5] = m[..., 0, 1] - m[..., 1, 0]
        if len(axes) > 1:
            err[..., 3:] *= 0.5
    return err


def solve_ik(
    chain: FastChain,
    target: IKTarget,
    rng: np.random.Generator,
    seeds: np.ndarray | None = None,
    params: IKParams | None = None,
    deadline: float = math.inf,
    nearest: bool = False,
    reference: np.ndarray | None = None,
) -> np.ndarray | None:
    """Joint angles (7,) reaching ``target``, or None if no restart converged.

    The batch holds the given ``seeds`` (k, 7) first, then uniform random restarts drawn from
    ``rng`` up to ``params.n_restarts``. Returns the lowest-index converged restart; with
    ``nearest`` (and seeds), the batch runs :data:`NEAREST_EXTRA_ITERS` more iterations after
    the first converges and the converged restart nearest ``seeds[0]`` wins, or the one
    nearest any row of ``reference`` (r, 7) where given. Gives up (None) once
    ``time.perf_counter()`` passes ``deadline``.
    """
    p = params or IKParams()
    seeds = np.empty((0, 7)) if seeds is None else np.atleast_2d(np.asarray(seeds, dtype=float))
    n_rand = max(0, p.n_restarts - len(seeds))
    q = np.vstack(
        [np.clip(seeds, ARM_LOWER, ARM_UPPER), rng.uniform(ARM_LOWER, ARM_UPPER, (n_rand, 7))]
    )
    nearest = nearest and len(seeds) > 0
    eye = np.eye(6) * p.damping**2
    partial = target.rotation is not None and len(target.axes) == 1
    checkpoint = np.full(len(q), np.inf)
    stop_at: int | None = None  # with ``nearest``: the iteration that picks among the converged
    for it in range(p.max_iters + (NEAREST_EXTRA_ITERS if nearest else 0)):
        if time.perf_counter() >= deadline:
            return None
        tip, jac = chain.jacobian(q)
        err = pose_error(tip, target)
        pos_n = np.linalg.norm(err[:, :3], axis=1)
        rot_n = np.linalg.norm(err[:, 3:], axis=1)
        done = (pos_n <= p.pos_tol) & (rot_n <= p.rot_tol)
        if done.any() and not nearest:
            return q[int(np.argmax(done))].copy()
        if done.any() and stop_at is None:
            stop_at = it + NEAREST_EXTRA_ITERS
        if stop_at is not None and it >= stop_at:
            break
        if stop_at is None and it >= p.max_iters:
            return None
        if stop_at is None and it % p.patience == 0:
            total = pos_n + rot_n
            if not (total < 0.9 * checkpoint).any():
                return None  # every restart has stalled: the target is out of their reach
            checkpoint = total
        if target.rotation is None:
            jac = jac[:, :3]
            err = err[:, :3]
        elif partial:
            # Rotation about the matched axis itself is free: drop it from the angular rows.
            a = tip[:, :3, target.axes[0]]
            proj = np.eye(3) - a[:, :, None] * a[:, None, :]
            jac = np.concatenate([jac[:, :3], proj @ jac[:, 3:]], axis=1)
        m = jac.shape[1]
        jjt = jac @ np.swapaxes(jac, 1, 2) + eye[:m, :m]
        dq = np.einsum("bji,bj->bi", jac, np.linalg.solve(jjt, err[..., None])[..., 0])
        biggest = np.abs(dq).max(axis=1, keepdims=True)
        dq *= np.minimum(1.0, p.max_step / np.maximum(biggest, 1e-12))
        dq[done] = 0.0  # a converged restart stays where it converged
        q = np.clip(q + dq, ARM_LOWER, ARM_UPPER)
    tip = chain.forward(q)
    err = pose_error(tip, target)
    done = (np.linalg.norm(err[:, :3], axis=1) <= p.pos_tol) & (
        np.linalg.norm(err[:, 3:], axis=1) <= p.rot_tol
    )
    if not done.any():
        return None
    if nearest:
        ref = seeds[:1] if reference is None else np.atleast_2d(reference)
        near = np.linalg.norm(q[:, None, :] - ref[None], axis=2).min(axis=1)
        gap = np.where(done, near, np.inf)
        return q[int(np.argmin(gap))].copy()
    return q[int(np.argmax(done))].copy()


def interpolate_rotation(r0: np.ndarray, r1: np.ndarray, s: float) -> np.ndarray:
    """The rotation a fraction ``s`` of the way from ``r0`` to ``r1`` (3, 3), about the fixed
    axis of ``r0.T @ r1`` (spherical linear interpolation)."""
    rel = r0.T @ r1
    angle = math.acos(float(np.clip((np.trace(rel) - 1.0) / 2.0, -1.0, 1.0)))
    if angle < 1e-9:
        return r0.copy()
    if angle > math.pi - 1e-6:  # half a turn: the axis is the eigenvector of eigenvalue 1
        w, v = np.linalg.eigh(rel + rel.T)
        axis = v[:, int(np.argmax(w))]
    else:
        axis = np.array([rel[2, 1] - rel[1, 2], rel[0, 2] - rel[2, 0], rel[1, 0] - rel[0, 1]])
        axis /= 2.0 * math.sin(angle)
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    a = s * angle
    return r0 @ (np.eye(3) + math.sin(a) * k + (1.0 - math.cos(a)) * (k @ k))


def solve_ik_along(
    chain: FastChain,
    target: IKTarget,
    q_from: np.ndarray,
    steps: int,
    rng: np.random.Generator,
    params: IKParams | None = None,
    deadline: float = math.inf,
) -> np.ndarray | None:
    """Joint angles (7,) reaching ``target`` on the IK branch of ``q_from``, or None.

    Walks the tip from its pose at ``q_from`` to ``target`` in ``steps`` equal steps
    (straight in position, :func:`interpolate_rotation` in orientation; a full-orientation
    ``target``), each solved from the previous solution alone. The answer is usually the
    solution nearest ``q_from``, where a batch of random restarts returns whichever
    converged first, often on another branch.
    """
    if target.rotation is None or len(target.axes) != 3:
        raise ValueError("solve_ik_along needs a target with a full orientation")
    p = replace(params or IKParams(), n_restarts=1)
    start = chain.forward(np.asarray(q_from, dtype=float)[None])[0]
    q: np.ndarray | None = np.asarray(q_from, dtype=float)
    for k in range(1, steps + 1):
        s = k / steps
        pos = (1.0 - s) * start[:3, 3] + s * target.position
        rot = interpolate_rotation(start[:3, :3], target.rotation, s)
        q = solve_ik(chain, IKTarget(pos, rot), rng, q[None], p, deadline)
        if q is None:
            return None
    return q
