"""DAgger's label expert: one planner expert per learner episode that keeps its plan.

The expert plans once from the episode's first state. At every step it gives the action it
would take from the command the environment holds (the label), then follows the action that
was actually executed (:meth:`agents.expert.SlideGraspExpert.follow`), so its next label
starts from the true command and still heads for the same plan, re-timed to the learner's
progress: a label never moves faster than the plan does at that point, so a learner that lags
is told to go on at the plan's pace rather than to catch up with its clock (which, before
re-timing, made 36 % of the labels full-speed steps against 8 % of the demonstrations'
actions). At a chunk boundary a fresh
expert takes over from the current state (:mod:`agents.takeover`; seeded from the episode
seed and the step) when the learner has left the plan (the plate moved during the approach,
or from the press on the commanded fingertip is more than ``drift`` from the plan's) or the
expert has failed. Labels of a failed expert are NaN until the next boundary.

A fresh expert every chunk (the first design) planned a new press point each time and
ramped up from rest, so the labels before contact pointed somewhere new every chunk and,
followed alone, hovered over the plate without pressing.

:meth:`PlanLabeler.chunk` labels a whole chunk at once: what the expert would do over the next
steps from the learner's state if it acted itself. A copy of the expert runs them in a second
env of the episode's scene put in the learner's state. Per-step labels along the learner's own
motion are not such a chunk: the learner did not follow them, so a correction the expert would
make once is repeated at every step after it.
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np

from agents.planner_agent import PlannerAgent
from slide_gym.datasets.config import CollectConfig
from slide_gym.geometry import ObjectShape, TableShape

DRIFT_M = 0.03
"""m: a commanded fingertip this far from the plan's has left it."""
PLATE_TOL_M = 0.005
"""m: a plate moved this far during the approach has left the plan."""


class _Lent:
    """An expert's planner lent to a copy of the expert: usable, but the copy cannot close it
    (the original goes on planning with it)."""

    def __init__(self, planner: Any):
        self._planner = planner

    def __getattr__(self, name: str) -> Any:
        return getattr(self._planner, name)

    def close(self) -> None:
        pass


def label_seed(episode_seed: int, step: int) -> int:
    """The seed of the expert that takes over at ``step`` of the episode."""
    return int(np.random.SeedSequence([int(episode_seed), int(step)]).generate_state(1)[0])


class PlanLabeler:
    """Labels one learner episode (see the module docstring).

    Args:
        config: the dataset's collection settings (planner, control mode).
        seed: the episode's reset seed.
        budget: planning seconds per expert (a takeover gets a fresh budget).
        obj, table: the episode's shapes (the expert recognises the scene by them).
        retime: re-time the plan to the learner's progress (False: keep the plan's clock, as
            before re-timing; for comparisons).
        skip_phases: expert phases whose labels are withheld (:meth:`label` still gives them,
            :attr:`withheld` says so): e.g. ``("release",)``, where the expert raises a
            fingertip the learner put somewhere the plan cannot continue from.
    """

    def __init__(
        self,
        config: CollectConfig,
        seed: int,
        budget: float,
        obj: ObjectShape,
        table: TableShape,
        *,
        drift: float = DRIFT_M,
        plate_tol: float = PLATE_TOL_M,
        retime: bool = True,
        skip_phases: tuple[str, ...] = (),
    ):
        self.config, self.seed, self.budget = config, int(seed), float(budget)
        self.shapes = ([obj], [table])
        self.drift, self.plate_tol = float(drift), float(plate_tol)
        self.retime = retime
        self.skip_phases = frozenset(skip_phases)
        self.withheld = False
        """Whether the last label came from a phase in ``skip_phases``."""
        self.agent: PlannerAgent | None = None
        self.queries = self.failures = 0
        self.reasons: dict[str, int] = {}

    def label(self, obs: dict[str, np.ndarray], step: int, boundary: bool) -> np.ndarray | None:
        """The expert's action for ``obs`` (None while its expert has failed); at a chunk
        ``boundary`` a fresh expert takes over if the learner has left the plan."""
        slot = None if self.agent is None else self.agent.expert(0)
        stale = slot is None or slot.phase == "failed"
        fresh = boundary and (
            stale or (slot is not None and slot.off_plan(obs, self.drift, self.plate_tol))
        )
        if fresh:
            self.close()
            self.agent = PlannerAgent(
                self.config.agent,
                self.budget,
                seed=label_seed(self.seed, step),
                objects=self.shapes[0],
                tables=self.shapes[1],
                control_mode=self.config.control_mode,
                **self.config.agent_kwargs(),
            )
            self.queries += 1
        elif stale:
            self.withheld = False
            return None
        assert self.agent is not None
        action, _ = self.agent.predict(obs, episode_start=np.array([fresh]))
        slot = self.agent.expert(0)
        assert slot is not None
        self.withheld = slot.phase in self.skip_phases
        if slot.phase == "failed":
            self.failures += 1
            why = str(slot.report.gave_up).split(":")[0]
            self.reasons[why] = self.reasons.get(why, 0) + 1
            return None
        return np.asarray(action)

    def chunk(
        self, first: np.ndarray, branch: Any, state: np.ndarray, length: int
    ) -> np.ndarray | None:
        """(length, A): ``first`` (the label :meth:`label` just gave) and the actions a copy of
        the expert takes after it when it acts itself (at the plan's own pace, not re-timed),
        from ``state`` (the learner's, from ``get_state()``) in ``branch`` (an unwrapped env
        of the episode's scene, reset with the episode's seed and options). Once the branch's
        episode ends the arm holds still, as a training window pads an episode's end. None if
        the expert has failed or fails on the way. The expert itself, and the learner's env,
        are left as they were."""
        slot = None if self.agent is None else self.agent.expert(0)
        if slot is None or slot.phase == "failed":
            return None
        shared: dict[int, Any] = {id(slot.library): slot.library}
        if slot.planner is not None:
            shared[id(slot.planner)] = _Lent(slot.planner)
        twin = copy.deepcopy(slot, memo=shared)
        try:
            twin.follow(first)
            # from here the expert acts itself: the plan at its own pace, not re-timed to a
            # learner (re-timed, it holds or crawls wherever its command lags a target)
            twin.retimed = False
            branch.set_state(state)
            actions = [np.asarray(first, np.float32)]
            obs, _, ended, _, _ = branch.step(first)
            while len(actions) < length:
                if ended:
                    hold = np.zeros_like(actions[0])
                    hold[-1] = actions[-1][-1]
                    actions.append(hold)
                    continue
                action = twin.act(obs)
                if twin.phase == "failed":
                    return None
                actions.append(np.asarray(action, np.float32))
                obs, _, ended, _, _ = branch.step(action)
        finally:
            twin.close()  # a planner of its own, if it planned anew; the lent one stays open
        return np.stack(actions)

    def executed(self, action: np.ndarray) -> None:
        """The environment executed ``action``: the expert carries on from its command."""
        slot = None if self.agent is None else self.agent.expert(0)
        if slot is not None and slot.phase != "failed":
            slot.follow(action)
            slot.retimed = self.retime

    def close(self) -> None:
        if self.agent is not None:
            self.agent.close()
            self.agent = None
