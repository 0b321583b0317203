"""Per-reset scene options, and one start pose per seed across plan, run and the env."""

from __future__ import annotations

import numpy as np
import pytest

from slide_gym.envs.top_slide import TopSlideEnv
from slide_gym.geometry import OBJECT_NAMES, TABLE_NAMES, get_object, get_table
from slide_gym.planning.runner import plan_once
from slide_gym.task import seeded_start_pose


@pytest.fixture
def env():
    e = TopSlideEnv(object="square", table="square")
    yield e
    e.close()


def test_options_choose_this_episodes_scene_and_the_env_keeps_its_own(env) -> None:
    _, info = env.reset(seed=0, options={"object": "E", "table": "round", "thickness": 0.002})
    assert (info["object"], info["table"]) == ("E", "round")
    assert env.task.object.thickness == pytest.approx(0.002)
    _, info = env.reset(seed=0, options={"object": "L", "scale": 0.8})
    assert (info["object"], info["table"]) == ("L", "square")
    assert env.task.object.polygon.area == pytest.approx(get_object("L", 0.8).polygon.area)
    _, info = env.reset(seed=0)
    assert (info["object"], info["table"]) == ("square", "square")
    assert env.task.object.thickness == get_object("square").thickness


def test_random_and_procedural_options_name_what_they_drew(env) -> None:
    _, info = env.reset(seed=3, options={"object": "random", "table": "random"})
    assert info["object"] in OBJECT_NAMES and info["table"] in TABLE_NAMES
    _, again = env.reset(seed=3, options={"object": "random", "table": "random"})
    assert (again["object"], again["table"]) == (info["object"], info["table"])
    _, info = env.reset(seed=5, options={"object": "procedural"})
    assert info["object"].startswith("procedural")


@pytest.mark.parametrize(
    ("options", "match"),
    [
        ({"objekt": "L"}, "unknown reset options.*allowed: object, table, scale, thickness"),
        ({"object": "l"}, "did you mean 'L'"),
        ({"table": "round-ish"}, "table"),
        ({"scale": 0.0}, "scale must be a positive number"),
        ({"thickness": 3.0}, "thickness must be"),
        ({"object_pose": (9.0, 9.0, 0.0)}, "object_pose"),
        ({"arm_qpos": [0.0] * 6}, "arm_qpos must be 7 finite joint angles"),
    ],
)
def test_bad_options_are_value_errors_that_name_them(env, options, match) -> None:
    with pytest.raises(ValueError, match=match):
        env.reset(seed=0, options=options)


@pytest.mark.parametrize(("obj", "table", "seed"), [("E", "square", 0), ("L", "round", 3)])
def test_plan_run_and_env_start_from_the_same_pose_for_a_seed(env, obj, table, seed) -> None:
    pose = seeded_start_pose(get_object(obj), get_table(table), seed)
    _, info = env.reset(seed=seed, options={"object": obj, "table": table})
    np.testing.assert_allclose(info["object_pose_2d"], pose, atol=2e-3)  # after settling
    planned = plan_once(obj, table, seed=seed, time_budget=0.01)
    np.testing.assert_array_equal(planned["object_start_pose"], pose)
