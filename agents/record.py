"""What one expert episode produced: the ``slide-gym run --json`` object, the rows of
``slide-gym bench execute``, and the per-episode metadata of datasets.

:class:`ExpertReport` is what the expert itself knows (filled attribute by attribute by
:class:`agents.expert.SlideGraspExpert` as it plans, slides and re-aims);
:class:`EpisodeRecord` adds the scene and the environment's outcome. Every JSON key is a field
name of one of the two: :meth:`EpisodeRecord.to_json_dict` flattens them into one object.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

from slide_gym import EXPERT_ENV_ID


@dataclass(kw_only=True)
class ExpertReport:
    """The expert's account of its episode.

    Attributes:
        planned: a plan was found.
        replans: plans made after the first slide (from where the plate lay).
        planning_time_s: seconds spent planning and re-checking grasps (``None``: no episode
            ran, the scene was rejected).
        plan_status: status of the last planner query (``"solved"``, ``"timeout"``,
            ``"iteration_limit"``, ``"infeasible"``), ``None`` before any.
        gave_up: why the expert gave up (it then stops acting), ``None`` if it did not.
        events: notable moments, in order (failed plan attempts, pull-backs, slide checks).
        phase_steps: ``(phase, step)`` each time a phase begins: the env step (0 = the first
            action) of its first action, in order (a replan's phases appear again).
        object_predicted_pose: ``[x, y, yaw]`` Eq. 2 predicts after the (last) slide.
        object_slid_pose: ``[x, y, yaw]`` measured after the (last) slide and lift-off.
        slide_error_m, slide_error_rad: position and yaw error of the slid pose against the
            prediction (``None`` if no slide finished).
    """

    planned: bool = False
    replans: int = 0
    planning_time_s: float | None = 0.0
    plan_status: str | None = None
    gave_up: str | None = None
    events: list[str] = field(default_factory=list)
    phase_steps: list[tuple[str, int]] = field(default_factory=list)
    object_predicted_pose: list[float] | None = None
    object_slid_pose: list[float] | None = None
    slide_error_m: float | None = None
    slide_error_rad: float | None = None


@dataclass(kw_only=True)
class EpisodeRecord:
    """One episode in ``SlideGym/TopSlideGrasp-v0``: scene, outcome and the expert's report.

    Attributes:
        object, table: shape names; ``scale``: the object's scale; ``seed``: the reset seed;
            ``planner``: the planner's name.
        phase_reached: the expert's last phase (``"done"``, ``"lift"``, ``"failed"``, ...),
            ``"rejected"`` if the scene was refused before an episode.
        env_id: the environment the episode ran in.
        success: the env's ``is_success`` at the end (for the grasp envs: the object lifted
            in the fingers; for the slide envs: left graspable).
        failure: why the episode failed (:func:`agents.outcome.failure_cause`: fell off, the
            expert's reason for giving up, out of time, or the plate's state at the end; why
            the scene was rejected), ``None`` exactly when it succeeded.
        steps: env steps; ``sim_time_s``: simulated seconds; ``wall_time_s``: real seconds
            (``None`` if no episode ran).
        object_start_pose, object_final_pose: ``[x, y, yaw]`` at reset and at the end.
        lift_height_m: how far the object's bottom-face centre rose above the table top, at
            the end; ``max_lift_height_m``: the most during the episode.
        clearance_m: the object's lowest point above the table top at the end (the lift test
            needs ``TaskParams.lift_height``, 5 cm); ``max_clearance_m``: the most.
        fell_off: the object fell off the table; ``truncated``: the episode hit its time limit
            or was ended when the expert gave up.
        video: path of the recorded video, if any.
        expert: the expert's :class:`ExpertReport`.
    """

    object: str
    table: str
    scale: float = 1.0
    seed: int
    planner: str
    env_id: str = EXPERT_ENV_ID
    success: bool = False
    failure: str | None = None
    expert: ExpertReport = field(default_factory=ExpertReport)
    phase_reached: str
    steps: int = 0
    sim_time_s: float = 0.0
    wall_time_s: float | None = None
    object_start_pose: list[float] | None = None
    object_final_pose: list[float] | None = None
    lift_height_m: float | None = None
    max_lift_height_m: float | None = None
    clearance_m: float | None = None
    max_clearance_m: float | None = None
    fell_off: bool = False
    truncated: bool = False
    video: str | None = None

    @classmethod
    def rejected(
        cls,
        object: str,  # noqa: A002 - the JSON key
        table: str,
        *,
        seed: int,
        planner: str,
        reason: str | Exception,
        scale: float = 1.0,
        env_id: str = EXPERT_ENV_ID,
    ) -> EpisodeRecord:
        """A scene refused before any episode ran (bad name, object too large, ...)."""
        return cls(
            object=str(object),
            table=str(table),
            scale=float(scale),
            seed=int(seed),
            planner=planner,
            env_id=env_id,
            phase_reached="rejected",
            failure=str(reason),
            expert=ExpertReport(planning_time_s=None),
        )

    def to_json_dict(self) -> dict[str, Any]:
        """One flat dict of JSON values: this record's fields with the expert's spliced in
        where ``expert`` stands (the ``slide-gym run --json`` object)."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            if f.name == "expert":
                out.update(dataclasses.asdict(self.expert))
            else:
                out[f.name] = _copy(getattr(self, f.name))
        return out

    @classmethod
    def from_json_dict(cls, data: dict[str, Any]) -> EpisodeRecord:
        """The record of a :meth:`to_json_dict` object (other keys, e.g. a job's ``case``,
        are ignored; keys missing from older files take their defaults)."""
        mine = {f.name for f in dataclasses.fields(cls)} - {"expert"}
        theirs = {f.name for f in dataclasses.fields(ExpertReport)}
        report = {k: v for k, v in data.items() if k in theirs}
        if "phase_steps" in report:  # JSON has no tuples
            report["phase_steps"] = [(str(p), int(k)) for p, k in report["phase_steps"]]
        return cls(**{k: v for k, v in data.items() if k in mine}, expert=ExpertReport(**report))


def _copy(value: Any) -> Any:
    return list(value) if isinstance(value, list) else value
