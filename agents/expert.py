"""One episode of the planner-driven expert: plan, press, slide, re-aim, grasp, lift.

:class:`SlideGraspExpert` turns a :class:`~slide_gym.planning.top_slide.TopSlidePlanner`
result into the environment's actions: joint increments, or fingertip-pose increments with an
:class:`~agents.ee_actions.EEActions` (``control_mode="ee_delta"``). It reads everything from
observations (scene outlines, object pose, fingertip pose) and keeps its own copy of the
environment's arm targets.

Phases: ``approach`` (joint-space move to a pose above the press point, via a raised pose if
the direct move would hit something, else along a planned joint route; never a route the
collision checker rejected), ``press`` (straight down to the planned contact depth),
``slide`` (the planned path), ``pull_back`` (only if the plate's centroid ended up near or past
the edge), ``lift_off``, then a check of the real plate pose against Eq. 2's prediction. A
graspable plate gets a grasp re-aimed at its measured pose: ``transfer`` (up and around to a
stand-off outside the table edge; along straight lines with ``ExpertParams.straight_transfer``),
``approach_grasp``, ``close``, ``lift``. A plate left
ungraspable is re-planned from where it lies, within the total planning budget. While the
fingertip is pressed, :class:`~agents.tracking.ContactTracker` corrects the planned targets.

The expert takes over from any state, not only from an episode's start (what DAgger needs
of it): from its first observation it reads where things are. A plate in the closed hand is
lifted and held. A fingertip pressed on a plate not yet graspable slides on: a slide planned
from the pressed arm (the planner's fixed start, :mod:`agents.takeover`), else a straight drag
toward the nearest edge, is queued, and what follows a slide follows; on a plate already
graspable it lifts off as after a slide and grasps it as it lies. A fingertip pressed where
no slide on is found, or low near a graspable plate, first rises (``release``); one low beside
a plate not yet graspable is planned for from where it is (the approach rises straight up to
the height above the press point, then moves across), and rises first only where that plan
finds no approach. A plate already
graspable gets its grasp at once; a plate partly over the edge is planned from where it lies
(as a replan is); anything else is planned as at the start.

Same seed, same episode, on any machine: every planning step is capped by a count
(``ExpertParams.strict_plan_iterations``, ``grasp_iterations``, ``route_iterations``); the
planning budget only decides when the expert gives up (``report.gave_up`` says why; it then
holds still, and :func:`agents.episode.play_episode` ends the episode).
"""

from __future__ import annotations

import dataclasses
import itertools
import time
from collections import deque
from dataclasses import dataclass

import numpy as np
import shapely

from agents.ee_actions import EEActions
from agents.params import (
    ExpertParams,
    is_small_plate,
    plate_grasp_u_star,
    plate_slide_params,
    relaxed_slide_params,
    thin_plate_slide_params,
    turning_slide_params,
)
from agents.record import ExpertReport
from agents.scene import SceneLibrary
from agents.takeover import lift_off_pressed, slide_on, slide_straight_on
from agents.tracking import ContactTracker, cartesian_line, cartesian_walk, rise
from agents.trajectory import Segment, time_segment
from slide_gym.geometry import (
    ObjectShape,
    Overhang,
    TableShape,
    overhang,
    quat_yaw,
    transform_polygon,
    wrap_angle,
)
from slide_gym.planning.api import (
    IKTarget,
    SlideParams,
    TopSlidePlanner,
    TopSlideProblem,
    planar_pose,
    slid_object_pose,
    solve_ik,
)
from slide_gym.planning.result import PlanResult, PlanStatus
from slide_gym.robot.kinematics import (
    FastChain,
    fingertip_chain,
    grasp_chain,
    mirrored_postures,
)
from slide_gym.robot.model import ARM_LOWER, ARM_UPPER, READY_ARM_Q

LOW_TIP_HEIGHT = 0.03
"""m: a fingertip this close above the table top (pressing the plate, or low beside it) when
the expert takes over rises first: from there every route would start in collision."""
ON_PLATE_MARGIN = 0.01
"""m: a fingertip within this distance of the plate's outline counts as on the plate."""
RETIME_MIN_STEP = 0.1
"""Action units: a re-timed plan's actions may always move this fast (a learner off a plan
that holds still is led back at this pace)."""
RETIME_WINDOW = 20
"""Queued targets a re-timed plan looks ahead for ones the learner has already passed."""
HELD_HEIGHT = 0.01
"""m: a plate whose bottom is this far above the table top, with the hand closed, is in the
hand when the expert takes over (it lifts and holds)."""
UNLOAD_MARGIN = 0.005
"""m: the lift-off's first leg rises this much more than half the pressed finger's bend."""
PULL_BACK_SLACK = 0.005
"""m: a pull-back drags the plate this much past the centroid margin it restores."""
APPROACH_RAISES = (0.15, 0.25, 0.35)
"""m above the pre-press pose: the approach goes via a pose raised by the first of these whose
route is free (when the direct move is not), before a planned route is tried."""
_FLIP_PALM = np.diag([-1.0, -1.0, 1.0])
"""A half turn about the grasp frame's approach axis: the side grasp with the palm the other
way up (:func:`~slide_gym.planning.pair.side_grasp_rotations`)."""


PHASES = (
    "plan",
    "approach",
    "press",
    "slide",
    "pull_back",
    "release",
    "lift_off",
    "transfer",
    "approach_grasp",
    "close",
    "lift",
    "done",
    "failed",
)
"""The values :attr:`SlideGraspExpert.phase` takes (see the module docstring)."""


