"""Constrained shortcutting: straighten a tree-search path on the constraint manifold.

A path read off RRT trees wanders. When the path is a fingertip slide, a detour drags the plate
along it, possibly over the table edge, so the slide is shortened before it is executed: pick two
states, grow a constrained extension from one toward the other with the search's own callables
(projection, collision), and splice it in if it arrives and is shorter. The end states never
change, so the pair (and its validation) stays the same. Paths without constraints (the transfer
to the grasp) are shortcut by straight joint-space segments instead (:func:`shortcut_straight`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

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
    """At most ``attempts`` shortcuts of ``path`` (m, dim); returns the shortened path.

    The first attempt spans the whole path: when the constrained extension from its first state
    reaches its last and is shorter, the path is that one extension and smoothing stops (a
    shortcut between two of its states would be the same extension again). Otherwise each
    further attempt draws two states i < j - 1 and keeps the extension from state i to state j
    when it reaches j and is shorter than the stretch it replaces. Which attempts run depends
    only on ``rng`` and the callables, so the same ``rng`` state gives the same result on any
    machine. ``deadline`` (``time.perf_counter``) is only a give-up: once it passes, the call
    raises :class:`~slide_gym.planning.result.OutOfTime` rather than return a path shortened
    by fewer attempts.
    """
    path = np.asarray(path, dtype=float)
    weights = np.asarray(
        fns.distance_weights if fns.distance_weights is not None else np.ones(path.shape[1])
    )
    for done in range(attempts):
        if time.perf_counter() >= deadline:
            raise OutOfTime(f"shortcutting ran out of time after {done} of {attempts} attempts")
        if done == 0:
            i, j = 0, len(path) - 1
        elif len(path) > 2:
            i, j = np.sort(rng.choice(len(path), size=2, replace=False))
        else:
            break
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
            if done == 0:
                break
    return path


def shortcut_straight(
    path: np.ndarray,
    motion_valid: Callable[[np.ndarray, np.ndarray], bool],
    deadline: float = math.inf,
) -> np.ndarray:
    """Greedy straight-segment shortcuts of an unconstrained ``path`` (m, dim).

    From the first state, jump to the farthest later state that ``motion_valid`` connects by
    a straight segment, and repeat from there (the path's own edges are valid, so it always
    advances). Deterministic; ``deadline`` is a give-up, as in :func:`shortcut_path`.
    """
    path = np.asarray(path, dtype=float)
    keep, i = [0], 0
    while i < len(path) - 1:
        if time.perf_counter() >= deadline:
            raise OutOfTime("shortcutting ran out of time")
        j = len(path) - 1
        while j > i + 1 and not motion_valid(path[i], path[j]):
            j -= 1
        keep.append(j)
        i = j
    return path[keep]
