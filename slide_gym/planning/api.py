"""Public names of the robot-specific top-sliding planner (IK, collision, constraints, regions)."""

from __future__ import annotations

from slide_gym.planning.collision import MODES, CollisionChecker
from slide_gym.planning.constraints import (
    ContactBand,
    SlideConstraints,
    contact_rotation,
    finger_b_low,
    planar_pose,
)
from slide_gym.planning.ik import IKParams, IKTarget, pose_error, solve_ik
from slide_gym.planning.pair import GraspParams, PairValidator, grasp_poses
from slide_gym.planning.params import SlideParams
from slide_gym.planning.plate_goals import PlateGoalPoses, PlateGoalRegion
from slide_gym.planning.problem import TopSlideProblem
from slide_gym.planning.regions import GoalRegion, StartRegion, goal_band, nominal_seed
from slide_gym.planning.se2 import se2_compose, se2_inverse, slid_object_pose
from slide_gym.planning.search import PLANNERS
from slide_gym.planning.top_slide import TopSlidePlanner

__all__ = [
    "MODES",
    "PLANNERS",
    "CollisionChecker",
    "ContactBand",
    "GoalRegion",
    "GraspParams",
    "IKParams",
    "IKTarget",
    "PairValidator",
    "PlateGoalPoses",
    "PlateGoalRegion",
    "SlideConstraints",
    "SlideParams",
    "StartRegion",
    "TopSlidePlanner",
    "TopSlideProblem",
    "contact_rotation",
    "finger_b_low",
    "goal_band",
    "grasp_poses",
    "nominal_seed",
    "planar_pose",
    "pose_error",
    "se2_compose",
    "se2_inverse",
    "slid_object_pose",
    "solve_ik",
]
