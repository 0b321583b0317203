"""The planners as policies with Stable-Baselines3's ``predict`` interface."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from typing import Any

import numpy as np

from agents.batch import as_batch
from agents.ee_actions import EEActions
from agents.expert import SlideGraspExpert
from agents.params import EXPERT_SLIDE_PARAMS, ExpertParams
from agents.scene import SceneLibrary
from slide_gym.envs.control import make_control
from slide_gym.geometry import ObjectShape, TableShape
from slide_gym.planning.api import PLANNERS, SlideParams
from slide_gym.planning.result import check_time_budget

_RESET_JUMP = 0.3
"""rad: an arm this far from the agent's own target must have been reset by the env."""


class PlannerAgent:
    """A top-slide planner as a closed-loop policy for ``SlideGym/TopSlideGrasp-v0``.

    ``predict`` takes one observation or a batch (a dict of stacked arrays, as from a VecEnv)
    and returns actions in the environment's action space. The agent plans from what the
    observation says (the scene outlines, the object's pose), then presses, slides, re-aims the
    grasp at the plate's measured pose (replanning if it is not graspable), grasps and lifts;
    see :class:`agents.expert.SlideGraspExpert`. It never touches the simulator.

    Each batch slot keeps its own episode controller. A slot starts a new episode when
    ``episode_start`` says so (as ``evaluate_policy`` and SB3 loops pass it), when
    :meth:`reset` is called, or, when ``episode_start`` is not given at all, when the observed
    arm is far from the agent's last target (an environment reset that nobody reported).
    ``episode_start`` set for a slot on consecutive calls counts once, unless the arm jumped:
    SB3's ``evaluate_policy`` leaves it set for an environment that has finished its
    episodes while the others run on, and re-planning on every such step stalled it.

    Args:
        planner: ``"regions"`` (the paper's), ``"cbirrt"`` or ``"cbirrt2"`` (the baselines).
        time_budget: planning seconds per episode (first plan and replans together).
        seed: planner seed; each episode also mixes in the observed start pose, so a batch slot
            and a single call plan identically for the same observation.
        objects, tables: shapes to recognise besides the catalog (for JSON scenes).
        params: execution parameters; ``max_joint_step`` and ``control_hz``: the env's values.
        control_mode: the env's (``"joint_delta"`` or ``"ee_delta"``), with its
            ``max_tip_step`` and ``max_rot_step`` in ``ee_delta`` mode.
        **planner_params: :class:`~slide_gym.planning.params.SlideParams` overrides (e.g. ``dz``).
    """

    def __init__(
        self,
        planner: str = "regions",
        time_budget: float = 10.0,
        *,
        seed: int = 0,
        objects: Iterable[ObjectShape] = (),
        tables: Iterable[TableShape] = (),
        params: ExpertParams | None = None,
        max_joint_step: float = 0.05,
        control_hz: float = 20.0,
        control_mode: str = "joint_delta",
        max_tip_step: float = 0.01,
        max_rot_step: float = 0.05,
        **planner_params: Any,
    ):
        if planner not in PLANNERS:
            raise ValueError(f"planner must be one of {', '.join(PLANNERS)}, got {planner!r}")
        check_time_budget(time_budget)
        fields = {f.name for f in dataclasses.fields(SlideParams)}
        unknown = set(planner_params) - fields
        if unknown:
            raise ValueError(
                f"unknown planner parameters {sorted(unknown)}; "
                f"allowed: {', '.join(sorted(fields))}"
            )
        self.planner, self.time_budget, self.seed = planner, float(time_budget), int(seed)
        self.slide_params: SlideParams = dataclasses.replace(EXPERT_SLIDE_PARAMS, **planner_params)
        self.params = params or ExpertParams()
        self.library = SceneLibrary(objects, tables)
        self.max_joint_step, self.control_dt = float(max_joint_step), 1.0 / float(control_hz)
        make_control(control_mode, max_joint_step, max_tip_step, max_rot_step)  # checks them
        self.control_mode, self.ee_steps = control_mode, (float(max_tip_step), float(max_rot_step))
        self._slots: list[SlideGraspExpert | None] = []
        self._started: list[bool] = []  # episode_start of each slot's last call

    def reset(self) -> None:
        """Forget every slot's episode; the next observation starts a new one."""
        for slot in self._slots:
            if slot is not None:
                slot.close()
        self._slots = []
        self._started = []

    def expert(self, index: int = 0) -> SlideGraspExpert | None:
        """The controller of batch slot ``index`` (its ``report``, an
        :class:`agents.record.ExpertReport`, says what happened)."""
        return self._slots[index] if index < len(self._slots) else None

    def predict(
        self,
        observation: dict[str, np.ndarray],
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """Actions for one observation (8,) or a batch (n, 8) (7 wide in ee_delta mode); ``state``
        is passed through."""
        batch, batched, starts = as_batch(observation, episode_start)
        n = len(starts)
        self._slots += [None] * (n - len(self._slots))
        self._started += [False] * (n - len(self._started))
        actions = []
        for i in range(n):
            obs = {k: v[i] for k, v in batch.items()}
            slot = self._slots[i]
            repeated = starts[i] and self._started[i]
            jumped = self._was_reset(slot, obs)
            unreported_reset = episode_start is None and jumped
            self._started[i] = bool(starts[i])
            if (starts[i] and (not repeated or jumped)) or slot is None or unreported_reset:
                if slot is not None:
                    slot.close()
                slot = self._slots[i] = self._new_expert()
            actions.append(slot.act(obs))
        return (np.stack(actions) if batched else actions[0]), state

    def _new_expert(self) -> SlideGraspExpert:
        return SlideGraspExpert(
            self.planner,
            self.time_budget,
            self.slide_params,
            self.params,
            self.seed,
            self.library,
            self.control_dt,
            self.max_joint_step,
            EEActions(self.max_joint_step, *self.ee_steps)
            if self.control_mode == "ee_delta"
            else None,
        )

    @staticmethod
    def _was_reset(slot: SlideGraspExpert | None, obs: dict[str, np.ndarray]) -> bool:
        if slot is None or slot.q_cmd is None:
            return False
        return bool(np.abs(np.asarray(obs["arm_qpos"]) - slot.q_cmd).max() > _RESET_JUMP)

    def close(self) -> None:
        """Release every slot's planner."""
        self.reset()
