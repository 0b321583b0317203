"""The expert's settings: planner parameters with margins for the real slide, and execution
speeds, heights and feedback gains."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from slide_gym.planning.api import GraspParams, SlideParams
from slide_gym.robot.model import ARM_LOWER, ARM_UPPER, MIN_CONTACT_SIZE, PINCH_DEPTH

EXPERT_PINCH_DEPTH = 0.035
"""How far (m) in from the overhang's outer end the expert's fingertips pinch, where the
table edge leaves room (the planner's default: ``PINCH_DEPTH``, 1.5 cm). A plate pinched
near its rim pivots in the grip when it is heavy: held 1.5 cm in, generated plates of 50 g
or more stayed on the table in about half their episodes (docs/benchmarks.md)."""

EXPERT_SLIDE_PARAMS = SlideParams(
    dz=(0.012, 0.02),
    press_radius=0.015,
    press_edge_margin=0.008,
    u_star=0.04,
    centroid_margin=0.015,
    max_rotation=0.8,
    tip_edge_margin=0.01,
    grasp=GraspParams(retreat=0.06 + EXPERT_PINCH_DEPTH - PINCH_DEPTH, depth=EXPERT_PINCH_DEPTH),
    goal_sampling="band",
)
"""Planner settings the expert uses by default, with margins for the real slide:

- contact depth 1.2-2.0 cm: shallower presses let the fingertip slip over the plate, deeper
  ones bring finger B within millimetres of the plate top;
- press points at least 8 mm inside the plate's outline (a rounded tip slips off an edge),
  and of those, the ones within 1.5 cm of the one nearest the plate's centroid (the plate
  then hardly spins about the tip);
