"""Constrained shortcutting: straighten a tree-search path on the constraint manifold.

A path read off RRT trees wanders. When the path is a fingertip slide, a detour drags the plate
along it, possibly over the table edge, so the slide is shortened before it is executed: pick two
states, grow a constrained extension from one toward the other with the search's own callables
(projection, collision), and splice it in if it arrives and is shorter. The end states never
change, so the pair (and its validation) stays the same.
"""

from __future__ import annotations

import math
import time

import numpy as np

from slide_gym.planning.forest import Forest
from slide_gym.planning.result import OutOfTime, SearchParams
from slide_gym.planning.search import SearchFunctions, constrained_extend


def path_length(path: np.ndarray, weights: np.ndarray) -> float:
    """Sum of weighted joint distances between consecutive states."""
    diff = np.diff(path, axis=0)
    return float(np.sqrt((weights * diff * diff).sum(axis=1)).sum())


def shortcut_path(
    path: np.ndarray,
    fns: SearchFunctions,
    params: SearchParams,
    rng: np.random.Generator,
    attempts: int = 40,
    deadline: float = math.inf,
) -> np.ndarray:
    """Exactly ``attempts`` random shortcuts of ``path`` (m, dim); returns the shortened path.

    Each attempt draws two states i < j - 1 and keeps the constrained extension from state i
    to state j when it reaches j and is shorter than the stretch it replaces. The number of
    attempts (and random draws) is fixed, so the same ``rng`` state gives the same result on
    any machine. ``deadline`` (``time.perf_counter``) is only a give-up: once it passes, the
    call raises :class:`~slide_gym.planning.result.OutOfTime` rather than return a path
    shortened by fewer attempts.
    """
    path = np.asarray(path, dtype=float)
    weights = np.asarray(
        fns.distance_weights if fns.distance_weights is not None else np.ones(path.shape[1])
    )
    for done in range(attempts):
        if time.perf_counter() >= deadline:
            raise OutOfTime(f"shortcutting ran out of time after {done} of {attempts} attempts")
        i, j = np.sort(rng.choice(len(path), size=2, replace=False)) if len(path) > 2 else (0, 1)
        if j - i < 2:
            continue
        forest = Forest(path.shape[1], weights)
        root = forest.add_root(path[i])
        end, reached = constrained_extend(
            forest,
            root,
            path[j],
            fns,
            params.step_size,
            tolerance=params.goal_tolerance,
            max_steps=params.max_extend_steps,
            deadline=deadline,
        )
        if time.perf_counter() >= deadline:  # the extension may have stopped at the deadline
            raise OutOfTime(f"shortcutting ran out of time in attempt {done + 1} of {attempts}")
        if not reached:
            continue
        bridge = forest.path_to_root(end)[::-1]  # path[i] ... a state within tolerance of path[j]
        candidate = np.vstack([bridge[:-1] if len(bridge) > 1 else bridge, path[j : j + 1]])
        if path_length(candidate, weights) < path_length(path[i : j + 1], weights) - 1e-9:
            path = np.vstack([path[:i], candidate, path[j + 1 :]])
    return path
