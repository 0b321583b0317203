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
}
ENV_IDS: tuple[str, ...] = tuple(_SPECS)
"""The registered environment ids (time limits: 40 s to slide, 60 s to slide and grasp).

40 s (800 steps): the expert leaves the plate graspable after a median of 224 steps, 425 at
the 95th percentile and 570 at most (a slide and two replanned ones; 85 episodes of
``slide-gym bench execute --trials 3``), so 800 leaves room past the longest."""

for _env_id, (_kwargs, _steps) in _SPECS.items():
    if _env_id not in registry:
        register(_env_id, entry_point=_ENTRY_POINT, kwargs=_kwargs, max_episode_steps=_steps)

from slide_gym.geometry import OBJECT_NAMES, TABLE_NAMES  # noqa: E402

__all__ = ["ENV_IDS", "OBJECT_NAMES", "TABLE_NAMES", "__version__"]
