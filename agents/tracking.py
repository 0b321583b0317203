"""Feedback and motion helpers of the expert: the contact loops (:class:`ContactTracker`) and
straight Cartesian moves (:func:`cartesian_line`). Pose arithmetic lives in
:mod:`slide_gym.geometry` (``quat_yaw``, ``wrap_angle``)."""

from __future__ import annotations

import math

import numpy as np

from agents.params import ExpertParams
from slide_gym.planning.api import IKParams, IKTarget, solve_ik
from slide_gym.planning.ik import interpolate_rotation
from slide_gym.robot.kinematics import FastChain

_LOCAL_IK = IKParams(n_restarts=1)  # the seed only: no jump to another IK branch
LINE_STEP = 0.01  # m between the IK waypoints of a straight Cartesian move
LINE_ROT_STEP = 0.05  # rad between the IK waypoints of a turning Cartesian move
_LINE_MAX_JOINT_STEP = 0.3  # rad: a larger change between waypoints means a branch switch


def cartesian_line(
    chain: FastChain, q0: np.ndarray, offset: np.ndarray, rng: np.random.Generator
) -> np.ndarray | None:
    """Joint waypoints that move ``chain``'s frame by ``offset`` (world, m) along a straight
    line, orientation kept; None if that leaves the reachable set.

    Each IK starts from the previous waypoint only, so the arm stays on one IK branch (a
    joint-space move between branches can sweep the hand through the scene).
    """
    start = chain.forward(q0)
    n = max(1, math.ceil(float(np.linalg.norm(offset)) / LINE_STEP))
    path = [np.asarray(q0, dtype=float)]
    for k in range(1, n + 1):
        target = IKTarget(start[:3, 3] + offset * k / n, start[:3, :3])
        q = solve_ik(chain, target, rng, path[-1][None], _LOCAL_IK)
        if q is None or np.abs(q - path[-1]).max() > _LINE_MAX_JOINT_STEP:
            return None
        path.append(q)
    return np.array(path)


def cartesian_walk(
    chain: FastChain,
    q0: np.ndarray,
    poses: list[tuple[np.ndarray, np.ndarray]],
    rng: np.random.Generator,
    toward: np.ndarray | None = None,
) -> np.ndarray | None:
    """Joint waypoints that move ``chain``'s frame from its pose at ``q0`` through ``poses``
    ((position (3,), rotation (3, 3)) in the world) along straight lines, the orientation
    turning at a constant rate about one axis on each leg; None if that leaves the reachable
    set or switches IK branch. Waypoints lie :data:`LINE_STEP` apart or turn
    :data:`LINE_ROT_STEP`, whichever needs more. Each IK starts from the previous waypoint,
    moved by an even share of the way left to ``toward`` (7,) if given: the arm's redundant
    motion then drifts toward that configuration instead of into a joint limit."""
    here = chain.forward(q0)
    pos, rot = here[:3, 3], here[:3, :3]
    targets = []
    for goal_pos, goal_rot in poses:
        turn = math.acos(float(np.clip((np.trace(rot.T @ goal_rot) - 1.0) / 2.0, -1.0, 1.0)))
        steps = max(float(np.linalg.norm(goal_pos - pos)) / LINE_STEP, turn / LINE_ROT_STEP)
        n = max(1, math.ceil(steps))
        targets += [
            IKTarget(pos + (goal_pos - pos) * k / n, interpolate_rotation(rot, goal_rot, k / n))
            for k in range(1, n + 1)
        ]
        pos, rot = np.asarray(goal_pos, dtype=float), np.asarray(goal_rot, dtype=float)
    path = [np.asarray(q0, dtype=float)]
    for i, target in enumerate(targets):
        last = path[-1]
        seeds = [last] if toward is None else [last + (toward - last) / (len(targets) - i), last]
        for seed in seeds:
            q = solve_ik(chain, target, rng, seed[None], _LOCAL_IK)
            if q is not None and np.abs(q - last).max() <= _LINE_MAX_JOINT_STEP:
                break
        else:
            return None
        path.append(q)
    return np.array(path)


def rise(
    chain: FastChain,
    q0: np.ndarray,
    heights: tuple[float, ...],
    any_branch: bool,
    rng: np.random.Generator,
) -> np.ndarray | None:
    """Waypoints raising ``chain``'s frame straight up by the first of ``heights`` that stays
    on one IK branch; with ``any_branch``, else a joint-space move to any IK solution at the
    first height (near a joint limit)."""
    for height in heights:
        line = cartesian_line(chain, q0, np.array([0.0, 0.0, height]), rng)
        if line is not None:
            return line
    if not any_branch:
        return None
    up = chain.forward(q0)
    up[2, 3] += heights[0]
    q_up = solve_ik(chain, IKTarget(up[:3, 3], up[:3, :3]), rng, np.asarray(q0)[None])
    return None if q_up is None else np.array([q0, q_up])


class ContactTracker:
    """Two integral loops that keep a pressed fingertip where the plan wants it (xy only).

    The inner loop moves the real fingertip onto the planned one: the compliant finger swings
    sideways as it is pressed. While sliding, a slower outer loop shifts that target by the
    plate's lag behind its Eq. 2 pose (the tip creeps a little over the plate as it drags it).
    """

    def __init__(self, chain: FastChain, params: ExpertParams):
        self.chain, self.params = chain, params
        self.correction = np.zeros(2)
        self.object_offset = np.zeros(2)

    def reset(self) -> None:
        """Forget both corrections (they are part of the arm command from now on)."""
        self.correction[:] = 0.0
        self.object_offset[:] = 0.0

    def joint_offset(
        self, q_plan: np.ndarray, object_xy: np.ndarray | None, obs: dict[str, np.ndarray]
    ) -> np.ndarray:
        """Joint offset to add to ``q_plan`` this step; ``object_xy``: the plate's Eq. 2 xy."""
        p = self.params
        t, jac = self.chain.jacobian(q_plan)
        pressing = float(obs["finger_qpos"][0]) > p.contact_deflection
        if object_xy is not None and pressing:
            lag = object_xy - np.asarray(obs["object_pose"][:2], dtype=float)
            limit = p.max_object_correction
            self.object_offset = np.clip(self.object_offset + p.object_gain * lag, -limit, limit)
        setpoint = t[:2, 3] + self.object_offset
        error = setpoint - np.asarray(obs["fingertip_pose"][:2], dtype=float)
        limit = p.max_correction
        self.correction = np.clip(self.correction + p.tip_gain * error, -limit, limit)
        return _xy_step(jac, self.correction + self.object_offset)

    def adopt(self, q_cmd: np.ndarray, obs: dict[str, np.ndarray]) -> np.ndarray:
        """Take over a fingertip already pressed: keep the correction a tracker would have
        built up (the commanded fingertip's xy minus the measured one, clipped) and return
        the arm without it, whose fingertip is the measured one (where a plan starts)."""
        t, jac = self.chain.jacobian(q_cmd)
        error = t[:2, 3] - np.asarray(obs["fingertip_pose"][:2], dtype=float)
        limit = self.params.max_correction
        self.correction = np.clip(error, -limit, limit)
        self.object_offset = np.zeros(2)
        return np.asarray(q_cmd, dtype=float) - _xy_step(jac, self.correction)


def _xy_step(jac: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Joint step (damped least squares) that moves the frame by ``xy`` (m), turning nothing."""
    twist = np.r_[xy, 0.0, 0.0, 0.0, 0.0]
    return jac.T @ np.linalg.solve(jac @ jac.T + 1e-4 * np.eye(6), twist)
