"""Robot-side pieces of the top-slide planner: kinematics, IK, projection, collision, Eq. 2."""

from __future__ import annotations

import math

import numpy as np
import pybullet as pb
import pytest
import shapely

from slide_gym.assets import robot_urdf
from slide_gym.geometry import get_object, get_table, overhang, transform_polygon
from slide_gym.planning.api import (
    CollisionChecker,
    ContactBand,
    GoalRegion,
    GraspParams,
    IKParams,
    IKTarget,
    SlideConstraints,
    SlideParams,
    StartRegion,
    TopSlideProblem,
    contact_rotation,
    goal_band,
    grasp_poses,
    planar_pose,
    se2_compose,
    se2_inverse,
    slid_object_pose,
    solve_ik,
)
from slide_gym.robot.kinematics import fast_chain, grasp_chain, robot_chain
from slide_gym.robot.model import ARM_JOINTS, ARM_LOWER, ARM_UPPER, MIN_CONTACT_SIZE, READY_ARM_Q

TABLE = get_table("square")
BAND = ContactBand(beta0=0.9, dbeta=0.1, z_lo=-0.021, z_hi=-0.001, z_surface=0.004)


@pytest.fixture(scope="module")
def bullet():
    cid = pb.connect(pb.DIRECT)
    robot = pb.loadURDF(str(robot_urdf()), useFixedBase=True, physicsClientId=cid)
    names = {}
    for j in range(pb.getNumJoints(robot, physicsClientId=cid)):
        info = pb.getJointInfo(robot, j, physicsClientId=cid)
        names[info[1].decode()] = j
        names[info[12].decode()] = j
    yield cid, robot, names
    pb.disconnect(cid)


@pytest.fixture(scope="module")
def checker():
    cc = CollisionChecker(TABLE, get_object("square"))
    yield cc
    cc.close()


@pytest.fixture(scope="module")
def constraints():
    return SlideConstraints(fast_chain(), BAND, TABLE.polygon)


def random_configs(n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(ARM_LOWER, ARM_UPPER, (n, 7))


def contact_config(rng, constraints, xy=(0.6, 0.0), alpha=None) -> np.ndarray:
    alpha = rng.uniform(0, 2 * np.pi) if alpha is None else alpha
    target = IKTarget([xy[0], xy[1], -0.01], contact_rotation(alpha, 0.9))
    seed = np.array(READY_ARM_Q)
    seed[0] = math.atan2(xy[1], xy[0])
    return solve_ik(constraints.chain, target, rng, seed[None])


@pytest.mark.parametrize("tip", ["fingertip_contact", "t42_b_fingertip", "wam_flange"])
def test_forward_kinematics_matches_pybullet(bullet, tip):
    cid, robot, names = bullet
    chain, fast = robot_chain(tip), fast_chain(tip)
    qs = random_configs(30, seed=1)
    mine, quick = chain.forward(qs), fast.forward(qs)
    for q, t, t2 in zip(qs, mine, quick, strict=True):
        for name, v in zip(ARM_JOINTS, q, strict=True):
            pb.resetJointState(robot, names[name], v, physicsClientId=cid)
        st = pb.getLinkState(robot, names[tip], computeForwardKinematics=True, physicsClientId=cid)
        rot = np.array(pb.getMatrixFromQuaternion(st[5])).reshape(3, 3)
        np.testing.assert_allclose(t[:3, 3], st[4], atol=1e-6)
        np.testing.assert_allclose(t[:3, :3], rot, atol=1e-6)
        np.testing.assert_allclose(t2, t, atol=1e-12)


@pytest.mark.parametrize("chain", [robot_chain(), fast_chain(), grasp_chain()])
def test_jacobian_matches_finite_differences(chain):
    h = 1e-6
    for q in random_configs(5, seed=2):
        t, jac = chain.jacobian(q)
        for i in range(7):
            dq = np.zeros(7)
            dq[i] = h
            tp, tm = chain.forward(q + dq), chain.forward(q - dq)
            np.testing.assert_allclose(jac[:3, i], (tp[:3, 3] - tm[:3, 3]) / (2 * h), atol=1e-6)
            drot = (tp[:3, :3] - tm[:3, :3]) / (2 * h) @ t[:3, :3].T  # skew(omega)
            omega = [drot[2, 1], drot[0, 2], drot[1, 0]]
            np.testing.assert_allclose(jac[3:, i], omega, atol=1e-6)
    batch = random_configs(4, seed=3)
    np.testing.assert_allclose(chain.jacobian(batch)[1][2], chain.jacobian(batch[2])[1], atol=1e-12)


def test_ik_reaches_reachable_targets_within_limits():
    rng = np.random.default_rng(4)
    chain = fast_chain()
    goals = chain.forward(random_configs(20, seed=5))
    solved = 0
    for goal in goals:
        q = solve_ik(chain, IKTarget(goal[:3, 3], goal[:3, :3]), rng)
        if q is None:
            continue
        solved += 1
        assert np.all(q >= ARM_LOWER) and np.all(q <= ARM_UPPER)
        reached = chain.forward(q)
        np.testing.assert_allclose(reached[:3, 3], goal[:3, 3], atol=1e-4)
        np.testing.assert_allclose(reached[:3, :3], goal[:3, :3], atol=1e-3)
    assert solved >= 18
    # partial orientation: only the approach axis (z) of the grasp frame is prescribed
    target = IKTarget([0.5, 0.3, 0.1], np.eye(3)[:, [1, 2, 0]], axes=(2,))
    q = solve_ik(grasp_chain(), target, rng)
    assert q is not None
    t = grasp_chain().forward(q)
    np.testing.assert_allclose(t[:3, 2], target.rotation[:, 2], atol=1e-3)
    # far out of reach
    assert solve_ik(chain, IKTarget([2.5, 0.0, 0.0]), rng, params=IKParams(max_iters=30)) is None


def test_contact_rotation_convention():
    rot = contact_rotation(np.array([0.3, 2.0, 4.5]), 0.9)
    for r in rot:
        np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-12)
        assert np.linalg.det(r) == pytest.approx(1.0)
        assert r[2, 0] == pytest.approx(0.0, abs=1e-12)  # X_F horizontal
        assert math.asin(-r[2, 2]) == pytest.approx(0.9)  # pitch below the table plane
        assert r[2, 1] < 0.0  # finger B (-Y_F side) above finger A
        np.testing.assert_allclose(np.cross(r[:, 2], r[:, 0]), r[:, 1], atol=1e-12)


