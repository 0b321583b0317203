"""The WAM arm + T42 hand in a :class:`~slide_gym.sim.Simulation`.

Arm: PyBullet position motors on the 7 joints plus a gravity-compensation feedforward (clipped
to ``ARM_TORQUE_LIMITS``), updated with each arm target and applied every physics step (see
:class:`ArmGains`). Each motor is capped at ``min(ARM_TORQUE_LIMITS, ARM_PEAK_TORQUES -
|feedforward|)`` (the controller's output limit, and what the joint has left once the
feedforward is applied), so motor plus feedforward never exceeds ``ARM_PEAK_TORQUES``.

Hand: PyBullet has no joint springs, so the finger motors are switched off (VELOCITY_CONTROL,
force 0) and :meth:`WamT42.apply_hand_torques` applies the spring + tendon torque with
TORQUE_CONTROL before every physics step::

    tau = R f_max u - K (q - q0) - D dq

An explicit spring is unstable here: the distal mode's effective inertia is about 5e-6 kg m^2,
so with K_d = 2.4 N m/rad, omega * dt is about 3 at dt = 1/240 s (above the limit 2, and
damping applied explicitly only shrinks that limit). The torque is therefore computed
*implicitly*: the spring and damper act on the end-of-step velocity, predicted with the
finger's 2x2 joint-space inertia and an estimate of everything else acting on the joints
(gravity, contacts, coupling) taken from the previous step's velocity change. At rest the
applied torque equals the formula above exactly (no bias); in motion it is a backward-Euler
spring-damper, stable for any stiffness. ``HandParams(implicit=False)`` gives the plain
explicit law (for comparison; it blows up with the default stiffness). The estimator keeps
one step of history: :meth:`WamT42.reset` clears it, and :meth:`WamT42.get_state` /
:meth:`WamT42.set_state` save and restore it with the joints.

The tendon level follows the command at ``HandParams.u_rate`` per second (servo speed), so
a step in u does not slam the light fingers together.

Known limit: a tip pressed hard (>= 1 cm) onto a surface it cannot slide on (tip friction
>= ~0.6) can jam: the distal joint folds back to its stop and the contact chatters.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pybullet as pb

from slide_gym.assets import robot_urdf
from slide_gym.robot.kinematics import urdf_joints
from slide_gym.robot.model import (
    ARM_JOINTS,
    ARM_PEAK_TORQUES,
    ARM_TORQUE_LIMITS,
    FINGER_JOINTS,
    ArmGains,
    HandParams,
)
from slide_gym.sim import Simulation

BODY_NAME = "robot"
FINGERTIP_LINK = "fingertip_contact"
FINGER_LINKS = (
    ("t42_a_proximal_link", "t42_a_distal_link"),
    ("t42_b_proximal_link", "t42_b_distal_link"),
)
"""Finger A's links and finger B's (only :data:`FINGER_PAIRS_KEPT` collide, see
:meth:`WamT42.load`)."""
FINGER_PAIRS_KEPT = {("t42_a_distal_link", "t42_b_distal_link")}
"""The finger A / finger B link pairs that do collide: the tips."""
STATE_SIZE = 2 * 11 + 3 + 12
"""Length of :meth:`WamT42.get_state`."""
LOAD_FLAGS = (
    pb.URDF_USE_INERTIA_FROM_FILE
    | pb.URDF_USE_SELF_COLLISION
    | pb.URDF_USE_SELF_COLLISION_EXCLUDE_ALL_PARENTS
    | pb.URDF_MERGE_FIXED_LINKS
)
"""Self-collision without ancestor pairs: only finger A against finger B is checked (cheap);
arm links never collide with each other. Fixed links (flange, palm, fingertip frames) are
merged into their parents, which makes a physics step about a third cheaper; their frames are
still available through :meth:`WamT42.link_pose` as fixed offsets from the parent link."""


_DEFAULT_HAND = HandParams()
_DEFAULT_GAINS = ArmGains()


class WamT42:
    """The robot: load it, reset it, drive the arm and the hand, read its state."""

    def __init__(
        self,
        sim: Simulation,
        hand: HandParams = _DEFAULT_HAND,
        arm_gains: ArmGains = _DEFAULT_GAINS,
    ):
        self.sim = sim
        self.arm_gains = arm_gains
        self.body = -1
        self._u = 0.0  # commanded tendon level
        self._u_applied = 0.0  # level the servo has reached (rate limited)
        self._joints: dict[str, int] = {}
        self._links: dict[str, int] = {}
        self._movable: list[int] = []  # all movable joints, in PyBullet's DOF order
        self._arm_list: list[int] = []
        self._finger_list: list[int] = []
        self._arm_dof = np.zeros(7, dtype=int)  # positions within _movable
        self._finger_dof = np.zeros(4, dtype=int)
        self._inertia_coeffs = (0.0, 0.0, 0.0, 0.0)
        self.set_hand(hand)
        self._zeros: list[float] = []
        self._arm_dof_limits: list[tuple[int, float]] = []
        self._finger_dof_list: list[int] = []
        # finger (dq, tau, estimated other torques) of the last step
        self._prev: tuple[list[float], list[float], list[float]] | None = None
        self._other = [0.0] * 4
        self._base_pose: tuple = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))

    # ------------------------------------------------------------------ set-up
    def set_hand(self, hand: HandParams) -> None:
        """Use ``hand``'s spring and tendon model from the next physics step on."""
        self.hand = hand
        self._hand_coeffs = tuple(
            tuple(float(v) for v in arr)
            for arr in (hand.stiffness, hand.damping, hand.rest, hand.tendon)
        )

    def load(self) -> int:
        """Load the URDF as body ``"robot"`` (fixed base at the origin); return its id."""
        c = self.sim.client
        self.body = self.sim.load_urdf(BODY_NAME, robot_urdf(), (0.0, 0.0, 0.0), True, LOAD_FLAGS)
        self._joints, self._links, self._movable = {}, {}, []
        for j in range(c.getNumJoints(self.body)):
            info = c.getJointInfo(self.body, j)
            self._joints[info[1].decode()] = j
            self._links[info[12].decode()] = j
            if info[2] != pb.JOINT_FIXED:
                self._movable.append(j)
        self._frames = _merged_frames(robot_urdf(), self._links)
        # Of the two fingers only the distal links (the tips) collide with each other. A hand
        # closed on nothing presses them together with 10-40 N through the tendon, and every
        # finger-finger contact between these light links made the arm diverge (joint speeds
        # pinned at 20 rad/s) in 10 of 20 random-action episodes. The tips must still meet:
        # around a pinched card they keep the pads from scissoring past each other (0.8 mm
        # plates slipped out in 6 of 8 lifts without). With the tips alone, 2 of the 20
        # episodes show a one-step kick of 9-13 rad/s and none diverges.
        for a in FINGER_LINKS[0]:
            for b in FINGER_LINKS[1]:
                if (a, b) not in FINGER_PAIRS_KEPT:
                    la, lb = self._links[a], self._links[b]
                    c.setCollisionFilterPair(self.body, self.body, la, lb, 0)
        self._arm_list = [self._joints[n] for n in ARM_JOINTS]
        self._finger_list = [self._joints[n] for n in FINGER_JOINTS]
        self._arm_dof = np.array([self._movable.index(j) for j in self._arm_list])
        self._finger_dof = np.array([self._movable.index(j) for j in self._finger_list])
        c.setJointMotorControlArray(
            self.body, self._finger_list, pb.VELOCITY_CONTROL, forces=[0.0] * 4
        )
        self._inertia_coeffs = tuple(float(v) for v in self._calibrate_finger_inertia())
        self._zeros = [0.0] * len(self._movable)
        self._arm_dof_limits = [
            (int(i), float(lim)) for i, lim in zip(self._arm_dof, ARM_TORQUE_LIMITS, strict=True)
        ]
        self._finger_dof_list = [int(i) for i in self._finger_dof]
        self._feedforward = [0.0] * len(self._movable)
        # Bound once: BulletClient builds a new partial on every attribute access.
        self._get_joint_states = c.getJointStates
        self._set_motors = c.setJointMotorControlArray
        self.reset(np.zeros(7))
        return self.body

    def _calibrate_finger_inertia(self) -> np.ndarray:
        """Coefficients (a, b, e, c) of a finger's 2x2 joint-space inertia.

        For two parallel revolute joints M11 = a + 2 s, M12 = c + s, M22 = c with
        s = b cos(q2) + e sin(q2) (q2: distal angle); read off PyBullet's mass matrix at
        q2 = 0 and pi/2 (finger A; finger B is the same finger turned by pi).
        """
        c = self.sim.client
        i_p, i_d = self._finger_dof[:2]
        blocks = []
        for q2 in (0.0, np.pi / 2):
            q = np.zeros(len(self._movable))
            q[i_d] = q2
            m = np.array(c.calculateMassMatrix(self.body, q.tolist()))
            blocks.append(m[np.ix_([i_p, i_d], [i_p, i_d])])
        m0, m90 = blocks
        cc = m0[1, 1]
        b, e = m0[0, 1] - cc, m90[0, 1] - cc
        return np.array([m0[0, 0] - 2 * b, b, e, cc])

    # ------------------------------------------------------------------ indices
    def link_index(self, name: str) -> int:
        """PyBullet link index carrying a URDF link's frame (the base ``wam_base`` is -1).

        A merged fixed link (e.g. ``fingertip_contact``) reports the link it was merged into.
        """
        if name == "wam_base":
            return -1
        try:
            return self._frames[name][0]
        except KeyError:
            raise KeyError(f"no link {name!r}; links: {sorted(self._frames)}") from None

    def joint_index(self, name: str) -> int:
        """PyBullet joint index of a URDF joint."""
        try:
            return self._joints[name]
        except KeyError:
            raise KeyError(f"no joint {name!r}; joints: {sorted(self._joints)}") from None

    @property
    def finger_a_links(self) -> list[int]:
        """Link indices of finger A (the sliding finger): proximal, distal."""
        return [self._links[f"t42_a_{n}_link"] for n in ("proximal", "distal")]

    @property
    def finger_b_links(self) -> list[int]:
        """Link indices of finger B: proximal, distal."""
        return [self._links[f"t42_b_{n}_link"] for n in ("proximal", "distal")]

    # ------------------------------------------------------------------ commands
    def reset(self, arm_q: np.ndarray, finger_q: np.ndarray | None = None) -> None:
        """Teleport the joints (velocities 0) and set the arm targets there.

        Fingers default to their rest angles. The hand controller starts afresh: tendon
        command and level 0 (open), no estimator history.
        """
        c = self.sim.client
        arm_q = np.asarray(arm_q, dtype=float).reshape(7)
        finger_q = self.hand.rest if finger_q is None else np.asarray(finger_q, float).reshape(4)
        joints = self._arm_list + self._finger_list
        for j, q in zip(joints, np.concatenate([arm_q, finger_q]), strict=True):
            c.resetJointState(self.body, j, float(q), 0.0)
        self._prev = None
        self._u = self._u_applied = 0.0
        self.set_arm_targets(arm_q)

    def set_arm_targets(self, q: np.ndarray, dq: np.ndarray | None = None) -> None:
        """Position control of the 7 arm joints (optional target velocities, rad/s).

        The feedforward is updated first; each motor is then capped so that motor plus
        feedforward stays within the joint's ``ARM_PEAK_TORQUES`` (see :meth:`motor_caps`).
        A position gain is the fraction of the error closed per physics step, so it is scaled
        by the step span in force (``sim.physics`` against ``sim.settings``, see
        :meth:`Simulation.adapt`): the arm tracks its targets as at the base rate.
        """
        g = self.arm_gains
        span = round(self.sim.physics.timestep / self.sim.settings.timestep)
        if g.gravity_compensation:
            self._update_gravity_feedforward()
        self.sim.client.setJointMotorControlArray(
            self.body,
            self._arm_list,
            pb.POSITION_CONTROL,
            targetPositions=np.asarray(q, dtype=float).reshape(7).tolist(),
            targetVelocities=[0.0] * 7 if dq is None else np.asarray(dq, float).tolist(),
            forces=self.motor_caps().tolist(),
            positionGains=[span * k for k in g.position_gains],
            velocityGains=list(g.velocity_gains),
        )

    def arm_feedforward(self) -> np.ndarray:
        """The gravity feedforward (7,) applied to the arm joints every physics step (N m)."""
        return np.array([self._feedforward[i] for i in self._arm_dof])

    def motor_caps(self) -> np.ndarray:
        """The arm motors' torque caps (7,): ``min(ARM_TORQUE_LIMITS, ARM_PEAK_TORQUES -
        |feedforward|)``, never below 0, so ``|motor + feedforward| <= ARM_PEAK_TORQUES``."""
        room = ARM_PEAK_TORQUES - np.abs(self.arm_feedforward())
        return np.clip(np.minimum(ARM_TORQUE_LIMITS, room), 0.0, None)

    def _update_gravity_feedforward(self) -> None:
        """Gravity torques at the current configuration, clipped to ``ARM_TORQUE_LIMITS``.

        Computed when a new arm target arrives (the control rate: the arm moves a few
        hundredths of a radian between targets) and applied every physics step.
        """
        c = self.sim.client
        q = [s[0] for s in c.getJointStates(self.body, self._movable)]
        g = c.calculateInverseDynamics(self.body, q, self._zeros, self._zeros)
        tau = [0.0] * len(self._movable)
        for i, limit in self._arm_dof_limits:
            tau[i] = min(max(g[i], -limit), limit)
        self._feedforward = tau

    def set_hand_command(self, u: float) -> None:
        """Tendon command u, clipped to [0, 1] (1 closes the hand).

        The applied level follows at ``HandParams.u_rate`` per second (servo speed).
        """
        self._u = float(np.clip(u, 0.0, 1.0))

    @property
    def hand_command(self) -> float:
        """The last commanded tendon level u."""
        return self._u

    @property
    def hand_activation(self) -> float:
        """The tendon level currently applied (approaches u at the servo rate)."""
        return self._u_applied

    def apply_hand_torques(self) -> list[float]:
        """Apply the finger spring/tendon torques (and the arm's gravity feedforward).

        Call exactly once before every physics step (the torques last one step).
        Returns the 4 finger torques. This runs every physics step, so it works on plain
        Python floats: NumPy's per-call overhead on 4-element arrays costs more than the math.
        """
        states = self._get_joint_states(self.body, self._finger_list)
        q = [s[0] for s in states]
        dq = [s[1] for s in states]
        step = self.hand.u_rate * self.sim.physics.timestep
        du = self._u - self._u_applied
        self._u_applied += min(max(du, -step), step)
        finger = self._finger_torques(q, dq)
        tau = list(self._feedforward)
        for i, t in zip(self._finger_dof_list, finger, strict=True):
            tau[i] = t
        self._set_motors(self.body, self._movable, pb.TORQUE_CONTROL, forces=tau)
        return finger

    def _finger_torques(self, q: list[float], dq: list[float]) -> list[float]:
        """Spring + tendon torques (4,) for finger state (q, dq); advances the estimator."""
        k, d, rest, tendon = self._hand_coeffs
        ua = self._u_applied
        tau_s = [tendon[i] * ua - k[i] * (q[i] - rest[i]) for i in range(4)]
        if self.hand.implicit:
            tau = self._implicit(tau_s, q, dq)
        else:
            tau = [tau_s[i] - d[i] * dq[i] for i in range(4)]
        self._prev = (dq, tau, self._other)
        return tau

    def _implicit(self, tau_s: list[float], q: list[float], dq: list[float]) -> list[float]:
        """Backward-Euler spring-damper: (M + dt D + dt^2 K) v1 = M dq + dt (tau_s + other).

        Per finger, M is the 2x2 joint-space inertia; ``other`` estimates what acted on the
        joints besides our torque during the last step (gravity, contacts, coupling).
        """
        dt = self.sim.physics.timestep
        a, b, e, cc = self._inertia_coeffs
        k, d, _, _ = self._hand_coeffs
        tau = [0.0] * 4
        other = [0.0] * 4
        for f in (0, 2):  # proximal index of finger A, then finger B
            p, t = f, f + 1
            s = b * math.cos(q[t]) + e * math.sin(q[t])
            m11, m12, m22 = a + 2 * s, cc + s, cc
            other_p = other_t = 0.0
            if self._prev is not None:
                dq0, tau0, other0 = self._prev
                acc_p, acc_t = (dq[p] - dq0[p]) / dt, (dq[t] - dq0[t]) / dt
                # Averaged with the last estimate: the raw one-step estimate feeds back our
                # own torque with a step's delay and chatters at the Nyquist rate.
                other_p = 0.5 * (m11 * acc_p + m12 * acc_t - tau0[p] + other0[p])
                other_t = 0.5 * (m12 * acc_p + m22 * acc_t - tau0[t] + other0[t])
            other[p], other[t] = other_p, other_t
            gain_p, gain_t = d[p] + dt * k[p], d[t] + dt * k[t]
            rhs_p = m11 * dq[p] + m12 * dq[t] + dt * (tau_s[p] + other_p)
            rhs_t = m12 * dq[p] + m22 * dq[t] + dt * (tau_s[t] + other_t)
            a11, a22 = m11 + dt * gain_p, m22 + dt * gain_t
            det = a11 * a22 - m12 * m12
            tau[p] = tau_s[p] - gain_p * (a22 * rhs_p - m12 * rhs_t) / det
            tau[t] = tau_s[t] - gain_t * (a11 * rhs_t - m12 * rhs_p) / det
        self._other = other
        return tau

    def step_physics(self) -> None:
        """apply_hand_torques() then one physics step."""
        self.apply_hand_torques()
        self.sim.step()

    def get_state(self) -> np.ndarray:
        """Everything that decides the robot's next physics steps, as :data:`STATE_SIZE`
        float64s: joint angles and velocities (7 arm joints, then FINGER_JOINTS), the tendon
        command and applied level, and the finger estimator's history (a 0/1 flag, then the
        last finger velocities, torques and estimated other torques). The arm's motor targets
        are not in it: the caller sends them every control step."""
        q, dq = self.joint_state()
        has_prev = self._prev is not None
        prev = [v for part in self._prev for v in part] if self._prev else [0.0] * 12
        return np.concatenate([q, dq, [self._u, self._u_applied, float(has_prev)], prev])

    def set_state(self, state: np.ndarray) -> None:
        """Put the joints and the hand controller in ``state`` (from :meth:`get_state`)."""
        s = np.asarray(state, dtype=float)
        n = len(ARM_JOINTS) + len(FINGER_JOINTS)
        c = self.sim.client
        for j, q, dq in zip(self._arm_list + self._finger_list, s[:n], s[n : 2 * n], strict=True):
            c.resetJointState(self.body, j, float(q), float(dq))
        self._u, self._u_applied = float(s[2 * n]), float(s[2 * n + 1])
        prev = [float(v) for v in s[2 * n + 3 :]]
        if s[2 * n + 2]:
            self._prev = (prev[:4], prev[4:8], prev[8:])
            self._other = prev[8:]
        else:
            self._prev, self._other = None, [0.0] * 4

    def move_apart(self, far: tuple[float, float, float]) -> None:
        """Move the base to ``far`` and open the fingers as wide as they go, so that the next
        collision pass finds no contact on the robot (not even finger against finger).
        :meth:`set_state` then :meth:`move_back` put it back."""
        c = self.sim.client
        self._base_pose = c.getBasePositionAndOrientation(self.body)
        c.resetBasePositionAndOrientation(self.body, far, (0.0, 0.0, 0.0, 1.0))
        for j in self._finger_list:
            c.resetJointState(self.body, j, c.getJointInfo(self.body, j)[8], 0.0)

    def move_back(self) -> None:
        """The base back where :meth:`move_apart` found it."""
        self.sim.client.resetBasePositionAndOrientation(self.body, *self._base_pose)

    # ------------------------------------------------------------------ state
    def _joint_state(self, joints: list[int]) -> tuple[np.ndarray, np.ndarray]:
        states = self.sim.client.getJointStates(self.body, joints)
        q = np.fromiter((s[0] for s in states), float, len(joints))
        dq = np.fromiter((s[1] for s in states), float, len(joints))
        return q, dq

    def joint_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Angles (11,) and velocities (11,): the 7 arm joints, then FINGER_JOINTS (one call)."""
        return self._joint_state(self._arm_list + self._finger_list)

    def arm_joint_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Arm angles (7,) and velocities (7,)."""
        return self._joint_state(self._arm_list)

    def finger_joint_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Finger angles (4,) and velocities (4,) in FINGER_JOINTS order."""
        return self._joint_state(self._finger_list)

    def link_pose(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """World position (3,) and quaternion xyzw (4,) of a link frame (not its inertial frame)."""
        c = self.sim.client
        link = self.link_index(name)
        _, offset_pos, offset_quat = self._frames[name]
        if link == -1:
            pos, quat = c.getBasePositionAndOrientation(self.body)
        else:
            state = c.getLinkState(self.body, link, computeForwardKinematics=True)
            pos, quat = state[4], state[5]
        if offset_pos is not None:
            pos, quat = c.multiplyTransforms(pos, quat, offset_pos, offset_quat)
        return np.array(pos), np.array(quat)

    def fingertip_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """Pose of ``fingertip_contact`` (finger A's tip apex): position (3,), quat xyzw (4,)."""
        return self.link_pose(FINGERTIP_LINK)


def _merged_frames(
    urdf: Path, links: dict[str, int]
) -> dict[str, tuple[int, tuple | None, tuple | None]]:
    """Every URDF link -> (PyBullet link index carrying it, offset position, offset quaternion).

    Links kept by PyBullet have no offset; a fixed link merged into its parent gets the
    composed origins of the fixed joints between it and the nearest kept ancestor.
    """
    joints = urdf_joints(str(urdf))
    fixed = {
        j.child: (j.parent, j.xyz, pb.getQuaternionFromEuler(j.rpy))
        for j in joints
        if j.type == "fixed"
    }
    frames: dict[str, tuple[int, tuple | None, tuple | None]] = {"wam_base": (-1, None, None)}
    frames.update({name: (index, None, None) for name, index in links.items()})
    for link in (j.child for j in joints):
        if link in frames:
            continue
        pos, quat, parent = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0), link
        while parent not in frames:
            parent, xyz, q = fixed[parent]
            pos, quat = pb.multiplyTransforms(xyz, q, pos, quat)
        carrier, p_pos, p_quat = frames[parent]
        if p_pos is not None:
            pos, quat = pb.multiplyTransforms(p_pos, p_quat, pos, quat)
        frames[link] = (carrier, tuple(pos), tuple(quat))
    return frames
