"""The WAM + T42 model: URDF kinematics, generator, finger springs, tendon, ready pose."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pybullet as pb
import pytest

from slide_gym.assets import robot_urdf
from slide_gym.robot import (
    ARM_LOWER,
    ARM_UPPER,
    READY_ARM_Q,
    HandParams,
    WamT42,
    flange_pose_dh,
)
from slide_gym.robot import model as m
from slide_gym.sim import PhysicsParams, Simulation

ROOT = Path(__file__).resolve().parents[1]


def _robot(gravity: float = -9.81, hand: HandParams | None = None) -> WamT42:
    sim = Simulation(physics=PhysicsParams(gravity=gravity))
    robot = WamT42(sim, hand or HandParams())
    robot.load()
    return robot


@pytest.fixture
def robot():
    r = _robot()
    yield r
    r.sim.close()


@pytest.fixture
def robot_no_gravity():
    r = _robot(gravity=0.0)
    yield r
    r.sim.close()


def _rot(quat: np.ndarray) -> np.ndarray:
    return np.array(pb.getMatrixFromQuaternion(quat.tolist())).reshape(3, 3)


def _settle(robot: WamT42, steps: int) -> None:
    for _ in range(steps):
        robot.step_physics()


def test_flange_pose_matches_dh_table(robot: WamT42) -> None:
    rng = np.random.default_rng(7)
    for _ in range(50):
        q = rng.uniform(ARM_LOWER, ARM_UPPER)
        robot.reset(q)
        pos, quat = robot.link_pose("wam_flange")
        expected = flange_pose_dh(q)
        assert np.allclose(pos, expected[:3, 3], atol=1e-3)
        rel = expected[:3, :3].T @ _rot(quat)
        angle = np.arccos(np.clip((np.trace(rel) - 1) / 2, -1.0, 1.0))
        assert angle < 1e-3


def test_committed_urdf_is_generated() -> None:
    spec = importlib.util.spec_from_file_location("generate_urdf", ROOT / "tools/generate_urdf.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    assert robot_urdf().read_text() == gen.build_urdf()


def test_fingertip_frame_at_rest(robot: WamT42) -> None:
    robot.reset(READY_ARM_Q)
    flange_pos, flange_quat = robot.link_pose("wam_flange")
    tip_pos, tip_quat = robot.fingertip_pose()
    flange, tip = _rot(flange_quat), _rot(tip_quat)
    assert np.allclose(tip[:, 2], flange[:, 2], atol=1e-6)  # Z_F = flange z
    assert np.allclose(tip[:, 0], flange[:, 0], atol=1e-6)  # X_F along the joint axes
    length = m.PIVOT_HEIGHT + m.PROXIMAL_LENGTH + m.DISTAL_LENGTH
    offset = flange.T @ (tip_pos - flange_pos)
    assert np.allclose(offset, [0.0, m.FINGER_BASE_SPACING / 2, length], atol=1e-6)


def _finger_a_jacobian(robot: WamT42) -> np.ndarray:
    """Tip Jacobian (3, 2) of finger A from its own joint frames."""
    tip, _ = robot.fingertip_pose()
    p1, quat = robot.link_pose("t42_a_proximal_link")
    p2, _ = robot.link_pose("t42_a_distal_link")
    axis = _rot(quat)[:, 0]
    return np.column_stack([np.cross(axis, tip - p1), np.cross(axis, tip - p2)])


@pytest.mark.parametrize("sign", [1.0, -1.0])  # +1 closes finger A, -1 pushes it open
def test_tip_deflection_matches_joint_stiffness(robot_no_gravity: WamT42, sign: float) -> None:
    robot = robot_no_gravity
    c = robot.sim.client
    robot.reset(READY_ARM_Q)
    _settle(robot, 20)
    rest, quat = robot.fingertip_pose()
    force = -sign * 0.5 * _rot(quat)[:, 1]  # 0.5 N along -Y_F: across the finger
    jac = _finger_a_jacobian(robot)
    predicted = jac @ np.linalg.solve(np.diag(robot.hand.stiffness[:2]), jac.T @ force)
    tip = robot.link_index("fingertip_contact")
    for _ in range(360):
        pos, _ = robot.fingertip_pose()
        c.applyExternalForce(robot.body, tip, force.tolist(), pos.tolist(), pb.WORLD_FRAME)
        robot.step_physics()
    loaded, _ = robot.fingertip_pose()
    assert np.abs(robot.finger_joint_state()[1]).max() < 1e-3  # static
    measured = loaded - rest
    assert 0.004 < np.linalg.norm(predicted) < 0.008
    assert np.linalg.norm(measured - predicted) < 0.1 * np.linalg.norm(predicted)
    _settle(robot, 240)
    assert np.linalg.norm(robot.fingertip_pose()[0] - rest) < 1e-3


def test_press_at_60_degrees_gives_centimetre_deflection() -> None:
    """2-4 N pressing straight up on a tip inclined 60 deg: 0.5-2.5 cm (static compliance)."""
    k = HandParams().stiffness[:2]
    finger = np.array([np.cos(np.pi / 3), -np.sin(np.pi / 3)])  # planar, pointing down
    normal = np.array([finger[1], -finger[0]])
    lengths = np.array([m.PROXIMAL_LENGTH + m.DISTAL_LENGTH, m.DISTAL_LENGTH])
    jac = np.outer(normal, lengths)  # straight finger: both columns across the finger
    for press in (2.0, 4.0):
        delta = jac @ np.linalg.solve(np.diag(k), jac.T @ np.array([0.0, press]))
        assert 0.005 <= np.linalg.norm(delta) <= 0.025


def test_tendon_closes_the_hand(robot: WamT42) -> None:
    robot.reset(READY_ARM_Q)
    _settle(robot, 10)
    gap_open = np.linalg.norm(robot.fingertip_pose()[0] - robot.link_pose("t42_b_fingertip")[0])
    robot.set_hand_command(1.0)
    _settle(robot, 240)
    q, dq = robot.finger_joint_state()
    gap = np.linalg.norm(robot.fingertip_pose()[0] - robot.link_pose("t42_b_fingertip")[0])
    assert robot.hand_activation == 1.0
    assert q[0] > 0.05 and q[2] > 0.05  # both proximal joints closed
    assert gap < gap_open - 0.02
    assert np.abs(dq).max() < 0.05
    robot.set_hand_command(0.0)
    _settle(robot, 240)
    assert np.abs(robot.finger_joint_state()[0]).max() < 0.01
    robot.set_hand_command(1.0)
    _settle(robot, 5)
    robot.reset(READY_ARM_Q)  # the controller starts afresh (deterministic episodes)
    assert robot.hand_command == 0.0 and robot.hand_activation == 0.0


def test_ready_pose_points_down_above_the_table(robot: WamT42) -> None:
    q = READY_ARM_Q
    assert np.all((q >= ARM_LOWER) & (q <= ARM_UPPER))
    c = robot.sim.client
    shape = c.createCollisionShape(pb.GEOM_BOX, halfExtents=[0.25, 0.45, 0.02])
    table = c.createMultiBody(0, shape, basePosition=[0.6, 0.0, -0.02])
    robot.reset(q)
    _, flange_quat = robot.link_pose("wam_flange")
    assert _rot(flange_quat)[:, 2] @ np.array([0.0, 0.0, -1.0]) > np.cos(np.radians(5))
    tip, _ = robot.fingertip_pose()
    assert 0.10 <= tip[2] <= 0.15
    assert abs(tip[0] - 0.55) < 0.05 and abs(tip[1]) < 0.05
    _settle(robot, 240)  # holds itself against gravity, touches nothing
    assert np.abs(robot.arm_joint_state()[0] - q).max() < 2e-3
    assert not c.getContactPoints(robot.body, table)
    assert not c.getClosestPoints(robot.body, table, 0.05)
    assert not c.getContactPoints(robot.body, robot.body)


def test_arm_tracks_a_new_target(robot: WamT42) -> None:
    robot.reset(READY_ARM_Q)
    target = READY_ARM_Q + np.array([0.3, -0.2, 0.2, 0.3, -0.3, 0.3, -0.3])
    robot.set_arm_targets(target)
    _settle(robot, 480)
    q, dq = robot.arm_joint_state()
    assert np.abs(q - target).max() < 2e-3
    assert np.abs(dq).max() < 1e-2


def test_finger_link_lists(robot: WamT42) -> None:
    a, b = robot.finger_a_links, robot.finger_b_links
    assert robot.link_index("fingertip_contact") in a
    assert robot.link_index("t42_b_distal_link") in b
    assert len(set(a) | set(b)) == 4


def test_hand_params_validation() -> None:
    assert np.allclose(HandParams().stiffness[1::2], 2 * HandParams().stiffness[0::2])
    with pytest.raises(ValueError):
        HandParams(k_proximal=0.0)
    with pytest.raises(ValueError):
        HandParams(d_distal=-1.0)


def test_motor_plus_feedforward_stays_within_the_joint_limits_when_pressing_the_table(
    robot: WamT42,
) -> None:
    """Hand driven into a table top (arm targets 10 cm below it): every physics step each
    joint's motor torque (PyBullet's applied torque) stays within the controller limit
    ARM_TORQUE_LIMITS and motor plus gravity feedforward within ARM_PEAK_TORQUES."""
    c = robot.sim.client
    shape = c.createCollisionShape(pb.GEOM_BOX, halfExtents=[0.25, 0.45, 0.02])
    table = c.createMultiBody(0, shape, basePosition=[0.6, 0.0, -0.02])
    robot.reset(READY_ARM_Q)
    tip, quat = robot.fingertip_pose()
    below = robot.sim.client.calculateInverseKinematics(
        robot.body,
        robot.link_index("fingertip_contact"),
        (tip - [0.0, 0.0, 0.22]).tolist(),  # 10 cm below the table top
        quat.tolist(),
        maxNumIterations=200,
    )
    target = np.array(below[:7])
    arm = [robot.joint_index(n) for n in m.ARM_JOINTS]
    saturated = np.zeros(7, bool)
    pressing = 0
    for k in range(480):
        if k % 12 == 0:  # new targets at the control rate, 0.05 rad per step toward `target`
            q = robot.arm_joint_state()[0]
            robot.set_arm_targets(q + np.clip(target - q, -0.05, 0.05))
        feedforward = robot.arm_feedforward()
        robot.step_physics()
        motor = np.array([s[3] for s in c.getJointStates(robot.body, arm)])
        assert np.all(np.abs(motor) <= m.ARM_TORQUE_LIMITS + 1e-6), (k, motor)
        assert np.all(np.abs(motor + feedforward) <= m.ARM_PEAK_TORQUES + 1e-6), (k, motor)
        saturated |= np.abs(motor) >= robot.motor_caps() - 1e-6
        pressing += k >= 240 and bool(c.getContactPoints(robot.body, table))
    assert pressing > 120  # it really pushes on the table (the pressed tip chatters a little)
    assert saturated[1]  # and joint 2's motor runs into its cap doing so
    # The feedforward (gravity, up to the controller limit) and the motor never sum past a
    # joint's peak torque: at READY_ARM_Q joint 2 needs 21.7 N m, above its 20 N m limit.
    robot.reset(READY_ARM_Q)
    assert abs(robot.arm_feedforward()[1]) == pytest.approx(m.ARM_TORQUE_LIMITS[1])
    assert np.all(robot.motor_caps() + np.abs(robot.arm_feedforward()) <= m.ARM_PEAK_TORQUES)
