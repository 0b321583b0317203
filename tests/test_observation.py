"""Observation modes: the flat state Dict (SB3-clean), the hole descriptor, and the ``"rgbd"``
cameras (keys, shapes, ranges, motion, determinism); the README's Monitor-wrapped evaluation."""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterator
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import shapely

import slide_gym  # noqa: F401 - registers the environments
from slide_gym.envs.cameras import FAR, NEAR
from slide_gym.envs.observation import (
    HOLE_POINTS,
    IMAGE_KEYS,
    MAX_HOLES,
    OBJECT_OUTLINE_POINTS,
    holes_descriptor,
)
from slide_gym.envs.top_slide import TopSlideEnv
from slide_gym.geometry import ObjectShape, get_object

env_checker = pytest.importorskip("stable_baselines3.common.env_checker")

W, H = 48, 40
"""A small, non-square image size: a swapped width and height shows."""
RECT = [(-0.06, -0.03), (0.06, -0.03), (0.06, 0.03), (-0.06, 0.03)]


def _ngon(radius: float, n: int, cx: float = 0.0, cy: float = 0.0) -> np.ndarray:
    t = 2 * np.pi * np.arange(n) / n
    return np.column_stack([cx + radius * np.cos(t), cy + radius * np.sin(t)])


@pytest.fixture
def make_env() -> Iterator[Callable[..., TopSlideEnv]]:
    """``make_env(**kwargs)``: a TopSlideEnv closed after the test."""
    made: list[TopSlideEnv] = []

    def make(**kwargs: Any) -> TopSlideEnv:
        made.append(TopSlideEnv(**kwargs))
        return made[-1]

    yield make
    for env in made:
        env.close()


def _sb3_warnings(env: gym.Env) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        env_checker.check_env(env)
    return [str(w.message) for w in caught]


def test_state_space_is_flat_and_passes_sb3_check_env(make_env) -> None:
    env = make_env(object="A")
    assert all(len(space.shape) == 1 for space in env.observation_space.spaces.values())
    assert _sb3_warnings(env) == []
    obs, _ = env.reset(seed=0)
    outline = obs["object_outline"].reshape(-1, 2)
    np.testing.assert_allclose(outline, get_object("A").descriptor(OBJECT_OUTLINE_POINTS), 1e-6)
    assert not set(IMAGE_KEYS) & set(obs)


def test_rgbd_check_env_warns_only_that_depth_is_not_uint8() -> None:
    kwargs = {"render_width": 40, "render_height": 36, "camera": {"distance": 1.0}}
    env = gym.make("SlideGym/TopSlide-v0", obs_mode="rgbd", **kwargs)
    try:
        assert env.observation_space["scene_rgb"].shape == (36, 40, 3)
        messages = _sb3_warnings(env)
    finally:
        env.close()
    assert messages and all("_depth" in m for m in messages)


def test_rgbd_images_have_their_shapes_dtypes_and_ranges(make_env) -> None:
    env = make_env(object="A", obs_mode="rgbd", render_width=W, render_height=H)
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    for cam in ("scene", "wrist"):
        rgb, depth = obs[f"{cam}_rgb"], obs[f"{cam}_depth"]
        assert rgb.shape == (H, W, 3) and rgb.dtype == np.uint8 and rgb.std() > 5
        assert depth.shape == (H, W, 1) and depth.dtype == np.float32
        assert NEAR <= depth.min() < depth.max() <= FAR
    # The scene camera is 1.35 m from its target and sees the background; the wrist camera
    # looks down at the table 0.26 m below the palm's side.
    assert 0.9 < obs["scene_depth"].min() < 1.6 and obs["scene_depth"].max() == FAR
    assert 0.2 < np.median(obs["wrist_depth"]) < 0.3


