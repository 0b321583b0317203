"""Policies for slide-gym environments: the planners as closed-loop experts (learned agents to
come).

``PlannerAgent`` has Stable-Baselines3's ``predict`` interface; ``run_episode`` runs one
expert episode and returns the ``slide-gym run`` summary.
"""

from agents.episode import run_episode
from agents.expert import SlideGraspExpert
from agents.params import EXPERT_SLIDE_PARAMS, ExpertParams
from agents.planner_agent import PlannerAgent

__all__ = ["EXPERT_SLIDE_PARAMS", "ExpertParams", "PlannerAgent", "SlideGraspExpert", "run_episode"]
