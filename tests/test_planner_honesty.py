"""Re-check the top-slide planner's answers without using its code.

Each solved path is replayed in a fresh PyBullet DIRECT client that loads the URDF and a box
table built here: the fingertip frame comes from PyBullet's forward kinematics, collisions
from ``getClosestPoints``, the overhang from :mod:`slide_gym.geometry`.
"""

from __future__ import annotations

import math

import numpy as np
import pybullet as pb
import pytest
import shapely

from slide_gym.assets import robot_urdf
from slide_gym.geometry import get_object, get_table, overhang, transform_polygon
from slide_gym.planning import PlanStatus
from slide_gym.planning.api import SlideParams, TopSlidePlanner, TopSlideProblem

PARAMS = SlideParams()  # the paper's relaxations: dbeta = 0.1 rad, dz = [0.5, 2.5] cm
TOL_ANGLE = 1e-3  # rad
TOL_Z = 1e-4  # m
PENETRATION = 1e-3  # m, PyBullet contact distances below -this count as collisions
CASES = [  # (object, table, start pose, seed, planner)
    ("square", "square", (0.55, 0.02, 0.3), 0, "regions"),
    ("circle", "square", (0.62, -0.08, 0.0), 1, "regions"),
    ("triangle", "long", (0.56, 0.12, 1.0), 2, "regions"),
    ("crescent", "square", (0.7, 0.1, 2.0), 3, "cbirrt"),
    ("irregular", "long", (0.6, -0.3, -1.0), 4, "cbirrt2"),
]
ARM_LINKS = [f"wam_link{i}" for i in range(1, 8)]
HAND_LINKS = ["t42_palm", "t42_a_proximal_link", "t42_a_distal_link"]
HAND_LINKS += ["t42_b_proximal_link", "t42_b_distal_link"]
FINGER_A = {"t42_a_proximal_link", "t42_a_distal_link"}
FINGER_B = {"t42_b_proximal_link", "t42_b_distal_link"}
# Primitive shapes that overlap inside the joint limits although the real arm moves through
# them (wrist housings around joint 6; shoulder column vs upper arm below j2 = 2.0 rad).
IGNORED_SELF = {frozenset(("wam_link5", "wam_link7")), frozenset(("wam_link1", "wam_link3"))}


