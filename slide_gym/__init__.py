"""slide-gym: pre-grasp top-sliding of thin objects with a compliant underactuated hand.

Importing the package registers the Gymnasium environments listed in :data:`ENV_IDS`.
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

from slide_gym import sim as _sim  # noqa: F401 - first PyBullet import, with its banner silenced

__version__ = "0.1.0"

_ENTRY_POINT = "slide_gym.envs.top_slide:TopSlideEnv"
_SPECS = {
    "SlideGym/TopSlide-v0": ({"goal": "slide", "reward_type": "sparse"}, 800),
    "SlideGym/TopSlideDense-v0": ({"goal": "slide", "reward_type": "dense"}, 800),
    "SlideGym/TopSlideGrasp-v0": ({"goal": "grasp", "reward_type": "sparse"}, 1200),
    "SlideGym/TopSlideGraspDense-v0": ({"goal": "grasp", "reward_type": "dense"}, 1200),
    "SlideGym/TopSlideGoal-v0": ({}, 800),
}
_ENTRY_POINTS = {"SlideGym/TopSlideGoal-v0": "slide_gym.envs.goal:TopSlideGoalEnv"}
"""Entry points other than :class:`TopSlideEnv` (the goal-conditioned slide, for HER)."""
ENV_IDS: tuple[str, ...] = tuple(_SPECS)
"""The registered environment ids (time limits: 40 s to slide, 60 s to slide and grasp).

40 s (800 steps): the expert leaves the plate graspable after a median of 224 steps, 425 at
the 95th percentile and 570 at most (a slide and two replanned ones; 85 episodes of
``slide-gym bench execute --trials 3``), so 800 leaves room past the longest."""

DICT_ENV_IDS: tuple[str, ...] = tuple(i for i in ENV_IDS if i not in _ENTRY_POINTS)
"""The ids of :class:`~slide_gym.envs.top_slide.TopSlideEnv` itself (its state ``Dict``
observation): the ones the planner agent, ``slide-gym run`` and ``bench execute`` drive."""
EXPERT_ENV_ID = "SlideGym/TopSlideGrasp-v0"
"""The env ``slide-gym run`` and ``bench execute`` use by default: slide, grasp, lift."""

for _env_id, (_kwargs, _steps) in _SPECS.items():
    if _env_id not in registry:
        register(
            _env_id,
            entry_point=_ENTRY_POINTS.get(_env_id, _ENTRY_POINT),
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
    "TaskParams",
    "__version__",
]
