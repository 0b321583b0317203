"""slide-gym: pre-grasp top-sliding of thin objects with a compliant underactuated hand.

Importing the package registers the Gymnasium environments listed in :data:`ENV_IDS`.
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

from slide_gym import sim as _sim  # noqa: F401 - first PyBullet import, with its banner silenced

__version__ = "0.1.0"

_ENTRY_POINT = "slide_gym.envs.top_slide:TopSlideEnv"
_TASKS = {
    "TopSlide": ({"goal": "slide", "reward_type": "sparse"}, 800),
    "TopSlideDense": ({"goal": "slide", "reward_type": "dense"}, 800),
    "TopSlideGrasp": ({"goal": "grasp", "reward_type": "sparse"}, 1200),
    "TopSlideGraspDense": ({"goal": "grasp", "reward_type": "dense"}, 1200),
    "TopSlideGoal": ({}, 800),
}
_ENTRY_POINTS = {"TopSlideGoal": "slide_gym.envs.goal:TopSlideGoalEnv"}
"""Entry points other than :class:`TopSlideEnv` (the goal-conditioned slide, for HER)."""
VERSIONS = (0, 1)
"""The registered versions of every task: v1 keeps friction anchors on the robot's contacts
(:data:`slide_gym.sim.ENV_VERSION_PHYSICS`); v0 is the physics every figure before it
was collected in, kept so that its datasets replay and its commands reproduce."""
_SPECS = {
    f"SlideGym/{task}-v{version}": (task, {**kwargs, "version": version}, steps)
    for version in VERSIONS
    for task, (kwargs, steps) in _TASKS.items()
}
ENV_IDS: tuple[str, ...] = tuple(_SPECS)
"""The registered environment ids (time limits: 40 s to slide, 60 s to slide and grasp).

40 s (800 steps): the expert leaves the plate graspable after a median of 224 steps, 425 at
the 95th percentile and 570 at most (a slide and two replanned ones; 85 episodes of
``slide-gym bench execute --trials 3``), so 800 leaves room past the longest."""

DICT_ENV_IDS: tuple[str, ...] = tuple(i for i in ENV_IDS if _SPECS[i][0] not in _ENTRY_POINTS)
"""The ids of :class:`~slide_gym.envs.top_slide.TopSlideEnv` itself (its state ``Dict``
observation): the ones the planner agent, ``slide-gym run`` and ``bench execute`` drive."""
EXPERT_ENV_ID = "SlideGym/TopSlideGrasp-v1"
"""The env ``slide-gym run``, ``collect``, ``evaluate`` and ``bench execute`` use by
default: slide, grasp, lift."""

for _env_id, (_task, _kwargs, _steps) in _SPECS.items():
    if _env_id not in registry:
        register(
            _env_id,
            entry_point=_ENTRY_POINTS.get(_task, _ENTRY_POINT),
            kwargs=_kwargs,
            max_episode_steps=_steps,
        )

from slide_gym.geometry import OBJECT_NAMES, TABLE_NAMES  # noqa: E402
from slide_gym.task import TaskParams  # noqa: E402

__all__ = [
    "DICT_ENV_IDS",
    "ENV_IDS",
    "EXPERT_ENV_ID",
    "OBJECT_NAMES",
    "TABLE_NAMES",
    "VERSIONS",
    "TaskParams",
    "__version__",
]
