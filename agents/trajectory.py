"""Joint-space trajectories sampled at the environment's control rate.

A :class:`Segment` is a polyline of arm configurations with speed limits (joint speed, and
fingertip speed where contact needs it) and a hand command. :func:`time_segment` turns it into
one arm target per control step; the agent emits the differences between consecutive targets as
the environment's joint-increment actions, so the environment's own target integrator
reproduces the sampled trajectory exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from slide_gym.robot.kinematics import FastChain


@dataclass(frozen=True)
class Segment:
    """A leg of the motion: ``waypoints`` (k, 7), traversed at the given speed limits.

    ``joint_speed`` caps every joint (rad/s); ``tip_speed`` (m/s) caps the motion of the frame
    ``chain`` computes (the fingertip while sliding). ``hand`` is the hand command u during the
    leg (the tendon servo ramps toward it at ``HandParams.u_rate``). ``hold_s`` keeps the last
    waypoint for that long after arriving (contact settles, fingers close). ``ramp_s``: the
    leg speeds up from rest and slows down to rest over this long (s) instead of starting and
    stopping at full speed; the arm's position servo then tracks without overshooting the
    last waypoint (a fast free-space move would otherwise dip ~1 cm past a pre-press pose).
    """

    name: str
    waypoints: np.ndarray
    joint_speed: float = 0.6
    tip_speed: float = math.inf
    hand: float = 0.0
    hold_s: float = 0.0
    ramp_s: float = 0.0


def time_segment(segment: Segment, dt: float, chain: FastChain | None = None) -> np.ndarray:
    """(n, 7) arm targets, one per control step of ``dt`` seconds, ending on the last waypoint.

    Each polyline edge takes the longest of its joint-speed and tip-speed durations; targets
    are interpolated linearly in time along the polyline (with a trapezoidal speed profile
    if ``segment.ramp_s`` > 0).
    """
    q = np.asarray(segment.waypoints, dtype=float)
    if q.ndim != 2 or q.shape[1] != 7 or len(q) == 0:
        raise ValueError(f"segment {segment.name!r}: waypoints must be (k, 7), got {q.shape}")
    if len(q) == 1:
        edge_times = np.zeros(0)
    else:
        edge_times = np.abs(np.diff(q, axis=0)).max(axis=1) / segment.joint_speed
        if chain is not None and math.isfinite(segment.tip_speed):
            tips = chain.forward(q)[:, :3, 3]
            tip_times = np.linalg.norm(np.diff(tips, axis=0), axis=1) / segment.tip_speed
            edge_times = np.maximum(edge_times, tip_times)
    knots = np.r_[0.0, np.cumsum(edge_times)]
    total = knots[-1]
    ramp = min(segment.ramp_s, total)
    n_move = max(1, math.ceil((total + ramp) / dt - 1e-9))
    t = _trapezoid(np.arange(1, n_move + 1) * dt, total, ramp)
    if total <= 0.0:
        moved = np.repeat(q[-1:], n_move, axis=0)
    else:
        moved = np.column_stack([np.interp(t, knots, q[:, j]) for j in range(7)])
    n_hold = math.ceil(segment.hold_s / dt - 1e-9)
    return np.vstack([moved, np.repeat(q[-1:], n_hold, axis=0)])


def _trapezoid(t: np.ndarray, total: float, ramp: float) -> np.ndarray:
    """Progress along a leg of ``total`` seconds at full speed, at times ``t``, when the speed
    ramps linearly from rest over ``ramp`` seconds and back to rest at the end (the leg then
    takes ``total + ramp``); ``ramp == 0``: constant speed."""
    end = total + ramp
    t = np.minimum(t, end)
    if ramp <= 0.0:
        return t
    return np.where(
        t < ramp,
        t**2 / (2 * ramp),
        np.where(t <= total, t - ramp / 2, total - (end - t) ** 2 / (2 * ramp)),
    )
