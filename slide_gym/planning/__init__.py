"""Robot-independent motion planning core: forests, Algorithm 1 search and results.

Robot-specific pieces (sampling from regions, constraint projection, collision checks, pair
validation) plug in as plain callables through :class:`SearchFunctions`.
"""

from __future__ import annotations

from slide_gym.planning.forest import Forest, weighted_distance
from slide_gym.planning.result import (
    Planner,
    PlannerStats,
    PlanResult,
    PlanStatus,
    SearchParams,
    check_time_budget,
    timed,
)
from slide_gym.planning.search import (
    PLANNERS,
    DensifyError,
    ForestConnectPlanner,
    SearchFunctions,
    can_add_root,
    constrained_extend,
    densify,
    forest_connect_search,
    timed_functions,
)

__all__ = [
    "PLANNERS",
    "DensifyError",
    "Forest",
    "ForestConnectPlanner",
    "PlanResult",
    "PlanStatus",
    "Planner",
    "PlannerStats",
    "SearchFunctions",
    "SearchParams",
    "can_add_root",
    "check_time_budget",
    "constrained_extend",
    "densify",
    "forest_connect_search",
    "timed",
    "timed_functions",
    "weighted_distance",
]