- a planned overhang of 4 cm (2 cm more than the hand's u*) with the centroid at least
  1.5 cm inside the edge, for plates large enough (smaller ones get what room they leave:
  :meth:`agents.expert.SlideGraspExpert._slide_params`);
- at most 0.8 rad of plate rotation: in larger turns the plate slips about the fingertip;
- the fingertip at least 1 cm inside the table edge: the fingertip creeps ahead of the plate
  and the tracker shifts it further, and a plate pressed beyond the edge tips over it;
- the grasp pinched up to :data:`EXPERT_PINCH_DEPTH` in from the plate's outer end, and
  approached from a stand-off 8 cm out (6 cm clear of the plate's corners for a pinch
  ``PINCH_DEPTH`` deep, and as much deeper as the pinch is, so the hand turns toward the
  grasp as far from the plate as it did before the deeper pinch);
- goal roots from the paper's band C_g (``goal_sampling="band"``), which these margins were
  tuned with: with the plate-first goals, the L on the square table (seed 2, ee_delta
  control) fell off while grasped. Plates too small for the full margins draw plate-first
  goals (:func:`plate_slide_params`)."""


THIN_PLATE = 0.002
"""Plates thinner than this (m) get :func:`thin_plate_slide_params`."""
THIN_PLATE_MAX_ROTATION = 0.4
"""The largest plate turn (rad) a strict plan may ask of a thin plate."""


def thin_plate_slide_params(params: SlideParams, thickness: float) -> SlideParams:
    """``params`` for a plate ``thickness`` (m) thick: below :data:`THIN_PLATE`, a plate turn
    of at most :data:`THIN_PLATE_MAX_ROTATION`.

    The pressed fingertip sinks through a sub-millimetre plate onto the table, which takes
    most of the press: a 0.5 mm plate pressed 1.6 cm deep carries 0.3 N, a 4 mm one 3.1 N.
    Dragged by the sunken tip's point contact, which hardly passes on a turn, a 0.5 mm shim
    turned 0.7 times the planned turn (a 4 mm one 1.0 times), so its yaw error grows with
    the turn asked for (``benchmarks/slide_rotation.py``, docs/benchmarks.md "Thin
    shims")."""
    if thickness >= THIN_PLATE:
        return params
    return dataclasses.replace(
        params, max_rotation=min(params.max_rotation, THIN_PLATE_MAX_ROTATION)
    )


GRASP_POSTURE = (-1.07, 1.73, 0.74, 1.26, 0.25, 1.46, -0.86)
"""An arm posture for a side grasp of a plate overhanging an edge beside the base (grasp
frame near (0.49, -0.26, 0.01) m, approaching along +y, palm up): the median grasp of the
tightest of the six IK branches the expert's square-table grasps used when it took the
solution nearest the arm's sliding configuration. The expert grasps on the branch nearest
it or its mirror images (:func:`~slide_gym.robot.kinematics.mirrored_postures`)."""

_COUNTS = ("max_replans", "strict_plan_iterations", "grasp_iterations", "route_iterations")
"""The integer fields of :class:`ExpertParams`: caps that count work, never time."""


@dataclass(frozen=True)
class ExpertParams:
    """Execution speeds, heights and gains (SI units), and the expert's planning caps.

    The caps count work, so the same seed gives the same episode on any machine; the
    episode's ``time_budget`` only decides when the expert gives up. Their values follow the
    clock-based caps they replaced, measured on the 2-core development machine (all objects
    and tables, seeds 0-2, 10 s budget):

    - ``strict_plan_iterations``: search iterations of the plan with the full margins before
      the expert plans with relaxed ones (it replaced "half the time budget"). Of 180 strict
      plans given 5 s, the 142 solved ones took a median of 85 iterations (90th percentile
      307, largest 607); the 38 that ran out of time had reached 141-1155 iterations (median
      611: the rate varies from 30 to 240 iterations/s with the plate and table). 300 makes
      22 of the 180 decide differently (17 solved ones go relaxed, 5 timed-out ones get more
      iterations; 400 would make 17, but at slow rates it leaves too little of a 10 s budget
      for the relaxed plan: 14 of 72 episodes gave up on a loaded machine, against 8 that ran
      out of time with the old split).
    - ``grasp_iterations``: iterations of the fallback transfer planner per grasp candidate
      when the grasp is re-aimed at the measured plate pose (it replaced a 1 s cap on the
      whole re-aim, within which each fallback also had at most 0.25 s). The 28 re-aims of 72
      episodes that needed the fallback took 1-49 iterations (median 5); 0.25 s held about
      50-80. Same value as ``GraspParams.transfer_iterations``.
    - ``route_iterations``: iterations of the joint-space route planner for the approach to
      the press point when neither the direct move nor a move via a raised pose is free (2 of
      72 episodes, both replans; before, the expert took the colliding route anyway).

    ``grasp_posture`` (7 joint angles, or None): the re-aimed grasp is the IK solution
    nearest this posture or its mirror images, so that demonstrations of similar plate poses
    end in similar grasps, which a learner can imitate; None takes the solution nearest the
    arm's own IK branch after the slide (the grasps then spread over the branches that the
    sliding configurations happened to be on).

    ``stop_overhang`` (m, or None): end a slide early, still pressing, once the plate's
    measured overhang reaches this, then settle and lift off as at the plan's end. None
    follows the plan to its end, whose overhang the planner samples anywhere from u* to
    several centimetres beyond it. A fixed stop makes the moment a slide ends a function of
    what a learner observes (the overhang), not of a plan it cannot see.

    ``straight_slide_on`` (bool; ``1``/``0`` on the command line): taking over a fingertip
    pressed on a plate not yet graspable, drag it straight on toward the edge that needs the
    shortest drag (:func:`agents.takeover.slide_straight_on`) before trying a planned slide
    on; False tries the planned one first. A planned slide on may aim at any edge, so two
    takeovers a few steps apart can disagree; the straight one aims where the state says,
    which DAgger's labels need.

    ``nearest_goal_edge`` (bool; ``1``/``0`` on the command line): plan every slide toward
    the reachable stretch of the table's outline nearest the plate (``SlideParams.goal_edge
    = "nearest"``) instead of toward any; where that stretch admits no goal (a plan answered
    infeasible), that attempt and the later ones aim at any edge. Which side a plate goes is
    then a function of where it lies, not of the search's luck: of the 200 square grasps of
    ``slide-gym/square-grasp-ee-stop-anchor-v1``, 98 went to the side of the square table
    nearest the plate's start and 102 across it (``benchmarks/slide_sides.py``), a choice a
    learner cannot see.

    ``straight_transfer`` (bool; ``1``/``0`` on the command line): move the hand from the
    lift-off to the re-aimed grasp along straight lines, turning at a constant rate
    (diagonally to above the pre-grasp, else up to the clear height, across and down; the
    first that is collision-free), instead of the planner's joint-space legs, whose hand path
    bends with the arm's IK branch. The grasp's pose is the planner's; False, or no free
    straight path, keeps the planner's transfer.

    The press, slide, final-approach and lift speeds are 1.5-1.6x, the closing time 0.75x,
    and the holds after the press, after the slide and at the grasp's stand-off half or a
    third, those of the figures measured before the quicker defaults (CHANGELOG: 0.02, 0.05,
    0.04 and 0.05 m/s, 0.8 s; 0.3 s each; pass them as ``--expert-param`` to reproduce such a
    figure). They bring the median simulated episode from about 22 s to 17.0-17.9 s on five
    of the six grasp sets and 18.1 s at half scale (docs/benchmarks.md, Every set at one
    commit). The lift-off and free-space speeds stay:
    a lift-off at 8 cm/s let 25 slid plates fall in six sets where 5 cm/s let 10 fall, and
    free moves at 1.5 rad/s knocked plates off the table in the press and the transfer.
    """

    approach_speed: float = 1.0  # rad/s, free-space joint speed
    ramp_s: float = 0.4  # s over which free-space legs, the slide and the lift speed up and down
    pre_contact_height: float = 0.03  # m above the press point before pressing
    press_speed: float = 0.03  # m/s fingertip speed while pressing
    press_hold_s: float = 0.15  # s pressed before the slide starts
    slide_speed: float = 0.075  # m/s fingertip speed along the slide
    lift_off_speed: float = 0.05  # m/s the fingertip rises off the plate after the slide
    transfer_speed: float = 1.0  # rad/s
    transfer_tip_speed: float = 0.4  # m/s of the grasp frame during the transfer
    lift_off_height: float = 0.06  # m the fingertip rises off the plate after the slide
    grasp_iterations: int = 100  # fallback transfer iterations when re-aiming the grasp
    settle_s: float = 0.1  # s at the stand-off pose: the arm settles before the approach
    grasp_speed: float = 0.06  # m/s on the final approach to the grasp
    close_s: float = 0.6  # hand closing time before lifting
    lift: float = 0.12  # m the grasp frame rises
    lift_speed: float = 0.08  # m/s
    tip_gain: float = 0.3  # per control step, integral gain of the fingertip loop
    object_gain: float = 0.02  # per control step, integral gain of the plate-pose loop
    max_object_correction: float = 0.03  # m
    slide_settle_s: float = 0.15  # s at the slide's end: the plate comes to rest, still pressed
    contact_deflection: float = 0.05  # rad of finger A's proximal joint: it is pressing
    max_correction: float = 0.04  # m, largest Cartesian correction of the fingertip
    max_replans: int = 2
    pull_back_margin: float = 0.012  # m: a slid plate's centroid closer to the edge is pulled back
    strict_plan_iterations: int = 300  # search iterations of the plan with full margins
    route_iterations: int = 200  # route planner iterations for the approach, if needed
    min_centroid_margin: float = 0.005  # m, for plates too small for the full margin
    grasp_u_star: float = MIN_CONTACT_SIZE + 0.002  # m, least real overhang to grasp (u* + 2 mm)
    pinch_u_star: float = 0.0175  # m, least overhang measured to pinch and lift (small plates)
    grasp_posture: tuple[float, ...] | None = GRASP_POSTURE
    stop_overhang: float | None = None
    straight_slide_on: bool = False
    nearest_goal_edge: bool = False
    straight_transfer: bool = False

    def __post_init__(self) -> None:
        for name, value in dataclasses.asdict(self).items():
            if name == "grasp_posture":
                _check_posture(value)
            elif name in ("straight_slide_on", "nearest_goal_edge", "straight_transfer"):
                if not isinstance(value, bool):
                    raise ValueError(f"{name} must be True or False (1 or 0): {value!r}")
            elif name == "stop_overhang" and value is None:
                continue
            elif name in _COUNTS:
                least = 0 if name == "max_replans" else 1
                if isinstance(value, bool) or not isinstance(value, int) or value < least:
                    raise ValueError(f"{name} must be an integer >= {least}, got {value!r}")
            elif not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"ExpertParams.{name} must be a finite positive number: {value}")


def expert_params(values: dict[str, float | None]) -> ExpertParams:
    """:class:`ExpertParams` with ``values`` replacing its defaults; a ValueError naming an
    unknown field and the allowed ones."""
    fields = [f.name for f in dataclasses.fields(ExpertParams)]
    unknown = sorted(set(values) - set(fields))
    if unknown:
        raise ValueError(f"unknown expert parameters {unknown}; allowed: {', '.join(fields)}")
    defaults = ExpertParams()
    counted = {k: _as_field_type(getattr(defaults, k), v) for k, v in values.items()}
    return dataclasses.replace(defaults, **counted)


def _as_field_type(default: Any, value: Any) -> Any:
    """A number from the command line as its field's type: the caps that count work are
    integers (``NAME=3`` arrives as 3.0), a switch is 1 or 0."""
    if isinstance(default, bool):
        return bool(value) if value in (0, 1) else value
    if isinstance(default, int) and isinstance(value, float) and value.is_integer():
        return int(value)
    return value


def _check_posture(value: tuple[float, ...] | None) -> None:
    if value is None:
        return
    q = np.asarray(value, dtype=float)
    if q.shape != (7,) or not ((q >= ARM_LOWER) & (q <= ARM_UPPER)).all():
        raise ValueError(
            f"grasp_posture must be 7 joint angles within the arm's limits "
            f"{ARM_LOWER.tolist()} .. {ARM_UPPER.tolist()}, or None: {value!r}"
        )


def plate_slide_params(sp: SlideParams, p: ExpertParams, circumradius: float) -> SlideParams:
    """``sp`` with the margins a plate of ``circumradius`` (m) leaves room for.

    A plate's overhang plus its centroid's depth inside the edge cannot exceed its
    circumradius. Both start from their least useful values (``p.grasp_u_star`` + 2 mm,
    ``p.min_centroid_margin``) and share the room left, up to ``sp``'s full margins: large
    plates get those, small ones less. A plate with no room for both plans its overhang down
    to ``p.pinch_u_star`` + 2 mm (then grasped from :func:`plate_grasp_u_star`). A plate
    without room for ``p.grasp_u_star`` + 2 mm of overhang and ``sp.centroid_margin`` draws
    its goal roots with ``goal_sampling="plate"``.
    """
    room = circumradius - 0.003
    u_least, m_least = p.grasp_u_star + 0.002, p.min_centroid_margin
    extra = room - u_least - m_least
    if extra <= 0.0:  # down to the overhang the hand was measured to pinch (plate_grasp_u_star)
        u_plan = max(min(MIN_CONTACT_SIZE, p.pinch_u_star + 0.002), room - m_least)
        margin = m_least
    else:
        u_plan = min(sp.u_star, u_least + 0.5 * extra)
        margin = min(sp.centroid_margin, room - u_plan)
    # A contact farther in than this cannot push the plate u_plan past the edge (the press
    # points lie within press_radius of the one nearest the centroid; 1 cm of slack for
    # shapes whose centroid is off the plate): keep the goal region's band that narrow, or
    # small plates draw mostly hopeless goals.
    reach_in = circumradius + (sp.press_radius or circumradius) + 0.01 - u_plan
    width = min(sp.goal_band_width, max(reach_in, sp.tip_edge_margin + 0.01))
    # A plate that cannot overhang the grasp threshold with the full centroid margin (all
    # half-scale catalog plates, no full-scale one) draws its goal roots through its own goal
    # pose: from the band, few of them let it overhang enough.
    sampling = "plate" if is_small_plate(sp, p, circumradius) else sp.goal_sampling
    return dataclasses.replace(
        sp, u_star=u_plan, centroid_margin=margin, goal_band_width=width, goal_sampling=sampling
    )


def is_small_plate(sp: SlideParams, p: ExpertParams, circumradius: float) -> bool:
    """Whether a plate of ``circumradius`` (m) lacks room for ``p.grasp_u_star`` + 2 mm of
    overhang with ``sp.centroid_margin`` (every half-scale catalog plate, no full-scale one):
    it gets plate-first goal roots and the unloading lift-off."""
    return circumradius - 0.003 < p.grasp_u_star + 0.002 + sp.centroid_margin


def plate_grasp_u_star(p: ExpertParams, planned: SlideParams, small: bool = False) -> float:
    """The least real overhang (m) at which the expert grasps a plate planned with
    ``planned`` (:func:`plate_slide_params`): ``p.grasp_u_star``; for a ``small`` plate
    (:func:`is_small_plate`) ``p.pinch_u_star``, the least overhang of a half-scale circle and
    square corner the T42 pinched and lifted in physics (1.25 cm and, in 2 of 3 placements,
    1.5 cm slipped). A small plate's slide is planned to more (2 mm or more above
    ``p.pinch_u_star``, more where it has room) and lands a few millimetres short of plan
    as often as past it; a plate that lands between the two thresholds is grasped rather than
    slid again."""
    return min(p.grasp_u_star, p.pinch_u_star) if small else p.grasp_u_star


def turning_slide_params(params: SlideParams, grasp_u_star: float) -> SlideParams:
    """Settings for when even the relaxed plan finds no goal configuration: the relaxed ones
    with any plate turn, and the planned overhang down to 2 mm above ``grasp_u_star`` (the
    overhang the plate will be grasped from, :func:`plate_grasp_u_star`). A small plate whose
    far points must face an edge the arm can grasp at may need to turn further than 1.6 rad
    (in ten half-scale episodes planned in vain with 1.6 rad, six were lifted with any turn),
    and a plate reaching little more than u* + 1 cm past its centroid cannot overhang its
    planned 2.65 cm with the fingertip 1 cm inside the edge."""
    relaxed = relaxed_slide_params(params)
    return dataclasses.replace(
        relaxed, max_rotation=math.pi, u_star=min(relaxed.u_star, grasp_u_star + 0.002)
    )


def relaxed_slide_params(params: SlideParams) -> SlideParams:
    """Settings for when no plan with the full margins comes within its iteration cap: any
    plate turn up to 1.6 rad, press points up to 3 cm from the centroid, a planned overhang
    of u* + 1 cm (3 cm) with the centroid 0.5 cm inside the edge, and no iteration cap."""
    return dataclasses.replace(
        params,
        max_iterations=None,
        max_rotation=max(params.max_rotation, 1.6),
        press_radius=None if params.press_radius is None else max(params.press_radius, 0.03),
        u_star=min(params.u_star, MIN_CONTACT_SIZE + 0.01),
        centroid_margin=min(params.centroid_margin, 0.005),
    )
