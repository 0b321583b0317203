"""Collision checking of arm configurations in a private PyBullet DIRECT world.

The world holds the robot URDF (fingers at rest), the table prisms (built exactly as the
environment builds them) and optionally the object plate. :meth:`CollisionChecker.collides`
sets the seven arm joints, runs PyBullet's collision detection once and looks at the contact
list: robot-table (and robot-object) contacts and self-collisions between links that can
move relative to each other. Pairs that can never tell anything are filtered out up front
with ``setCollisionFilterPair``: parent-child links, links rigidly joined (link 7, palm and
the resting fingers), pairs already touching at ``READY_ARM_Q`` and two pairs whose crude
cylinders overlap well inside the joint limits (see ``_ARTIFACT_PAIRS``). About 15-40 us per
check.
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Sequence

import numpy as np
import pybullet as pb

from slide_gym.assets import robot_urdf
from slide_gym.geometry import ObjectShape, TableShape
from slide_gym.robot.model import ARM_JOINTS, READY_ARM_Q
from slide_gym.sim import Simulation
from slide_gym.task import add_table_body

MODES: tuple[str, ...] = ("sliding", "full")
FINGER_A_LINKS: tuple[str, ...] = ("t42_a_proximal_link", "t42_a_distal_link")
_ARTIFACT_PAIRS: tuple[tuple[str, str], ...] = (
    ("wam_link5", "wam_link7"),  # wrist cylinders overlap once |j6| > ~0.5 rad
    ("wam_link1", "wam_link3"),  # shoulder column vs upper arm from j2 ~ 1.2 rad (limit 2.0)
)
"""Link pairs whose primitive shapes overlap inside the joint limits although the real arm
is built to move through them; they would forbid most configurations near the table."""
_BASE = -1
_PARKED = (0.0, 0.0, -50.0)  # where the object waits when it is not part of the world


class CollisionChecker:
    """Robot vs table / object / itself for arm configurations ``q`` (7,).

    Modes: ``"full"`` checks everything in the world. ``"sliding"`` ignores finger A's links
    against the table: the planner lets the contact point sink up to Delta_Z+ below the object
    top (the real compliant finger flexes instead), which puts finger A's tip below the table
    top, so its contact with the table is the modelled flexing, not a collision. The object is
    never part of the ``"sliding"`` check (the fingertip touching it is the task) and only
    part of ``"full"`` while placed with :meth:`place_object`.

    Args:
        table: the support surface.
        obj: optional plate to include in ``"full"`` checks once placed.
        tolerance: contacts deeper than this (m, PyBullet distance below ``-tolerance``) count.
    """

    def __init__(self, table: TableShape, obj: ObjectShape | None = None, tolerance: float = 0.0):
        self.table = table
        self.tolerance = float(tolerance)
        self.sim = Simulation()
        c = self.sim.client
        self._cid = c._client  # noqa: SLF001 - raw calls skip BulletClient's per-call overhead
        self.table_id = add_table_body(self.sim, table)
        self.object_id = -2
        self.object_placed = False
        if obj is not None:
            half = obj.thickness / 2.0
            self.object_id = self.sim.create_prism_body(
                "object", obj.convex_pieces(), -half, half, mass=0.0, position=_PARKED
            )
            self._object_half = half
        self.robot = self.sim.load_urdf("robot", robot_urdf(), flags=pb.URDF_USE_SELF_COLLISION)
        self.links: dict[str, int] = {}
        parents: dict[int, int] = {}
        moving: dict[int, bool] = {}
        for j in range(c.getNumJoints(self.robot)):
            info = c.getJointInfo(self.robot, j)
            self.links[info[12].decode()] = j
            parents[j] = info[16]
            moving[j] = info[1].decode() in ARM_JOINTS
        self.arm_indices = [self.links[n.replace("wam_j", "wam_link")] for n in ARM_JOINTS]
        self.finger_a = frozenset(self.links[n] for n in FINGER_A_LINKS)
        self.self_pairs = self._filter_self_pairs(parents, moving)

    # ------------------------------------------------------------------ set-up
    def _has_shape(self, link: int) -> bool:
        return bool(self.sim.client.getCollisionShapeData(self.robot, link))

    def _filter_self_pairs(
        self, parents: dict[int, int], moving: dict[int, bool]
    ) -> list[tuple[int, int]]:
        """Disable uninformative link pairs; return the self pairs still checked."""
        links = [_BASE, *parents]
        shaped = [k for k in links if self._has_shape(k)]

        def group(k: int) -> int:  # the link a rigid cluster hangs from (fixed joints merged)
            while k != _BASE and not moving[k]:
                k = parents[k]
            return k

        def parent_group(k: int) -> int:
            g = group(k)
            return _BASE if g == _BASE else group(parents[g])

        self._set_joints(READY_ARM_Q)
        pb.performCollisionDetection(physicsClientId=self._cid)
        touching = {
            frozenset((p[3], p[4]))
            for p in pb.getContactPoints(self.robot, self.robot, physicsClientId=self._cid)
        }
        artifacts = {frozenset(self.links[n] for n in pair) for pair in _ARTIFACT_PAIRS}
        kept = []
        for a, b in itertools.combinations(shaped, 2):
            ga, gb = group(a), group(b)
            skip = (
                ga == gb
                or parent_group(a) == gb
                or parent_group(b) == ga
                or frozenset((a, b)) in touching
                or frozenset((a, b)) in artifacts
            )
            if skip:
                pb.setCollisionFilterPair(
                    self.robot, self.robot, a, b, 0, physicsClientId=self._cid
                )
            else:
                kept.append((a, b))
        return kept

    def _set_joints(self, q: Sequence[float]) -> None:
        pb.resetJointStatesMultiDof(
            self.robot,
            self.arm_indices,
            [[float(v)] for v in q],
            physicsClientId=self._cid,
        )

    # ----------------------------------------------------------------- queries
    def place_object(self, pose: Sequence[float] | None) -> None:
        """Put the plate at world pose (x, y, yaw) on the table top, or remove it (None)."""
        if self.object_id < 0:
            raise ValueError("this CollisionChecker was built without an object")
        if pose is None:
            self.sim.reset_base_pose("object", _PARKED, 0.0)
            self.object_placed = False
            return
        x, y, yaw = (float(v) for v in pose)
        z = self.table.height + self._object_half
        self.sim.reset_base_pose("object", (x, y, z), yaw)
        self.object_placed = True

    def contacts(self, q: np.ndarray, mode: str = "full") -> list[tuple[str, str, float]]:
        """All counted contacts at ``q``: (robot link, other body/link, distance)."""
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        self._set_joints(q)
        pb.performCollisionDetection(physicsClientId=self._cid)
        names = {v: k for k, v in self.links.items()} | {_BASE: "wam_base"}
        out = []
        for p in pb.getContactPoints(bodyA=self.robot, physicsClientId=self._cid):
            if self._counts(p, mode):
                other = "table" if p[2] == self.table_id else "object"
                if p[2] == self.robot:
                    other = names[p[4]]
                out.append((names[p[3]], other, float(p[8])))
        return out

    def _counts(self, p: tuple, mode: str) -> bool:
        if p[8] >= -self.tolerance:
            return False
        if p[2] == self.object_id:
            return mode == "full"
        return not (mode == "sliding" and p[2] == self.table_id and p[3] in self.finger_a)

    def collides(self, q: np.ndarray, mode: str = "full") -> bool:
        """True if configuration ``q`` (7,) is in collision under ``mode``."""
        self._set_joints(q)
        pb.performCollisionDetection(physicsClientId=self._cid)
        for p in pb.getContactPoints(bodyA=self.robot, physicsClientId=self._cid):
            if self._counts(p, mode):
                return True
        return False

    def segment_free(self, a: np.ndarray, b: np.ndarray, mode: str, resolution: float) -> bool:
        """Check the joint-space straight line a -> b every ``resolution`` rad (max joint).

        The states are checked end first, then in bisection order (midpoint, quarter points,
        ...), so a blocked segment is usually found after a few checks; a free one costs the
        same as a sweep.
        """
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        n = max(1, int(np.ceil(np.abs(b - a).max() / resolution)))
        return not any(self.collides(a + (i / n) * (b - a), mode) for i in _bisection_order(n))

    def close(self) -> None:
        """Disconnect the private PyBullet client (safe to call twice)."""
        self.sim.close()


@functools.lru_cache(maxsize=256)
def _bisection_order(n: int) -> tuple[int, ...]:
    """1..n with n first, then the midpoints of ever finer halvings (each index once; cached:
    segment checks ask for the same few lengths over and over)."""
    order, seen = [n], {0, n}
    spans = [(0, n)]
    while spans:
        nxt = []
        for lo, hi in spans:
            if hi - lo < 2:
                continue
            mid = (lo + hi) // 2
            if mid not in seen:
                seen.add(mid)
                order.append(mid)
            nxt += [(lo, mid), (mid, hi)]
        spans = nxt
    return tuple(order)