class Replay:
    """The robot and a box table in their own PyBullet client."""

    def __init__(self, table_name: str):
        self.cid = pb.connect(pb.DIRECT)
        table = get_table(table_name)
        minx, miny, maxx, maxy = table.polygon.bounds
        assert table.polygon.equals(shapely.box(minx, miny, maxx, maxy)), "box tables only"
        half = [(maxx - minx) / 2, (maxy - miny) / 2, table.slab_thickness / 2]
        shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=half, physicsClientId=self.cid)
        centre = [(minx + maxx) / 2, (miny + maxy) / 2, table.height - half[2]]
        self.table = pb.createMultiBody(0, shape, basePosition=centre, physicsClientId=self.cid)
        self.robot = pb.loadURDF(str(robot_urdf()), useFixedBase=True, physicsClientId=self.cid)
        self.link = {}
        self.joint = {}
        for j in range(pb.getNumJoints(self.robot, physicsClientId=self.cid)):
            info = pb.getJointInfo(self.robot, j, physicsClientId=self.cid)
            self.link[info[12].decode()] = j
            self.joint[info[1].decode()] = j
        self.arm = [self.joint[f"wam_j{i}"] for i in range(1, 8)]

    def set(self, q: np.ndarray) -> None:
        for j, v in zip(self.arm, q, strict=True):
            pb.resetJointState(self.robot, j, float(v), physicsClientId=self.cid)

    def frame(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        st = pb.getLinkState(
            self.robot, self.link[name], computeForwardKinematics=True, physicsClientId=self.cid
        )
        rot = np.array(pb.getMatrixFromQuaternion(st[5])).reshape(3, 3)
        return np.array(st[4]), rot

    def distance(self, link_a: str, other: str | None) -> float:
        """Closest distance of a robot link to the table (other None) or another link."""
        kw = {"linkIndexA": self.link[link_a]}
        if other is None:
            body = self.table
        else:
            body = self.robot
            kw["linkIndexB"] = self.link[other]
        pts = pb.getClosestPoints(self.robot, body, 0.05, physicsClientId=self.cid, **kw)
        return min((p[8] for p in pts), default=math.inf)

    def close(self) -> None:
        pb.disconnect(self.cid)


def _group(link: str) -> int:
    return ARM_LINKS.index(link) if link in ARM_LINKS else len(ARM_LINKS) - 1


def check_config(rp: Replay, q: np.ndarray, sliding: bool) -> None:
    rp.set(q)
    for link in ARM_LINKS + HAND_LINKS:
        if sliding and link in FINGER_A:
            continue
        assert rp.distance(link, None) >= -PENETRATION, f"{link} hits the table"
    links = ARM_LINKS + HAND_LINKS
    for i, a in enumerate(links):
        for b in links[i + 1 :]:
            if abs(_group(a) - _group(b)) < 2 or frozenset((a, b)) in IGNORED_SELF:
                continue
            assert rp.distance(a, b) >= -PENETRATION, f"self-collision {a} / {b}"


def planar(pos: np.ndarray, rot: np.ndarray) -> np.ndarray:
    return np.array([pos[0], pos[1], math.atan2(rot[1, 0], rot[0, 0])])


def eq2(gs: np.ndarray, gg: np.ndarray, ks: np.ndarray) -> np.ndarray:
    """Gamma_g * inv(Gamma_s) * kappa_s with homogeneous 3x3 matrices."""

    def mat(p):
        c, s = math.cos(p[2]), math.sin(p[2])
        return np.array([[c, -s, p[0]], [s, c, p[1]], [0, 0, 1]])

    m = mat(gg) @ np.linalg.inv(mat(gs)) @ mat(ks)
    return np.array([m[0, 2], m[1, 2], math.atan2(m[1, 0], m[0, 0])])


@pytest.fixture(scope="module")
def solved(solve_top_slide):
    return {
        (obj, table): solve_top_slide(obj, table, pose, PARAMS, kind, seed)
        for obj, table, pose, seed, kind in CASES
    }


@pytest.mark.parametrize(("obj", "table", "pose", "seed", "kind"), CASES)
def test_solution_is_honest(solved, obj, table, pose, seed, kind):
    check_honest(solved[(obj, table)], obj, table, pose, kind)


def check_honest(res, obj: str, table: str, pose, kind: str) -> None:
    """Every rule the answer claims, re-checked in a fresh PyBullet client."""
    assert res.solved, res.reason
    assert res.extra["planner"] == kind
    beta0, dbeta, (dz_lo, dz_hi) = PARAMS.beta0, PARAMS.dbeta, PARAMS.dz
    table_poly = get_table(table).polygon
    z_s = get_table(table).height + get_object(obj).thickness
    z_lo, z_hi = z_s - dz_hi, z_s - dz_lo
    assert res.extra["contact_height_range"] == pytest.approx([z_lo, z_hi])
    par = res.extra["parameters"]
    assert (par["beta0"], par["dbeta"], par["dz"]) == (beta0, dbeta, [dz_lo, dz_hi])
    assert par["u_star"] == PARAMS.u_star and par["n_star"] == 100
    rp = Replay(table)
    try:
        tips = []
        for q in res.path:
            rp.set(q)
            pos, rot = rp.frame("fingertip_contact")
            x_f, y_f, z_f = rot.T
            assert abs(x_f[2]) <= TOL_ANGLE, "roll: X_F not horizontal"
            beta = math.asin(-z_f[2])
            assert beta0 - dbeta - TOL_ANGLE <= beta <= beta0 + dbeta + TOL_ANGLE
            assert y_f[2] < 0.0, "finger B must be above finger A"
            assert z_lo - TOL_Z <= pos[2] <= z_hi + TOL_Z
            assert table_poly.contains(shapely.Point(pos[0], pos[1]))
            for link in FINGER_B:  # the idle finger stays above the plate top
                assert rp.distance(link, None) >= z_s - get_table(table).height - PENETRATION
            tips.append(pos)
        steps = np.linalg.norm(np.diff(tips, axis=0), axis=1)
        assert steps.max() <= 0.01 + 1e-6
        stride = max(1, len(res.path) // 40)
        for q in [*res.path[::stride], res.path[-1]]:
            check_config(rp, q, sliding=True)
        np.testing.assert_allclose(res.path[0], res.start_config)
        np.testing.assert_allclose(res.path[-1], res.goal_config)
        gammas = []
        for q in (res.start_config, res.goal_config):
            rp.set(q)
            gammas.append(planar(*rp.frame("fingertip_contact")))
        goal = eq2(gammas[0], gammas[1], np.asarray(pose, dtype=float))
        got = np.array(res.extra["object_goal_pose"])
        np.testing.assert_allclose(got[:2], goal[:2], atol=1e-6)
        assert abs(math.remainder(got[2] - goal[2], 2 * math.pi)) < 1e-6
        ov = overhang(transform_polygon(get_object(obj).polygon, *goal), table_poly)
        assert ov.u >= PARAMS.u_star and ov.centroid_inside
        assert res.extra["overhang_m"] == pytest.approx(ov.u, abs=1e-6)  # poses agree to 1e-6
        check_config(rp, np.array(res.extra["grasp_config"]), sliding=False)
        pos, rot = rp.frame("t42_palm")
        assert abs(rot[2, 2]) < 1e-3 and abs(abs(rot[2, 1]) - 1.0) < 1e-3  # side grasp
    finally:
        rp.close()


def test_same_seed_same_result(solve_top_slide):
    obj, table, pose, _, _ = CASES[0]
    a, b = (solve_top_slide(obj, table, pose, seed=5) for _ in range(2))
    assert a.solved and b.solved
    np.testing.assert_array_equal(a.path, b.path)
    assert a.extra["object_goal_pose"] == b.extra["object_goal_pose"]
    assert a.stats.counts() == b.stats.counts()


@pytest.mark.parametrize(
    ("build", "match"),
    [
        (lambda: SlideParams(dz=(0.02, 0.01)), "dz"),
        (lambda: SlideParams(dbeta=math.nan), "dbeta"),
        (lambda: SlideParams(step=0.0), "step"),
        (lambda: TopSlideProblem("square", "square", (math.nan, 0.0, 0.0)), "finite"),
        (lambda: TopSlideProblem("square", "square", (0.84, 0.0, 0.0)), "off table"),
        (lambda: TopSlideProblem("square", "square", (0.6, 0.0)), "3 finite"),
    ],
)
def test_bad_inputs_raise(build, match):
    with pytest.raises(ValueError, match=match):
        build()


def test_no_start_configuration_is_infeasible(solve_top_slide):
    # Pressing 2-2.5 cm deep at a pitch of 1.3-1.5 rad puts the idle finger into the plate.
    params = SlideParams(beta0=1.4, dbeta=0.1, dz=(0.02, 0.025))
    res = solve_top_slide("square", "square", (0.6, 0.0, 0.0), params)
    assert res.status is PlanStatus.INFEASIBLE and res.path is None
    assert "no start configuration" in res.reason
    assert res.extra["region_draws"]["start"] == [300, 0]


@pytest.mark.parametrize("budget", [math.nan, 0.0, -1.0, math.inf])
def test_bad_budget_raises(budget):
    planner = TopSlidePlanner(TopSlideProblem("square", "square", (0.6, 0.0, 0.0)), seed=0)
    try:
        with pytest.raises(ValueError, match="time_budget"):
            planner.solve(budget)
    finally:
        planner.close()


def _mid_slide(solved) -> tuple[np.ndarray, np.ndarray]:
    """A configuration halfway along case 0's path and where Eq. 2 has the plate then."""
    obj, table, pose, _, _ = CASES[0]
    res = solved[(obj, table)]
    q_mid = res.path[len(res.path) // 2]
    rp = Replay(table)
    try:
        gammas = []
        for q in (res.start_config, q_mid):
            rp.set(q)
            gammas.append(planar(*rp.frame("fingertip_contact")))
    finally:
        rp.close()
    return q_mid, eq2(gammas[0], gammas[1], np.asarray(pose, dtype=float))


def test_fixed_start_is_honest(solved):
    """A plan from a pressed arm mid-slide starts at that configuration and passes every
    check, with the plate where the first half of the slide left it."""
    obj, table, _, _, _ = CASES[0]
    q_mid, pose_mid = _mid_slide(solved)
    problem = TopSlideProblem(obj, table, pose_mid, PARAMS, allow_overhang=True)
    with TopSlidePlanner(problem, "regions", seed=9, start_config=q_mid) as planner:
        res = planner.solve(30.0)
    check_honest(res, obj, table, pose_mid, "regions")
    np.testing.assert_allclose(res.start_config, q_mid, atol=1e-6)
    assert res.extra["fixed_start"] and res.extra["region_draws"]["start"] == [0, 0]


def test_fixed_start_off_the_manifold_is_infeasible(solved):
    obj, table, _, _, _ = CASES[0]
    q_mid, pose_mid = _mid_slide(solved)
    q_off = q_mid + np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.4, 0.0])  # the wrist tilts the tip
    problem = TopSlideProblem(obj, table, pose_mid, PARAMS, allow_overhang=True)
    with TopSlidePlanner(problem, "regions", seed=9, start_config=q_off) as planner:
        res = planner.solve(5.0)
    assert res.status is PlanStatus.INFEASIBLE and res.path is None
    assert "start configuration" in res.reason


@pytest.mark.parametrize(
    ("kind", "q", "match"),
    [
        ("cbirrt", np.zeros(7), "regions planner"),
        ("regions", np.zeros(6), "7 finite"),
        ("regions", np.full(7, np.nan), "7 finite"),
    ],
)
def test_bad_fixed_start_raises(kind, q, match):
    problem = TopSlideProblem("square", "square", (0.6, 0.0, 0.0))
    with pytest.raises(ValueError, match=match):
        TopSlidePlanner(problem, kind, seed=0, start_config=q)