def test_wrist_image_follows_the_hand_and_a_seed_replays_the_images(make_env) -> None:
    envs = [make_env(obs_mode="rgbd", render_width=W, render_height=H) for _ in range(2)]
    action = np.zeros(8, dtype=np.float32)
    action[0] = 1.0  # turn the base joint: the hand swings sideways
    runs = []
    for env in envs:
        frames = [env.reset(seed=3)[0]]
        frames += [env.step(action)[0] for _ in range(4)]
        runs.append(frames)
    for a, b in zip(*runs, strict=True):
        for key in IMAGE_KEYS:
            np.testing.assert_array_equal(a[key], b[key])
    first, last = runs[0][0], runs[0][-1]
    moved = np.abs(first["wrist_rgb"].astype(int) - last["wrist_rgb"]).mean()
    assert moved > 5


def test_render_follows_render_size_and_camera(make_env) -> None:
    default = make_env(render_mode="rgb_array")
    default.reset(seed=0)
    assert default.render().shape == (360, 480, 3)
    views = []
    for camera in (None, {"distance": 0.8, "yaw": 90.0}):
        env = make_env(render_mode="rgb_array", render_width=W, render_height=H, camera=camera)
        env.reset(seed=0)
        views.append(env.render())
    assert views[0].shape == (H, W, 3) and not np.array_equal(views[0], views[1])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"obs_mode": "rgb"}, "obs_mode"),
        ({"render_width": 0}, "render_width"),
        ({"render_height": 12.5}, "render_height"),
        ({"camera": {"dist": 1.0}}, "camera keys"),
        ({"camera": {"distance": -1.0}}, "distance"),
        ({"camera": {"target": (0.0, 0.0)}}, "target"),
    ],
)
def test_bad_image_arguments_are_value_errors(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        TopSlideEnv(**kwargs)


def test_holes_descriptor_pads_with_zeros_and_keeps_the_largest(make_env) -> None:
    env = make_env(object="A")
    obs, _ = env.reset(seed=0)
    np.testing.assert_array_equal(obs["object_hole_mask"], [1, 0, 0, 0])
    assert obs["object_holes"].shape == (2 * MAX_HOLES * HOLE_POINTS,)
    points = obs["object_holes"].reshape(MAX_HOLES, HOLE_POINTS, 2)
    ring = get_object("A").polygon.interiors[0]
    assert max(ring.distance(shapely.Point(p)) for p in points[0]) < 1e-6
    assert not points[1:].any()

    square_holes, square_mask = holes_descriptor(get_object("square"))
    assert not square_holes.any() and not square_mask.any()

    radii = (0.004, 0.008, 0.005, 0.006, 0.007)  # five holes: the smallest is left out
    xs = (-0.044, -0.022, 0.0, 0.022, 0.044)
    holes = [_ngon(r, 12, x) for r, x in zip(radii, xs, strict=True)]
    plate = ObjectShape.from_vertices("five_holes", RECT, holes, 0.003)
    points, mask = holes_descriptor(plate)
    np.testing.assert_array_equal(mask, [1, 1, 1, 1])
    centres = points.reshape(MAX_HOLES, HOLE_POINTS, 2).mean(axis=1)
    np.testing.assert_allclose(centres[:, 0], [-0.022, 0.044, 0.022, 0.0], atol=1e-3)


def test_readme_evaluate_policy_with_monitor_warns_nothing() -> None:
    evaluation = pytest.importorskip("stable_baselines3.common.evaluation")
    from stable_baselines3.common.monitor import Monitor

    from agents import PlannerAgent

    env = Monitor(
        gym.make("SlideGym/TopSlideGrasp-v0", object="square", table="square", max_episode_steps=30)
    )
    agent = PlannerAgent("cbirrt2", time_budget=1.0, seed=0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rewards, lengths = evaluation.evaluate_policy(
            agent, env, n_eval_episodes=2, return_episode_rewards=True
        )
    env.close()
    assert lengths == [30, 30] and len(rewards) == 2
    assert not [w for w in caught if "Monitor" in str(w.message)]
