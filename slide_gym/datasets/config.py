"""What a demonstration dataset is collected from: :class:`CollectConfig`, and dataset ids.

A configuration is the identity of a dataset apart from its size: collecting more episodes
into the same id continues it, and the same id with another configuration is refused.
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from slide_gym import DICT_ENV_IDS
from slide_gym.envs.control import CONTROL_MODES
from slide_gym.envs.observation import OBS_MODES
from slide_gym.envs.randomization import DEFAULT, parse, to_json
from slide_gym.envs.scene import SceneChoice
from slide_gym.planning.api import PLANNERS
from slide_gym.planning.result import check_time_budget
from slide_gym.sim import physics_overrides
from slide_gym.splits import get_split

MAX_ACTION_NOISE = 1.0
"""Largest DART noise: one standard deviation spans half the action range."""
DATASET_ID = re.compile(r"^[A-Za-z0-9_-]{2,}/[A-Za-z0-9_-]+-v\d+$")
"""Minari's id form with a namespace (Minari refuses a ``.`` anywhere in an id)."""


def check_dataset_id(dataset_id: str) -> str:
    """``dataset_id`` if it reads ``NAMESPACE/NAME-vK`` (Minari's form), else a ValueError."""
    if not isinstance(dataset_id, str) or not DATASET_ID.match(dataset_id):
        raise ValueError(
            f"dataset id must read NAMESPACE/NAME-vK (namespace of 2+ letters, digits, '_-'; "
            f"K a version number), e.g. slide-gym/square-expert-v0; got {dataset_id!r}"
        )
    return dataset_id


NUMERIC_PLANNER_PARAMS = ("u_star", "centroid_margin", "press_radius", "max_rotation")
"""The expert's planner parameters a collection may override (the slide's goal and press)."""


def check_planner_params(params: dict[str, Any]) -> dict[str, float]:
    """``params`` as ``{name: float}``, or a ValueError naming the allowed keys."""
    if not isinstance(params, dict):
        raise ValueError(f"planner_params must be a dict of name -> number, got {params!r}")
    out = {}
    for name, value in params.items():
        if name not in NUMERIC_PLANNER_PARAMS:
            raise ValueError(
                f"unknown planner parameter {name!r}; allowed: {', '.join(NUMERIC_PLANNER_PARAMS)}"
            )
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"planner parameter {name} must be a number, got {value!r}")
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"planner parameter {name} must be positive and finite, got {value}")
        out[name] = float(value)
    return out


def check_expert_params(params: dict[str, Any]) -> dict[str, float]:
    """``params`` as ``{name: float}`` if :func:`agents.params.expert_params` accepts them,
    else its ValueError (an unknown name lists the allowed ones)."""
    from agents.params import expert_params  # agents builds on slide_gym: imported on use

    if not isinstance(params, dict):
        raise ValueError(f"expert_params must be a dict of name -> number, got {params!r}")
    for name, value in params.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"expert parameter {name} must be a number, got {value!r}")
    out = {name: float(value) for name, value in params.items()}
    expert_params(out)
    return out


