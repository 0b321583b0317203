"""The dense reward of :class:`~slide_gym.envs.top_slide.TopSlideEnv`, as named terms.

Every step pays shaping terms, each a weighted potential in [0, 1] whose weights sum to 1, so a
step's shaping lies in [0, 1]. Success adds :attr:`DenseReward.success_bonus`; the step on which
the object falls off pays only :attr:`DenseReward.fall_penalty` (negative). With both set to the
horizon (the longest time limit, 1200 steps), for any episode of at most ``horizon`` steps::

    return(fell off) < 0 <= return(neither) <= horizon <= return(success)

so ending an episode by dropping the plate is never better than staying (and from any state,
strictly worse than any way of carrying on), and holding a near-success state until the time
limit never beats finishing. The same holds with a discount: from a state at step t, dropping
pays ``-gamma^t * horizon`` where carrying on pays at least 0, and lingering pays at most
``gamma^t * min(horizon - t, 1 / (1 - gamma))`` where succeeding pays ``gamma^t * horizon``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from slide_gym.task import SceneState, TaskParams

TERM_NAMES = ("reach", "progress", "lift", "success", "fall_off")
"""The keys of ``info["reward_terms"]`` in the dense envs (the same for both goals)."""

_WEIGHTS = {
    "slide": {"reach": 0.5, "progress": 0.5, "lift": 0.0},
    "grasp": {"reach": 0.25, "progress": 0.25, "lift": 0.5},
}


@dataclass(frozen=True)
class DenseReward:
    """Shaping potentials, a success bonus and a fall-off penalty (see the module docstring).

    Terms (each the weight times a potential in [0, 1]):

    - ``reach``: ``1 - tanh(d / reach_scale)``, d the fingertip-contact frame's distance (m) to
      the centre of the object's top face.
    - ``progress``: ``min(u / u*, 1)``, u the overhang past the nearest table edge line.
    - ``lift`` (``goal="grasp"`` only): ``clip(clearance / lift_height, 0, 1)``, the object's
      lowest point above the table top.
    - ``success``: ``success_bonus`` on the step that succeeds, else 0.
    - ``fall_off``: ``-fall_penalty`` on the step the object falls off, else 0; that step pays
      no shaping.
    """

    horizon: int = 1200
    """Longest episode (steps) the return ordering is guaranteed for: the longest registered
    time limit (grasp envs: 1200; slide envs: 800)."""
    reach_scale: float = 0.1
    """Distance (m) at which the reach potential has fallen to ``1 - tanh(1)`` (0.24)."""

    def __post_init__(self) -> None:
        if not (isinstance(self.horizon, int) and self.horizon >= 1):
            raise ValueError(f"horizon must be a positive integer, got {self.horizon!r}")
        if not (math.isfinite(self.reach_scale) and self.reach_scale > 0):
            raise ValueError(f"reach_scale must be a positive number, got {self.reach_scale}")

    @property
    def success_bonus(self) -> float:
        """At least the most shaping an episode of ``horizon`` steps can collect."""
        return float(self.horizon)

    @property
    def fall_penalty(self) -> float:
        """More than the most shaping the steps before a fall can collect."""
        return float(self.horizon)

    def terms(
        self,
        goal: str,
        s: SceneState,
        fingertip: np.ndarray,
        object_thickness: float,
        params: TaskParams,
        success: bool,
    ) -> dict[str, float]:
        """This step's terms for ``goal`` (``"slide"`` or ``"grasp"``); their sum is the reward."""
        if s.fell_off:
            return {**dict.fromkeys(TERM_NAMES, 0.0), "fall_off": -self.fall_penalty}
        w = _WEIGHTS[goal]
        top = np.array([s.object_pose[0], s.object_pose[1], s.object_z + object_thickness])
        d = float(np.linalg.norm(np.asarray(fingertip, dtype=float) - top))
        lift = min(max(s.clearance_m / params.lift_height, 0.0), 1.0) if w["lift"] else 0.0
        return {
            "reach": w["reach"] * (1.0 - math.tanh(d / self.reach_scale)),
            "progress": w["progress"] * min(max(s.overhang_m, 0.0) / params.u_star, 1.0),
            "lift": w["lift"] * lift,
            "success": self.success_bonus if success else 0.0,
            "fall_off": 0.0,
        }


def sparse_terms(success: bool) -> dict[str, float]:
    """The sparse reward's one term: 1 on success, else 0 (no fall-off penalty)."""
    return {"success": 1.0 if success else 0.0}