@dataclass
class _Step:
    q: np.ndarray
    hand: float
    phase: str
    track: bool
    object_xy: np.ndarray | None = None  # where Eq. 2 puts the plate at this step


class SlideGraspExpert:
    """The planner as a closed-loop controller for one episode (see the module docstring).

    Args:
        planner: ``"regions"``, ``"cbirrt"`` or ``"cbirrt2"``.
        time_budget: total planning time (s) over the first plan and any replans.
        slide_params: planner parameters.
        params: execution parameters.
        seed: seeds the planner and the expert's own IK restarts (with the observed pose).
        library: known shapes for recognising the scene.
        control_dt: seconds per environment step; ``max_joint_step``: the env's action scale.
        ee: for ``control_mode="ee_delta"``, the pose-increment encoder (None: joint mode).
    """

    def __init__(
        self,
        planner: str,
        time_budget: float,
        slide_params: SlideParams,
        params: ExpertParams,
        seed: int,
        library: SceneLibrary,
        control_dt: float,
        max_joint_step: float,
        ee: EEActions | None = None,
    ):
        self.planner_name, self.time_budget = planner, float(time_budget)
        self.ee = ee
        self.slide_params, self.params, self.seed = slide_params, params, int(seed)
        self.library, self.dt, self.max_joint_step = library, control_dt, max_joint_step
        self.tip: FastChain = fingertip_chain()
        self.hand: FastChain = grasp_chain()
        self.queue: deque[_Step] = deque()
        self.phase = "plan"
        self.q_cmd: np.ndarray | None = None
        self.hand_cmd = 0.0
        self.tracker = ContactTracker(self.tip, params)
        self.planner: TopSlidePlanner | None = None
        self.obj: ObjectShape | None = None
        self.table: TableShape | None = None
        self.rng = np.random.default_rng(self.seed)
        self.centroid_margin = slide_params.centroid_margin  # set per plate by _slide_params
        self.grasp_u_star = params.grasp_u_star  # likewise
        self.small_plate = False  # likewise: unloading lift-off (is_small_plate)
        self._steps = 0  # actions returned so far
        self._taken_over = False  # the first observation's state has been read
        self._raise_if_no_approach = False  # taken over low beside the plate: see _take_over
        self.grasp_seed: np.ndarray | None = None  # the plan's grasp, an IK seed for re-aiming
        posture = params.grasp_posture  # re-aimed grasps: the IK solution nearest these
        self.grasp_postures = None if posture is None else mirrored_postures(np.array(posture))
        self.target: np.ndarray | None = None  # the last action's joint target
        self.object_start: np.ndarray | None = None  # the plate's pose the plan started from
        self._before: tuple[np.ndarray, np.ndarray | None] | None = None  # see follow
        self.retimed = False  # a learner acts: the plan follows its progress (see follow)
        self._plan_q: np.ndarray | None = None  # the plan's last target taken (no corrections)
        self.report = ExpertReport()

    # ------------------------------------------------------------------ act
    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """The next action ((8,), or (7,) in ee_delta mode) for observation ``obs``."""
        if self.q_cmd is None:
            self.q_cmd = np.asarray(obs["arm_qpos"], dtype=float).copy()
            if self.ee is not None:
                self.ee.reset(self.q_cmd)
            self.obj = self.library.object_from(obs["object_outline"])
            self.table = self.library.table_from(obs["table_outline"], obs["table_height"][0])
            self._slide_params()  # this plate's margins and grasp threshold
        ahead = self.retimed and self._skip_passed()
        if not ahead and self.ee is not None and self.ee.hold():  # the pose lags: wait
            assert self.ee.last is not None
            self._steps += 1
            return self._action(*self.ee.last)
        while not self.queue and self.phase not in ("done", "failed"):
            self._advance(obs)
        if not self.queue:
            self._steps += 1
            return self._action(self.q_cmd, self.hand_cmd)
        step = self.queue.popleft()
        if step.phase == "slide" and self._overhang_reached(obs):
            self._stop_slide(step)
        limit = 1.0
        if self.retimed and self._plan_q is not None:
            limit = min(1.0, max(RETIME_MIN_STEP, self._step_size(self._plan_q, step.q)))
        self._plan_q = step.q
        if step.phase != self.phase or not self.report.phase_steps:
            self.report.phase_steps.append((step.phase, self._steps))
        self.phase = step.phase
        self._steps += 1
        if step.track:
            target = step.q + self.tracker.joint_offset(step.q, step.object_xy, obs)
        else:  # untracked legs start from the command, corrections included
            self.tracker.reset()
            target = step.q
        return self._action(target, step.hand, limit)

    def _action(self, target: np.ndarray, hand: float, limit: float = 1.0) -> np.ndarray:
        assert self.q_cmd is not None
        self.target = np.asarray(target, dtype=float)
        self._before = (self.q_cmd.copy(), None if self.ee is None else self.ee.control.get_state())
        self.hand_cmd = hand
        if self.ee is not None:
            action = self.ee.action(target, hand, limit)
            self.q_cmd = self.ee.q_cmd
            return action
        target = np.clip(target, ARM_LOWER, ARM_UPPER)
        delta = (target - self.q_cmd) / self.max_joint_step
        if limit < 1.0:  # re-timed: shrunk as a whole to the plan's pace
            delta *= min(1.0, limit / max(float(np.abs(delta).max()), 1e-12))
        delta = np.clip(delta, -1.0, 1.0)
        self.q_cmd = np.clip(self.q_cmd + self.max_joint_step * delta, ARM_LOWER, ARM_UPPER)
        return np.r_[delta, 2.0 * hand - 1.0].astype(np.float32)

    def follow(self, action: np.ndarray, retime: bool = True) -> None:
        """The environment executed ``action`` instead of this expert's last one (a learner
        acted, or DART's noise): carry on from the command that ``action`` gives, as the
        environment's controller computed it. The plan and its queue stay; only the command
        moves, and the next action heads for the plan's next target from there.

        With ``retime`` (a learner acted), from then on the plan is re-timed to the
        learner's progress (:attr:`retimed`): no action moves faster than the plan does at
        that point (at least ``RETIME_MIN_STEP``), a lagging command holds the plan (in
        ``ee_delta`` mode), and targets the command has already passed are dropped. A label
        then shows the learner how to go on from where it is at the plan's pace, not how to
        catch up with the plan's clock at full speed."""
        self.retimed = self.retimed or retime
        if self._before is None:
            return
        q_before, ee_state = self._before
        a = np.clip(np.asarray(action, dtype=float).reshape(-1), -1.0, 1.0)
        self.hand_cmd = float((a[-1] + 1.0) / 2.0)
        if self.ee is not None:
            assert ee_state is not None
            self.ee.control.set_state(ee_state)
            self.ee.control.apply(a)
            self.q_cmd = self.ee.q_cmd
        else:
            step = self.max_joint_step * a[:-1]
            self.q_cmd = np.clip(q_before + step, ARM_LOWER, ARM_UPPER)

    def off_plan(self, obs: dict[str, np.ndarray], drift: float, plate_tol: float) -> bool:
        """Whether the state has left this expert's plan: during the approach, the plate moved
        more than ``plate_tol`` (m) from where the plan found it (the approach itself leads
        any arm back to the plan's press); from the press on, the commanded fingertip is more
        than ``drift`` (m) from where the plan has it now."""
        if self.q_cmd is None or self.target is None or self.phase in ("done", "failed"):
            return False
        if self.phase in ("plan", "approach"):
            if self.object_start is None:
                return False
            moved = self._object_pose(obs)[:2] - np.asarray(self.object_start)[:2]
            return bool(np.linalg.norm(moved) > plate_tol)
        tips = self.tip.forward(np.stack([self.q_cmd, self.target]))[:, :3, 3]
        return bool(np.linalg.norm(tips[0] - tips[1]) > drift)

    def _overhang_reached(self, obs: dict[str, np.ndarray]) -> bool:
        """Whether ``ExpertParams.stop_overhang`` is set and the plate's measured overhang
        has reached it, its centroid still on the table."""
        stop = self.params.stop_overhang
        if stop is None or self.obj is None or self.table is None:
            return False
        ov = self._overhang_at(self._object_pose(obs))
        return bool(ov.u >= stop and ov.centroid_inside)

    def _stop_slide(self, step: _Step) -> None:
        """End the slide at ``step``: the rest of it is dropped and the fingertip holds there,
        still pressed, for ``slide_settle_s`` (as at a plan's end); what follows a slide
        follows."""
        left = sum(1 for s in self.queue if s.phase == "slide")
        hold = max(1, round(self.params.slide_settle_s / self.dt))
        if left <= hold:  # already settling at the plan's end
            return
        for _ in range(left):
            self.queue.popleft()
        for _ in range(hold):
            self.queue.appendleft(dataclasses.replace(step))
        self.q_slide_end = np.asarray(step.q, dtype=float)
        self.report.events.append(
            f"slide stopped at the overhang {self.params.stop_overhang:.3f} m, "
            f"{left - hold} steps early"
        )

    def _step_size(self, q_from: np.ndarray, q_to: np.ndarray) -> float:
        """The plan's speed between two consecutive targets, in action units."""
        if self.ee is not None:
            return self.ee.step_size(q_from, q_to)
        return float(np.abs(q_to - q_from).max() / self.max_joint_step)

    def _skip_passed(self) -> bool:
        """Drop the queued targets of the current leg that the commanded fingertip has passed
        (it is nearer to a later one than to the current target); True if any were."""
        if self.q_cmd is None or self.target is None or not self.queue:
            return False
        leg = []
        for step in itertools.islice(self.queue, RETIME_WINDOW):
            if step.phase != self.phase:
                break
            leg.append(step.q)
        if not leg:
            return False
        tips = self.tip.forward(np.stack([self.q_cmd, self.target, *leg]))[:, :3, 3]
        nearest = int(np.argmin(np.linalg.norm(tips[1:] - tips[0], axis=1)))
        for _ in range(nearest):  # 0: the current target is the nearest
            self._plan_q = self.queue.popleft().q
        return nearest > 0

    # --------------------------------------------------------------- stages
    def _advance(self, obs: dict[str, np.ndarray]) -> None:
        """Queue the next stage's targets (called when the queue runs dry)."""
        if self.phase == "plan":
            if not self._taken_over:
                self._taken_over = True
                if self._take_over(obs):
                    return None
            self._plan(obs)
        elif self.phase == "release":  # read the state again, the fingertip now up
            self.phase, self._taken_over = "plan", False
        elif self.phase == "slide":
            self._pull_back_or_lift_off(obs)
        elif self.phase == "pull_back":
            self._lift_off(obs)
        elif self.phase == "lift_off":
            self._after_lift_off(obs)
        elif self.phase == "lift":
            self.phase = "done"
        else:
            self._fail(f"nothing follows phase {self.phase!r}")

    def _fail(self, why: str) -> None:
        self.report.gave_up = why
        self.phase = "failed"
        self.queue.clear()
        if self.planner is not None:
            self.planner.close()
            self.planner = None

    def _object_pose(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        pose = obs["object_pose"]
        return np.array([float(pose[0]), float(pose[1]), quat_yaw(pose[3:7])])

    def _overhang_at(self, pose: np.ndarray) -> Overhang:
        """The plate's overhang over the table at ``pose`` (x, y, yaw)."""
        assert self.obj is not None and self.table is not None
        return overhang(transform_polygon(self.obj.polygon, *pose), self.table.polygon)

    def _slide_params(self) -> list[tuple[str, SlideParams]]:
        """The planner settings to try in turn: the margins this plate leaves room for, then
        relaxed ones."""
        assert self.obj is not None
        strict = plate_slide_params(self.slide_params, self.params, self.obj.circumradius)
        strict = thin_plate_slide_params(strict, self.obj.thickness)
        if self.params.nearest_goal_edge:
            strict = dataclasses.replace(strict, goal_edge="nearest")
        self.centroid_margin = strict.centroid_margin
        self.small_plate = is_small_plate(self.slide_params, self.params, self.obj.circumradius)
        self.grasp_u_star = plate_grasp_u_star(self.params, strict, self.small_plate)
        return [
            ("strict", strict),
            ("relaxed", relaxed_slide_params(strict)),
            ("turning", turning_slide_params(strict, self.grasp_u_star)),
        ]

    def _budget_left(self) -> float:
        """Planning seconds left in the episode's budget (a give-up deadline, nothing more)."""
        return self.time_budget - (self.report.planning_time_s or 0.0)

    def _take_over(self, obs: dict[str, np.ndarray]) -> bool:
        """Read the first observation's state (see the module docstring); True if it queued
        (or decided) what comes first, False if planning as at the start is right."""
        assert self.obj is not None and self.table is not None and self.q_cmd is not None
        p = self.params
        plate_z = float(obs["object_pose"][2]) - float(obs["table_height"][0])
        if plate_z > HELD_HEIGHT and float(obs["hand_command"][0]) > 0.5:
            self.report.events.append(f"took over with the plate in the hand ({plate_z:.3f} m up)")
            lift_path = rise(
                self.hand, self.q_cmd, (p.lift, 0.75 * p.lift, 0.5 * p.lift), True, self.rng
            )
            if lift_path is None:
                self._fail("no IK solution for lifting the grasped object")
                return True
            self._push(
                Segment("lift", lift_path, 1.0, p.lift_speed, hand=1.0, hold_s=1.0), self.hand
            )
            return True
        pose = self._object_pose(obs)
        placed = transform_polygon(self.obj.polygon, *pose)
        tip = np.asarray(obs["fingertip_pose"][:3], dtype=float)
        graspable = overhang(placed, self.table.polygon).graspable(self.grasp_u_star)
        if tip[2] - float(obs["table_height"][0]) < LOW_TIP_HEIGHT:
            on_plate = placed.buffer(ON_PLATE_MARGIN).contains(shapely.Point(tip[0], tip[1]))
            where = "on the plate" if on_plate else "low over the table"
            if not on_plate and not graspable:  # _plan raises it only if no approach is found
                self.report.events.append(f"took over with the fingertip {where}: planning")
                self._raise_if_no_approach = True
                return False
            if on_plate:
                n = len(self.report.events)
                if graspable:
                    why, done = lift_off_pressed(self, obs), "lifted it off"
                else:
                    why, done = self._slide_on(obs)
                if why is None:
                    self.report.events.insert(n, f"took over with the fingertip {where}: {done}")
                    return True
                what = "lift off" if graspable else "slide on"
                self.report.events.append(f"no {what} from here ({why})")
            self._raise_fingertip(f"took over with the fingertip {where}: raised it")
            return True
        if graspable:
            self.report.events.append("took over with the plate graspable: grasping it")
            return self._grasp_as_it_lies(pose)
        return False

    def _raise_fingertip(self, event: str) -> None:
        """Queue the fingertip straight up by ``lift_off_height`` (``release``); the state is
        read again from there."""
        h = self.params.lift_off_height
        line = rise(self.tip, self.q_cmd, (h, h / 2, h / 4), True, self.rng)
        if line is None:
            return self._fail("no IK solution to raise the fingertip")
        self.report.events.append(event)
        self._push(Segment("release", line, 1.0, self.params.lift_off_speed), self.tip)

    def _slide_on(self, obs: dict[str, np.ndarray]) -> tuple[str | None, str]:
        """Queue a slide on from the pressed fingertip, planned or straight, in the order
        ``ExpertParams.straight_slide_on`` says; ``(None, what it did)`` if one was queued
        (the other's failure, if tried first, noted), else ``(why neither, "")``."""
        tries = [
            ("planned", "slid on", slide_on),
            ("straight", "slid straight on", slide_straight_on),
        ]
        if self.params.straight_slide_on:
            tries.reverse()
        failed: list[str] = []
        for kind, done, queue in tries:
            why = queue(self, obs)
            if why is None:
                self.report.events.extend(f"no {f}" for f in failed)
                return None, done
            failed.append(f"{kind} slide on ({why})")
        return "; ".join(failed), ""

    def _grasp_as_it_lies(self, pose: np.ndarray) -> bool:
        """Re-aim a grasp at a graspable plate that nothing planned; False (plan instead) if
        no grasp is found."""
        assert self.obj is not None and self.table is not None and self.q_cmd is not None
        try:
            problem = TopSlideProblem(
                self.obj, self.table, pose, self._slide_params()[0][1], allow_overhang=True
            )
        except ValueError as exc:
            self.report.events.append(f"no grasp from here ({exc}): planning a slide")
            return False
        rng = np.random.default_rng(np.random.SeedSequence([self.seed, 7]))
        self.planner = TopSlidePlanner(problem, self.planner_name, rng)
        ok, info = self._reaim(pose, max(self._budget_left(), 1e-3))
        if not ok:
            self.report.events.append(f"no grasp from here ({info.get('reason')}): planning")
            return False
        self._queue_grasp(np.asarray(info["transfer_path"]), pose)
        return True

    def _plan(self, obs: dict[str, np.ndarray]) -> None:
        assert self.obj is not None and self.table is not None and self.q_cmd is not None
        pose = self._object_pose(obs)
        replan = self.report.replans > 0 or self._overhang_at(pose).u > 0
        attempts = self._slide_params()
        k = 0
        while k < len(attempts):
            name, params = attempts[k]
            budget = self._budget_left()
            if budget <= 0.05:
                return self._fail("planning budget used up")
            if name.startswith("strict"):  # capped by iterations, not by a share of the time
                params = dataclasses.replace(
                    params, max_iterations=self.params.strict_plan_iterations
                )
            try:
                problem = TopSlideProblem(self.obj, self.table, pose, params, allow_overhang=replan)
            except ValueError as exc:
                return self._fail(f"cannot plan from the object's pose: {exc}")
            if self.planner is not None:
                self.planner.close()
            key = [self.seed, self.report.replans, k]
            key += list(np.round(pose * 1e4).astype(np.int64) % 2**32)
            rng = np.random.default_rng(np.random.SeedSequence(key))
            self.planner = TopSlidePlanner(problem, self.planner_name, rng)
            t0 = time.perf_counter()
            result = self.planner.solve(budget)
            self.report.planning_time_s += time.perf_counter() - t0
            self.report.plan_status = result.status.value
            if result.solved:
                break
            self.report.events.append(f"{name} plan: {result.status.value}: {result.reason}")
            if result.status is PlanStatus.TIMEOUT:
                return self._fail(f"planning budget used up ({name} plan: {result.reason})")
            if result.status is PlanStatus.INFEASIBLE and params.goal_edge == "nearest":
                attempts[k + 1 :] = [  # this attempt again, and the rest, toward any edge
                    (f"{n} (any edge)", dataclasses.replace(p, goal_edge="any"))
                    for n, p in attempts[k:]
                ]
            k += 1
        else:
            if result.status is PlanStatus.INFEASIBLE:
                return self._fail(f"plan infeasible: {result.reason}")
            return self._fail(f"no plan, {result.status.value}: {result.reason}")
        self.use_plan(self.planner, result, pose)
        why = self._queue_press_and_slide(result.start_config, result.path, pose)
        raise_first, self._raise_if_no_approach = self._raise_if_no_approach, False
        if why is None:
            return None
        if raise_first:  # from a fingertip low beside the plate: rise, then read it again
            return self._raise_fingertip(f"{why}: raised the fingertip")
        if self.report.replans >= self.params.max_replans:
            return self._fail(why)
        self.report.events.append(f"{why}: planning again")  # nothing has moved yet
        self.report.replans += 1
        return self._plan(obs)

    def use_plan(self, planner: TopSlidePlanner, result: PlanResult, pose: np.ndarray) -> None:
        """Adopt a solved plan from the plate at ``pose``: its planner, Eq. 2's prediction."""
        if self.planner is not None and self.planner is not planner:
            self.planner.close()
        self.planner, self.result, self.object_start = planner, result, pose
        self.report.planned = True
        self.report.plan_status = result.status.value
        gamma_s, gamma_g = planar_pose(
            self.tip.forward(np.stack([result.start_config, result.goal_config]))
        )
        self.predicted = slid_object_pose(gamma_s, gamma_g, pose)
        self.report.object_predicted_pose = self.predicted.tolist()
        grasp = result.extra.get("grasp_config")
        self.grasp_seed = None if grasp is None else np.asarray(grasp, dtype=float)

    def _ik(self, chain: FastChain, t: np.ndarray, seed: np.ndarray) -> np.ndarray | None:
        return solve_ik(chain, IKTarget(t[:3, 3], t[:3, :3]), self.rng, seed[None])

    def _queue_press_and_slide(
        self, q_s: np.ndarray, path: np.ndarray, pose: np.ndarray
    ) -> str | None:
        """Queue approach, press and slide for a plan; else why not (nothing queued)."""
        p, planner = self.params, self.planner
        assert planner is not None and self.q_cmd is not None
        down = rise(self.tip, q_s, (p.pre_contact_height,), True, self.rng)
        if down is None:
            return "no IK solution above the press point"
        down = down[::-1]  # from above the press point straight down to it
        q_pre = down[0]
        high = self.tip.forward(q_pre)
        high[2, 3] += APPROACH_RAISES[0]
        q_high = self._ik(self.tip, high, q_pre)
        q_up = self._up_to(q_pre)
        routes = [[self.q_cmd, q_pre]] + [
            [self.q_cmd, q, q_pre] for q in (q_up, q_high) if q is not None
        ]
        route = next((r for r in routes if planner.route_free(r, pose)), None)
        if route is None:
            route, why = self._other_approach(q_pre, pose)
            if route is None:
                return f"no collision-free approach to the press point: {why}"
        if not planner.route_free(down, None, mode="sliding"):
            return "the press move down to the plate would collide"
        approach = Segment("approach", np.array(route), p.approach_speed, ramp_s=p.ramp_s)
        self._push(approach, self.tip)
        press = Segment("press", down, 1.0, p.press_speed, hold_s=p.press_hold_s)
        self._push(press, self.tip, track=True)
        self.queue_slide(q_s, path, pose)
        return None

    def _up_to(self, q_pre: np.ndarray) -> np.ndarray | None:
        """The arm with the fingertip straight above where it is, at the height of ``q_pre``'s
        fingertip; None where it already is that high (as at an episode's start) or no IK
        solution. A fingertip taken over low beside the plate rises this far before it moves
        across, instead of moving diagonally through the plate's edge."""
        assert self.q_cmd is not None
        here, there = self.tip.forward(np.stack([self.q_cmd, q_pre]))
        if here[2, 3] >= there[2, 3] - 1e-3:
            return None
        here[2, 3] = there[2, 3]
        return self._ik(self.tip, here, self.q_cmd)

    def queue_slide(self, q_s: np.ndarray, path: np.ndarray, pose: np.ndarray) -> None:
        """Queue the planned slide ``path`` (tracked, each step with the plate's Eq. 2 xy for
        the plate at ``pose`` pressed at ``q_s``)."""
        p = self.params
        first = len(self.queue)
        slide = Segment("slide", path, 1.0, p.slide_speed, hold_s=p.slide_settle_s, ramp_s=p.ramp_s)
        self._push(slide, self.tip, track=True)
        targets = [step.q for step in list(self.queue)[first:]]
        gammas = planar_pose(self.tip.forward(np.stack([q_s, *targets])))
        for step, gamma in zip(list(self.queue)[first:], gammas[1:], strict=True):
            step.object_xy = slid_object_pose(gammas[0], gamma, pose)[:2]
        self.q_slide_end = np.asarray(path[-1], dtype=float)

    def _other_approach(
        self, q_pre: np.ndarray, pose: np.ndarray
    ) -> tuple[list[np.ndarray] | np.ndarray | None, str]:
        """An approach to ``q_pre`` when neither the direct move nor the one via the pose
        15 cm above it is free: via poses raised higher, via the ready pose (for an arm the
        expert took over somewhere else), else a joint route planned with at most
        ``route_iterations`` search iterations. ``(route, "")`` or ``(None, why)``."""
        planner = self.planner
        assert planner is not None and self.q_cmd is not None
        for lift in APPROACH_RAISES[1:]:
            high = self.tip.forward(q_pre)
            high[2, 3] += lift
            q_high = self._ik(self.tip, high, q_pre)
            if q_high is not None and planner.route_free([self.q_cmd, q_high, q_pre], pose):
                self.report.events.append(f"approach via a pose raised {lift:.2f} m")
                return [self.q_cmd, q_high, q_pre], ""
        ready = np.asarray(READY_ARM_Q, dtype=float)  # an arm taken over far from any plan
        if planner.route_free([self.q_cmd, ready, q_pre], pose):
            self.report.events.append("approach via the ready pose")
            return [self.q_cmd, ready, q_pre], ""
        budget = self._budget_left()
        if budget <= 0.0:
            return None, "direct and raised moves collide and the planning budget is used up"
        t0 = time.perf_counter()
        route, why = planner.plan_route(
            self.q_cmd, q_pre, pose, self.params.route_iterations, budget
        )
        self.report.planning_time_s += time.perf_counter() - t0
        if route is None:
            return None, f"direct and raised moves collide; route planner: {why}"
        self.report.events.append(f"approach along a planned route ({len(route)} waypoints)")
        return route, ""

    def _push(self, segment: Segment, chain: FastChain | None, track: bool = False) -> None:
        for q in time_segment(segment, self.dt, chain):
            self.queue.append(_Step(q, segment.hand, segment.name, track))

    def _pull_back_or_lift_off(self, obs: dict[str, np.ndarray]) -> None:
        """If the slide left the plate's centroid at (or past) the table edge, drag it back
        inward while still pressing; a plate lifted off there would tip over the edge.

        The drag goes :data:`PULL_BACK_SLACK` past the margin it restores, but no further
        than keeps the overhang at the grasp threshold (:attr:`grasp_u_star`) plus a
        millimetre: with the whole slack, half-scale circles pulled back from 3-5 mm inside
        the edge landed at 1.5-1.7 cm of overhang, under their 1.75 cm threshold."""
        assert self.table is not None and self.obj is not None
        pose = self._object_pose(obs)
        centroid = shapely.Point(pose[0], pose[1])
        ring = self.table.polygon.exterior
        edge_point = np.asarray(ring.interpolate(ring.project(centroid)).coords[0])
        inside = self.table.polygon.contains(centroid)
        depth = centroid.distance(ring) * (1.0 if inside else -1.0)
        keep = min(self.params.pull_back_margin, self.centroid_margin)
        if depth >= keep:
            return self._lift_off(obs)
        inward = (pose[:2] - edge_point) * (1.0 if inside else -1.0)
        inward /= max(float(np.linalg.norm(inward)), 1e-9)
        u = self._overhang_at(pose).u
        room = u - (keep - depth) - self.grasp_u_star - 0.001
        slack = min(PULL_BACK_SLACK, max(0.0, room))
        shift = np.r_[inward * (keep - depth + slack), 0.0]
        line = cartesian_line(self.tip, self.q_slide_end, shift, self.rng)
        assert self.planner is not None
        if line is None or not self.planner.route_free(line, None, mode="sliding"):
            return self._lift_off(obs)
        self.report.events.append(f"centroid {depth:.3f} m inside the edge: pulled back")
        self._push(Segment("pull_back", line, 1.0, self.params.press_speed), self.tip, track=True)
        self.q_slide_end = line[-1]

    def _lift_off(self, obs: dict[str, np.ndarray]) -> None:
        """Raise the fingertip off the plate, untracked.

        The pressed finger is bent: the arm's rigid-finger fingertip (the command, the
        tracker's corrections included) lies centimetres from the real one, below the plate
        top. Rising straight up, the finger springs back and its tip swings onto the
        command's xy, dragging a light plate with it (by as much as a small plate's centroid
        margin). So for a small plate (:func:`~agents.params.is_small_plate`) the first leg
        moves the command's fingertip onto the measured one while rising by half the bend
        (:meth:`_unload_line`), the rest is straight up. Larger plates, which the drag did
        not tip (their margins were tuned with it), rise straight up from the slide's end.
        """
        assert self.q_cmd is not None and self.planner is not None
        h = self.params.lift_off_height  # near a joint limit, less still unloads the finger
        q_from = np.asarray(self.q_cmd, dtype=float)
        line = self._unload_line(q_from, obs) if self.small_plate else None
        if line is not None:
            left = h - float(self.tip.forward(line[-1])[2, 3] - self.tip.forward(q_from)[2, 3])
            up = rise(self.tip, line[-1], (left, left / 2, left / 4), False, self.rng)
            line = None if up is None else np.vstack([line, up[1:]])
        if line is None:  # no unload leg: straight up from the slide's nominal end
            line = rise(self.tip, self.q_slide_end, (h, h / 2, h / 4), False, self.rng)
            if line is None:
                return self._fail("no IK solution to lift the fingertip off the plate")
            if not self.planner.route_free(line, None, mode="sliding"):
                return self._fail("the lift-off move would collide")
            seg = Segment("lift_off", line, 1.0, self.params.lift_off_speed)
            return self._push(seg, self.tip, track=True)
        if not self.planner.route_free(line, None, mode="sliding"):
            return self._fail("the lift-off move would collide")
        self._push(Segment("lift_off", line, 1.0, self.params.lift_off_speed), self.tip)

    def _unload_line(self, q_from: np.ndarray, obs: dict[str, np.ndarray]) -> np.ndarray | None:
        """Waypoints from ``q_from`` that bring the command's fingertip over the measured one
        while rising by half the finger's bend plus :data:`UNLOAD_MARGIN` (the finger
        unloads early in the rise: a leg rising by the whole bend still dragged a plate 5 mm);
        None if the finger is not bent the usual way or the move leaves the reachable set."""
        cmd = self.tip.forward(q_from)[:3, 3]
        real = np.asarray(obs["fingertip_pose"][:3], dtype=float)
        bend = real - cmd
        limit = self.params.max_correction + self.params.max_object_correction
        if bend[2] <= 0.0 or np.linalg.norm(bend[:2]) > limit:
            return None
        offset = np.r_[bend[:2], min(0.5 * bend[2] + UNLOAD_MARGIN, self.params.lift_off_height)]
        return cartesian_line(self.tip, q_from, offset, self.rng)

    def _after_lift_off(self, obs: dict[str, np.ndarray]) -> None:
        """Compare the real slid pose with Eq. 2; re-aim the grasp at it, or replan."""
        assert self.planner is not None and self.q_cmd is not None
        assert self.obj is not None and self.table is not None
        actual = self._object_pose(obs)
        self.report.object_slid_pose = actual.tolist()
        self.report.slide_error_m = float(np.linalg.norm(actual[:2] - self.predicted[:2]))
        self.report.slide_error_rad = abs(wrap_angle(actual[2] - self.predicted[2]))
        ov = self._overhang_at(actual)
        ok, info = False, {"reason": "overhang below u_star or centroid off the table"}
        if ov.graspable(self.grasp_u_star):
            budget = self._budget_left()
            if budget <= 0.0:
                return self._fail("planning budget used up before re-aiming the grasp")
            ok, info = self._reaim(actual, budget, self.grasp_seed)
            if info.get("timeout"):
                return self._fail("planning budget used up while re-aiming the grasp")
        what = "slid" if self.report.planned else "lifted off"  # no plan: it lay there
        self.report.events.append(
            f"{what}: overhang {ov.u:.3f} m, error {self.report.slide_error_m:.3f} m "
            f"{self.report.slide_error_rad:.3f} rad, grasp {'ok' if ok else info.get('reason')}"
        )
        if ok:
            return self._queue_grasp(np.asarray(info["transfer_path"]), actual)
        if self.report.replans >= self.params.max_replans:
            return self._fail(f"not graspable after the slide ({info.get('reason')})")
        self.report.replans += 1
        self._plan(obs)

    def _reaim(
        self, pose: np.ndarray, budget: float, grasp_seed: np.ndarray | None = None
    ) -> tuple[bool, dict]:
        """:meth:`TopSlidePlanner.reaim_grasp` at the plate's ``pose`` from the commanded arm,
        its time counted as planning."""
        assert self.planner is not None and self.q_cmd is not None
        t0 = time.perf_counter()
        ok, info = self.planner.reaim_grasp(
            pose,
            self.q_cmd,
            self.grasp_u_star,
            max_iterations=self.params.grasp_iterations,
            time_budget=budget,
            grasp_seed=grasp_seed,
            postures=self.grasp_postures,
        )
        self.report.planning_time_s += time.perf_counter() - t0
        return ok, info

    def _approach_leg(self, transfer: np.ndarray) -> np.ndarray:
        """``transfer`` with a waypoint added on its last leg where the hand is one stand-off
        (``grasp.retreat``) from the grasp, if that leg is longer than two stand-offs (a
        transfer without a reachable pre-grasp). Only the leg after it runs at the slow
        grasp speed; the whole leg did, taking up to 20 s for half a metre."""
        standoff = self.slide_params.grasp.retreat
        line = transfer[-2] + np.linspace(0.0, 1.0, 41)[:, None] * (transfer[-1] - transfer[-2])
        hand = self.hand.forward(line)[:, :3, 3]
        far = np.linalg.norm(hand - hand[-1], axis=1) >= standoff
        if np.linalg.norm(hand[0] - hand[-1]) <= 2.0 * standoff:
            return transfer
        return np.vstack([transfer[:-1], line[np.flatnonzero(far)[-1]], transfer[-1]])

    def _straight_transfer(self, transfer: np.ndarray, pose: np.ndarray) -> np.ndarray | None:
        """A transfer to the pre-grasp and grasp positions of ``transfer``'s last two
        configurations that moves the hand along straight lines, turning at a constant rate:
        diagonally to above the pre-grasp, or first up to the planner's clear height and then
        across, and down to it; the palm as planned or turned over (the pinch is symmetric).
        The first of these that stays on the arm's IK branch (each configuration follows from
        the one before) and is collision-free with the plate at ``pose``; None if none is."""
        assert self.q_cmd is not None and self.planner is not None and self.table is not None
        g = self.slide_params.grasp
        here, pre, grasp = self.hand.forward(np.stack([self.q_cmd, transfer[-2], transfer[-1]]))
        high = pre[:3, 3] + [0.0, 0.0, g.rise]
        clear_z = self.table.height + g.clear_height
        for rot in (pre[:3, :3], pre[:3, :3] @ _FLIP_PALM):  # either way up pinches
            across = [(high, rot)]
            over = [(np.r_[here[:2, 3], clear_z], here[:3, :3]), (np.r_[high[:2], clear_z], rot)]
            for legs in (across, over + across) if here[2, 3] < clear_z else (across,):
                walk = cartesian_walk(
                    self.hand, self.q_cmd, [*legs, (pre[:3, 3], rot)], self.rng, transfer[-2]
                )
                if walk is None:
                    continue
                approach = cartesian_walk(self.hand, walk[-1], [(grasp[:3, 3], rot)], self.rng)
                if approach is None:
                    continue
                route = np.vstack([walk, approach[-1:]])
                if self.planner.route_free(route, pose):
                    return route
        return None

    def _queue_grasp(self, transfer: np.ndarray, pose: np.ndarray) -> None:
        p = self.params
        assert self.q_cmd is not None
        transfer = self._approach_leg(transfer)
        if p.straight_transfer:
            straight = self._straight_transfer(transfer, pose)
            if straight is not None:
                transfer = straight
                self.report.events.append("straight transfer to the grasp")
        q_grasp = transfer[-1]
        heights = (p.lift, 0.75 * p.lift, 0.5 * p.lift)  # lower near the edge of the workspace
        lift_path = rise(self.hand, q_grasp, heights, True, self.rng)
        if lift_path is None:
            return self._fail("no IK solution for lifting the grasped object")
        assert self.planner is not None
        if not self.planner.route_free(lift_path, None):
            return self._fail("lifting the grasped object would collide")
        route = np.vstack([self.q_cmd, transfer[1:-1]])
        transfer_leg = Segment(
            "transfer",
            route,
            p.transfer_speed,
            p.transfer_tip_speed,
            hold_s=p.settle_s,
            ramp_s=p.ramp_s,
        )
        self._push(transfer_leg, self.hand)
        self._push(Segment("approach_grasp", transfer[-2:], 1.0, p.grasp_speed), self.hand)
        self._push(Segment("close", transfer[-1:], hand=1.0, hold_s=p.close_s), None)
        lift = Segment("lift", lift_path, 1.0, p.lift_speed, hand=1.0, hold_s=1.0, ramp_s=p.ramp_s)
        self._push(lift, self.hand)
        if self.planner is not None:
            self.planner.close()
            self.planner = None

    def close(self) -> None:
        """Release the planner's collision world."""
        if self.planner is not None:
            self.planner.close()
            self.planner = None