@dataclass(frozen=True)
class CollectConfig:
    """The environment and the agent of a dataset.

    Args:
        env_id: one of :data:`slide_gym.DICT_ENV_IDS`.
        agent: the planner the expert uses (``"regions"``, ``"cbirrt"``, ``"cbirrt2"``).
        object, table: catalog names, ``.json`` paths (stored absolute), or ``"random"``
            (``"procedural"`` for objects), as the env takes them.
        scale, thickness: the env's object scale and thickness (None: each object's own).
        obs_mode, control_mode: the env's observation and control modes.
        time_budget: the expert's planning seconds per episode.
        seed: the first reset seed; episode i of the collection is reset with ``seed + i``.
        only_success: keep only the episodes the expert solved (then more seeds are run).
        action_noise: DART (Laskey et al. 2017): the standard deviation of seeded Gaussian
            noise added to the expert's arm actions before they are executed (action units;
            the hand command is left alone). The dataset's ``actions`` are the executed ones
            (an exact replay needs them) and ``infos["expert_action"]`` the expert's clean
            ones, the labels a learner trains on. 0: no noise, no labels.
        noise_phases: the expert's phases (:data:`agents.expert.PHASES`) whose actions get
            the noise, such as ``["approach", "transfer"]``, the free-space moves where a
            learner drifts; None: every phase. Noise while pressing or pinching turns the
            slid plate and loosens the grasp (the expert lifted 2 of 4 square grasps with
            noise 0.03 on every phase).
        split: the named split (:mod:`slide_gym.splits`) the episodes come from, or None;
            then ``object`` is the split's and every seed stays in its collect seeds.
        randomization: the env's domain randomisation: None, ``"default"`` or a dict of
            key -> (low, high) or number (stored as key -> [low, high]); each episode's
            drawn values are in its reset options.
        physics: the env's physics settings (:class:`slide_gym.sim.PhysicsParams` fields
            other than ``timestep``), e.g. ``{"friction_anchor": True}``; None: the defaults.
        planner_params: overrides of the expert's planner parameters (names in
            :data:`NUMERIC_PLANNER_PARAMS`), e.g. ``{"u_star": 0.03}`` for slides that stop
            at a smaller overhang; None: the expert's own.
        expert_params: overrides of the expert's execution settings
            (:class:`agents.params.ExpertParams` fields), e.g. ``{"stop_overhang": 0.035}``
            for slides that end once the plate overhangs 3.5 cm; None: the defaults.
    """

    env_id: str
    agent: str = "regions"
    object: str = "square"
    table: str = "square"
    scale: float = 1.0
    thickness: float | None = None
    obs_mode: str = "state"
    control_mode: str = "joint_delta"
    time_budget: float = 10.0
    seed: int = 0
    only_success: bool = False
    action_noise: float = 0.0
    noise_phases: list[str] | None = None
    split: str | None = None
    randomization: str | dict[str, list[float]] | None = None
    physics: dict[str, Any] | None = None
    planner_params: dict[str, float] | None = None
    expert_params: dict[str, float] | None = None

    def __post_init__(self) -> None:
        if self.env_id not in DICT_ENV_IDS:
            raise ValueError(
                f"env {self.env_id!r} is not a slide-gym env with Dict observations; "
                f"choose from {', '.join(DICT_ENV_IDS)}"
            )
        if self.agent not in PLANNERS:
            raise ValueError(f"agent must be one of {', '.join(PLANNERS)}, got {self.agent!r}")
        if self.obs_mode not in OBS_MODES:
            raise ValueError(f"obs_mode must be one of {', '.join(OBS_MODES)}")
        if self.control_mode not in CONTROL_MODES:
            raise ValueError(f"control_mode must be one of {', '.join(CONTROL_MODES)}")
        check_time_budget(self.time_budget)
        if not (
            isinstance(self.action_noise, (int, float))
            and math.isfinite(self.action_noise)
            and 0 <= self.action_noise <= MAX_ACTION_NOISE
        ):
            raise ValueError(
                f"action_noise must be a number in [0, {MAX_ACTION_NOISE}] (the standard "
                f"deviation in action units, which span [-1, 1]), got {self.action_noise!r}"
            )
        if self.noise_phases is not None:
            object.__setattr__(self, "noise_phases", _check_noise_phases(self.noise_phases))
            if not self.action_noise:
                raise ValueError("noise_phases needs an action_noise above 0")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ValueError(f"seed must be a non-negative integer, got {self.seed!r}")
        if not (isinstance(self.scale, (int, float)) and math.isfinite(self.scale)):
            raise ValueError(f"scale must be a positive number, got {self.scale!r}")
        # JSON shapes are stored by absolute path, so the dataset's env spec finds them again.
        for kind in ("object", "table"):
            spec = getattr(self, kind)
            if isinstance(spec, str) and spec.lower().endswith(".json"):
                object.__setattr__(self, kind, str(Path(spec).expanduser().resolve()))
        SceneChoice(self.object, self.table, self.scale, self.thickness)  # ValueError if bad
        if self.split is not None:
            split = get_split(self.split)
            if self.object != split.object:
                raise ValueError(
                    f"split {split.name!r} collects object {split.object!r}, not {self.object!r}"
                )
            split.first_seed("collect", 1, self.seed)
        if self.planner_params is not None:
            object.__setattr__(self, "planner_params", check_planner_params(self.planner_params))
        if self.expert_params is not None:
            object.__setattr__(self, "expert_params", check_expert_params(self.expert_params))
        object.__setattr__(self, "physics", physics_overrides(self.physics))
        ranges = parse(self.randomization)
        if self.randomization is not None and self.randomization != DEFAULT:
            object.__setattr__(self, "randomization", to_json(ranges))  # JSON's own form

    def agent_kwargs(self) -> dict[str, Any]:
        """The expert's overrides: planner parameters, and ``params`` (its execution
        settings) if any are set (``PlannerAgent(..., **kwargs)``)."""
        kwargs: dict[str, Any] = dict(self.planner_params or {})
        if self.expert_params:
            from agents.params import expert_params

            kwargs["params"] = expert_params(self.expert_params)
        return kwargs

    def env_kwargs(self) -> dict[str, Any]:
        """The keyword arguments of ``gym.make(env_id, ...)`` (JSON values only)."""
        kwargs: dict[str, Any] = {"object": self.object, "table": self.table, "scale": self.scale}
        if self.thickness is not None:
            kwargs["thickness"] = self.thickness
        kwargs |= {"obs_mode": self.obs_mode, "control_mode": self.control_mode}
        if self.randomization is not None:
            kwargs["randomization"] = self.randomization
        if self.physics:
            kwargs["physics"] = self.physics
        return kwargs

    def to_json(self) -> dict[str, Any]:
        """The fields as JSON values; ``action_noise``, ``noise_phases``, ``split``,
        ``randomization`` and
        ``physics`` only
        when set, so that collections made before those fields existed keep their identity
        (and resume)."""
        data = dataclasses.asdict(self)
        for name in ("action_noise", "noise_phases", "split"):
            if not data[name]:
                del data[name]
        for name in ("randomization", "physics", "planner_params", "expert_params"):
            if not data[name]:
                del data[name]
        return data

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> CollectConfig:
        fields = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in data.items() if k in fields})

    @classmethod
    def from_metadata(cls, metadata: dict[str, Any]) -> CollectConfig:
        """The config that collected a dataset (its ``slide_gym`` metadata), whose
        ``expert_params`` also hold every numeric expert setting recorded there that differs
        from today's default: an expert built from it acts as the one that collected the
        dataset, even where a default changed since (the quicker defaults of ``acbcfdf``).
        ``grasp_posture``, not a number, keeps today's value."""
        from agents.params import ExpertParams

        config = cls.from_json(metadata["config"])
        recorded = metadata.get("agent", {}).get("expert_params", {})
        defaults = dataclasses.asdict(ExpertParams())
        changed = {
            name: float(value)
            for name, value in recorded.items()
            if isinstance(value, (int, float)) and name in defaults and value != defaults[name]
        }
        if not changed:
            return config
        return dataclasses.replace(
            config, expert_params={**changed, **(config.expert_params or {})}
        )

    def differences(self, other: CollectConfig) -> list[str]:
        """``"name: mine != theirs"`` for every field that differs."""
        a, b = dataclasses.asdict(self), dataclasses.asdict(other)
        return [f"{k}: {a[k]!r} != {b[k]!r}" for k in a if a[k] != b[k]]


def _check_noise_phases(phases: Any) -> list[str]:
    """``phases`` as a list of the expert's phase names; ValueError naming the allowed ones."""
    from agents.expert import PHASES

    names = [phases] if isinstance(phases, str) else list(phases)
    unknown = [p for p in names if p not in PHASES]
    if not names or unknown:
        raise ValueError(
            f"noise_phases must name some of the expert's phases ({', '.join(PHASES)}), "
            f"got {phases!r}"
        )
    return names
