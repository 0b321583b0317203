"""Policies for slide-gym environments: the planners as closed-loop experts, a scripted slider
(no planner), and policies learned from the expert (:mod:`agents.learned`: the diffusion
policy, ``DiffusionPolicy.load(folder)``).

``PlannerAgent`` has Stable-Baselines3's ``predict`` interface; ``run_episode`` runs one
expert episode and returns its ``EpisodeRecord`` (``to_json_dict()`` is the ``slide-gym run``
summary); ``ScriptedSlider`` is the scripted press-and-slide of ``slide-gym demo``.
"""

from agents.episode import run_episode
from agents.expert import SlideGraspExpert
from agents.params import EXPERT_SLIDE_PARAMS, ExpertParams
from agents.planner_agent import PlannerAgent
from agents.record import EpisodeRecord, ExpertReport
from agents.scripted import ScriptedSlider, run_demo

__all__ = [
    "EXPERT_SLIDE_PARAMS",
    "EpisodeRecord",
    "ExpertParams",
    "ExpertReport",
    "PlannerAgent",
    "ScriptedSlider",
    "SlideGraspExpert",
    "run_demo",
    "run_episode",
]