def test_projection_lands_on_relaxed_manifold(constraints):
    rng = np.random.default_rng(6)
    done = 0
    while done < 15:
        q0 = contact_config(rng, constraints)
        if q0 is None:
            continue
        assert constraints.satisfied(q0)
        q_bad = q0 + rng.normal(0.0, 0.05, 7)
        res = constraints.residuals(fast_chain().forward(q_bad))
        q = constraints.project(q_bad, q0)
        assert q is not None
        assert constraints.satisfied(q)
        assert np.all(q >= ARM_LOWER) and np.all(q <= ARM_UPPER)
        assert np.linalg.norm(q - q_bad) < 0.3
        done += np.abs(res).max() > constraints.tolerance  # it did have to move
    # hopeless: contact behind the robot (off the table) and finger B below finger A
    q_behind = np.array(READY_ARM_Q)
    q_behind[0] = math.pi - 0.1
    assert constraints.project(q_behind) is None
    q0 = contact_config(np.random.default_rng(7), constraints, alpha=math.pi / 2)
    flipped = q0.copy()
    flipped[6] += -math.pi if q0[6] > 0 else math.pi  # hand turned over: finger B below A
    assert fast_chain().forward(flipped)[2, 1] > 0.0
    assert constraints.project(flipped) is None


def test_collision_checker_table_and_self(checker, bullet):
    assert not checker.collides(READY_ARM_Q, "full")
    into = np.array(READY_ARM_Q)
    into[1] += 0.3  # drive the hand down through the table top
    assert checker.collides(into, "full")
    hits = checker.contacts(into, "full")
    assert {"t42_a_distal_link", "t42_b_distal_link"} <= {h[0] for h in hits}
    # in sliding mode only finger B counts here
    assert checker.collides(into, "sliding")
    assert {h[0] for h in checker.contacts(into, "sliding")} == {"t42_b_distal_link"}
    shallow = np.array(READY_ARM_Q)
    shallow[1] += 0.25  # only finger A's tip is below the table top
    assert checker.collides(shallow, "full") and not checker.collides(shallow, "sliding")
    # the object counts in "full" mode only while placed
    tip = fast_chain().forward(shallow)[:3, 3]
    checker.place_object((tip[0], tip[1], 0.0))
    try:
        assert any(h[1] == "object" for h in checker.contacts(shallow, "full"))
    finally:
        checker.place_object(None)
    # self-collisions: elbow folded so the wrist meets the base; the hand on the upper arm
    folded = np.array([0.0, 2.0, 0.0, 3.1, 0.0, 0.0, 0.0])
    pairs = {frozenset(h[:2]) for h in checker.contacts(folded, "full") if h[1] != "table"}
    assert frozenset(("wam_base", "wam_link6")) in pairs
    folded[[1, 5]] = (-1.5, 1.6)
    pairs = {frozenset(h[:2]) for h in checker.contacts(folded, "full") if h[1] != "table"}
    assert frozenset(("wam_link3", "t42_a_proximal_link")) in pairs
    assert checker.collides(folded, "sliding")
    # over random arms: collides() is contacts() != [], and "sliding" only ever drops contacts
    n_full = 0
    for q in random_configs(300, seed=8):
        full, sliding = checker.collides(q, "full"), checker.collides(q, "sliding")
        assert full == bool(checker.contacts(q, "full"))
        assert sliding == bool(checker.contacts(q, "sliding"))
        assert full or not sliding
        n_full += full
    assert 0 < n_full < 300


