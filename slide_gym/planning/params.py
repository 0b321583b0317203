"""Parameters of the top-sliding planner, with the paper's defaults where it gives them."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from numbers import Real
from typing import Any

import numpy as np

from slide_gym.planning.ik import IKParams
from slide_gym.planning.pair import GraspParams
from slide_gym.task import TaskParams

PROJECTIONS: tuple[str, ...] = ("steps", "nodes", "ompl", "orientation")
"""The values of :attr:`SlideParams.projection` (the first is the default)."""
GOAL_SAMPLINGS: tuple[str, ...] = ("plate", "band")
"""The values of :attr:`SlideParams.goal_sampling` (the first is the default)."""
GOAL_EDGES: tuple[str, ...] = ("any", "nearest")
"""The values of :attr:`SlideParams.goal_edge` (the first is the default)."""


@dataclass(frozen=True)
class SlideParams:
    """Planner parameters (SI units, radians); defaults follow the paper where it gives one.

    ``beta0 = 0.9`` rad (52 deg) is our choice (the paper gives none): finger B sits 52 mm
    from finger A across the hand, so with the pitch at most beta0 + dbeta = 1.0 rad and the
    contact up to dz_hi = 25 mm below the plate top, finger B's rounded tip still clears the
    plate top (52 mm * cos(1.0) - 10.5 mm * (1 - sin(1.0)) = 26.4 mm > 25 mm). Steeper pitches
    press harder but make the idle finger hit the plate.

    ``max_iterations`` (None: no cap, the paper's setting) caps the tree search's iterations
    (:attr:`~slide_gym.planning.result.SearchParams.max_iterations`; for ``cbirrt`` also the
    start/goal pairs it draws before the search): the query then ends with status
    ``iteration_limit``, on any machine at the same point, while the time budget only gives up.

    ``restart_iterations``: the ``cbirrt`` baseline searches this many iterations for a path
    between its validated start/goal pair, then draws a new validated pair and starts a new
    search (the paper's pair-based planner "has to restart with a different pair");
    ``cbirrt-norestart`` keeps its first pair for the whole budget.

    ``projection`` (one of :data:`PROJECTIONS`) chooses how the tree extension keeps to the
    manifold; the variants model what a CBiRRT implementation of the paper's time might have
    done (the ``relaxation`` experiment asks which makes dZ* = 0 hard):

    * ``"steps"`` (default): every extension step is projected by
      :meth:`~slide_gym.planning.constraints.SlideConstraints.project` (minimum-norm Newton on
      the violated constraints only, aiming inside the bands, each residual within
      ``tolerance``, at most 25 iterations); the stretch between two nodes counts as on the
      manifold (the found path is densified by projection).
    * ``"nodes"``: projection only at tree nodes: each new node is projected as above, but the
      edge from its parent is the straight joint-space chord, accepted only if points on it
      at most ``path_resolution`` of fingertip travel apart (and at least its midpoint) all
      satisfy the constraints within ``tolerance`` (a discrete motion validator).
    * ``"ompl"``: OMPL's ``Constraint::project`` with its defaults (OMPL 2.0.1:
      ``CONSTRAINT_PROJECTION_TOLERANCE`` 1e-4, ``CONSTRAINT_PROJECTION_MAX_ITERATIONS`` 50):
      Newton's method with the least-squares (SVD) step on all three residuals, until their
      Euclidean norm is below ``tolerance``; no aiming inside the bands, no clipping to the
      joint limits (a result outside them fails).
    * ``"orientation"``: the projection handles the roll and the pitch band only; the contact
      depth is checked, never projected onto, so a step that leaves the depth band fails.

    ``goal_sampling`` (one of :data:`GOAL_SAMPLINGS`) chooses how goal roots are drawn:
    ``"plate"`` (default) draws the plate's goal pose first, overhanging u* with its centroid
    on the table, and the fingertip from the inverse of Eq. 2 for the latest start root
    (:mod:`slide_gym.planning.plate_goals`); ``"band"`` is the paper's C_g (Eq. 4): the
    contact anywhere in the band P_g with any yaw.

    ``goal_edge`` (one of :data:`GOAL_EDGES`) chooses where goals may lie: ``"any"`` (default,
    the paper) along every stretch of the outline with a reachable side grasp; ``"nearest"``
    only along the one nearest the plate's start centroid and those joined to it end to end
    (:func:`~slide_gym.planning.grasp_reach.nearest_stretches`; needs
    ``goal_band_reachable``). With ``"any"`` a plate in the middle of the square table is
    slid toward either side, whichever the search meets first; with ``"nearest"`` the side
    is a function of where the plate lies, which a learner imitating the slide can see.
    """

    beta0: float = 0.9
    dbeta: float = 0.1  # paper: Delta_beta = 0.1 rad
    dz: tuple[float, float] = (0.005, 0.025)  # paper: Delta_Z = [0.5, 2.5] cm
    n_star: int = 100  # paper: N* = 100
    u_star: float = TaskParams.u_star
    step: float = 0.1  # rad, CBiRRT extension step (weighted joint distance)
    tolerance: float = 1e-4  # projection tolerance (rad on the axes' dot products, m)
    cloud_spacing: float = 0.01  # m, grid spacing of P_o
    goal_band_width: float = 0.05  # m, width of the band P_g inside the table outline
    goal_band_reachable: bool = True  # keep only edge stretches with a reachable side grasp
    path_resolution: float = 0.01  # m, largest fingertip move between returned path states
    max_rotation: float = math.inf  # rad, largest plate turn a valid pair may ask for
    centroid_margin: float = 0.0  # m the placed plate's centroid must lie inside the table edge
    press_edge_margin: float = 0.0  # m, least distance of a press point from the plate's edge
    press_radius: float | None = None  # m: press only near the centroid (None: anywhere, paper)
    tip_edge_margin: float = 0.0  # m the fingertip contact stays inside the table edge (0: paper)
    shortcut_attempts: int = 40  # constrained shortcuts tried on the found slide (0: none)
    max_iterations: int | None = None  # search iterations before giving up (None: no cap)
    restart_iterations: int = 100  # cbirrt: iterations on one pair before drawing a new one
    distance_weights: tuple[float, ...] = (1.0, 1.0, 1.0, 1.0, 0.6, 0.6, 0.3)
    projection: str = "steps"  # how the extension keeps to the manifold (PROJECTIONS)
    goal_sampling: str = "plate"  # how goal roots are drawn (GOAL_SAMPLINGS)
    goal_edge: str = "any"  # where goals may lie (GOAL_EDGES)
    ik: IKParams = field(default_factory=IKParams)
    grasp: GraspParams = field(default_factory=GraspParams)

    def __post_init__(self) -> None:
        for name in ("beta0", "dbeta", "u_star", "step", "tolerance", "cloud_spacing"):
            _finite(getattr(self, name), name, positive=name != "dbeta")
        for name in ("goal_band_width", "path_resolution"):
            _finite(getattr(self, name), name, positive=True)
        _finite(self.centroid_margin, "centroid_margin")
        _finite(self.press_edge_margin, "press_edge_margin")
        _finite(self.tip_edge_margin, "tip_edge_margin")
        if not (isinstance(self.max_rotation, Real) and self.max_rotation > 0):
            raise ValueError(f"max_rotation must be a positive number, got {self.max_rotation!r}")
        try:
            lo, hi = (float(v) for v in self.dz)
        except (TypeError, ValueError):
            raise ValueError(
                f"dz must be a pair (dz_lo, dz_hi) of numbers, got {self.dz!r}"
            ) from None
        _finite(lo, "dz_lo")
        _finite(hi, "dz_hi")
        if lo < 0.0 or hi < lo:
            raise ValueError(f"dz must satisfy 0 <= dz_lo <= dz_hi, got dz = ({lo}, {hi})")
        object.__setattr__(self, "dz", (lo, hi))
        if not (self.beta0 - self.dbeta > 0.0 and self.beta0 + self.dbeta < math.pi / 2):
            raise ValueError(
                f"beta0 +- dbeta must stay inside (0, pi/2), got {self.beta0} +- {self.dbeta}"
            )
        if isinstance(self.n_star, bool) or not isinstance(self.n_star, int) or self.n_star < 1:
            raise ValueError(f"n_star must be an integer >= 1, got {self.n_star!r}")
        if self.press_radius is not None:
            _finite(self.press_radius, "press_radius", positive=True)
        cap = self.max_iterations
        if cap is not None and (isinstance(cap, bool) or not isinstance(cap, int) or cap < 1):
            raise ValueError(f"max_iterations must be None or an integer >= 1, got {cap!r}")
        period = self.restart_iterations
        if isinstance(period, bool) or not isinstance(period, int) or period < 1:
            raise ValueError(f"restart_iterations must be an integer >= 1, got {period!r}")
        attempts = self.shortcut_attempts
        if isinstance(attempts, bool) or not isinstance(attempts, int) or attempts < 0:
            raise ValueError(f"shortcut_attempts must be an integer >= 0, got {attempts!r}")
        if not isinstance(self.projection, str) or self.projection not in PROJECTIONS:
            raise ValueError(
                f"projection must be one of {', '.join(PROJECTIONS)}, got {self.projection!r}"
            )
        if not isinstance(self.goal_sampling, str) or self.goal_sampling not in GOAL_SAMPLINGS:
            raise ValueError(
                f"goal_sampling must be one of {', '.join(GOAL_SAMPLINGS)}, "
                f"got {self.goal_sampling!r}"
            )
        if not isinstance(self.goal_edge, str) or self.goal_edge not in GOAL_EDGES:
            raise ValueError(
                f"goal_edge must be one of {', '.join(GOAL_EDGES)}, got {self.goal_edge!r}"
            )
        if self.goal_edge == "nearest" and not self.goal_band_reachable:
            raise ValueError('goal_edge="nearest" needs goal_band_reachable=True')
        w = np.asarray(self.distance_weights, dtype=float)
        if w.shape != (7,) or not (np.isfinite(w).all() and (w > 0).all()):
            raise ValueError("distance_weights must be 7 finite positive numbers")

    def contact_height_range(self, z_surface: float) -> tuple[float, float]:
        """The contact-height band [z_s - dz_hi, z_s - dz_lo] for plate-top height z_s."""
        return (z_surface - self.dz[1], z_surface - self.dz[0])

    def as_dict(self) -> dict[str, Any]:
        """Every value as plain Python data (for the result's ``extra``)."""
        out = asdict(self)
        out["dz"] = list(self.dz)
        out["distance_weights"] = list(self.distance_weights)
        if math.isinf(self.max_rotation):
            out["max_rotation"] = None  # no limit (JSON has no infinity)
        return out


def _finite(value: Any, name: str, positive: bool = False) -> None:
    if isinstance(value, bool) or not isinstance(value, Real) or not math.isfinite(value):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    if positive and value <= 0:
        raise ValueError(f"{name} must be > 0, got {value!r}")
    if value < 0:
        raise ValueError(f"{name} must be >= 0, got {value!r}")