def test_eq2_and_overhang_hand_worked():
    # The fingertip sits 5 cm behind the plate centre along its X_F, then turns by +90 deg.
    kappa = slid_object_pose(
        np.array([0.5, 0.0, 0.0]), np.array([0.6, 0.2, math.pi / 2]), [0.55, 0.0, 0.1]
    )
    np.testing.assert_allclose(kappa, [0.6, 0.25, math.pi / 2 + 0.1], atol=1e-12)
    a = np.array([0.3, -0.2, 2.5])
    np.testing.assert_allclose(se2_compose(a, se2_inverse(a)), 0.0, atol=1e-12)
    # A 10 cm square pushed 5 cm across the y = 0.25 edge of the square table.
    square = get_object("square")
    placed = transform_polygon(
        square.polygon, *slid_object_pose([0.6, 0.18, 0.0], [0.6, 0.23, 0.0], [0.6, 0.18, 0.0])
    )
    ov = overhang(placed, TABLE.polygon)
    assert ov.u == pytest.approx(0.03) and ov.centroid_inside
    np.testing.assert_allclose(sorted(ov.edge[:, 1]), [0.25, 0.25])
    poses = grasp_poses(ov.outside, ov.edge, 0.002, GraspParams(depth=0.015))
    assert poses is not None and len(poses) == 2
    pos, rot = poses[0]
    np.testing.assert_allclose(pos, [0.6, 0.25 + 0.03 - 0.015, 0.002], atol=1e-9)
    np.testing.assert_allclose(rot[:, 2], [0.0, -1.0, 0.0], atol=1e-12)  # into the table
    assert abs(rot[2, 1]) == pytest.approx(1.0)  # palm y vertical: fingers above and below
    # a deeper pinch stops short of the table's edge face; too little plate in reach: none
    deep = grasp_poses(ov.outside, ov.edge, 0.002, GraspParams(depth=0.035))
    assert deep is not None
    np.testing.assert_allclose(deep[0][0], [0.6, 0.25 + 0.005, 0.002], atol=1e-9)
    for least, ok in ((0.024, True), (0.026, False)):  # 2.5 cm of plate within reach
        held = grasp_poses(ov.outside, ov.edge, 0.002, GraspParams(depth=0.035, least_hold=least))
        assert (held is not None) == ok
    # planar_pose reads (x, y, yaw of X_F)
    tip = np.eye(4)
    tip[:3, :3] = contact_rotation(1.2, 0.9)
    tip[:3, 3] = [0.4, 0.1, 0.0]
    np.testing.assert_allclose(planar_pose(tip), [0.4, 0.1, 1.2])


def test_regions_sample_valid_contacts(constraints, checker):
    rng = np.random.default_rng(9)
    prob = TopSlideProblem("circle", "square", (0.6, 0.05, 0.0), SlideParams())
    start = StartRegion(prob.start_points, constraints, checker)
    band = goal_band(TABLE.polygon, 0.05, 0.002)
    goal = GoalRegion(band, constraints, checker)
    disc = shapely.Point(0.6, 0.05).buffer(0.05 + 1e-6)
    for region, area in ((start, disc), (goal, band.buffer(1e-6))):
        got = [q for q in (region.sample(rng) for _ in range(20)) if q is not None]
        assert len(got) >= 8
        for q in got:
            assert constraints.satisfied(q) and not checker.collides(q, "sliding")
            tip = fast_chain().forward(q)
            assert area.contains(shapely.Point(tip[0, 3], tip[1, 3]))
    # The pruned band keeps the side edges near the robot, not the far edge (x = 0.85).
    assert band.within(TABLE.polygon.buffer(1e-9)) and band.area < 0.09
    assert not band.intersects(shapely.box(0.8, -0.2, 0.85, 0.2))
    assert band.contains(shapely.Point(0.5, 0.23))


def test_slide_params_validation():
    p = SlideParams()
    assert p.contact_height_range(0.004) == pytest.approx((-0.021, -0.001))
    assert p.n_star == 100 and p.dbeta == 0.1 and p.u_star == MIN_CONTACT_SIZE == 0.02
    with pytest.raises(ValueError, match="dz"):
        SlideParams(dz=(0.03, 0.01))
    with pytest.raises(ValueError, match="beta0"):
        SlideParams(beta0=1.6)
    with pytest.raises(ValueError, match="n_star"):
        SlideParams(n_star=0)
    with pytest.raises(ValueError, match="tolerance"):
        SlideParams(tolerance=-1e-3)
