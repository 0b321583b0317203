"""The registered versions: v1 keeps friction anchors on the robot, v0 the engine's defaults;
a ``physics`` dict overrides single settings on top of the version's."""

from __future__ import annotations

import gymnasium as gym
import pytest

import slide_gym  # noqa: F401 - registers the environments
from slide_gym.envs.top_slide import TopSlideEnv
from slide_gym.sim import PhysicsParams, versioned_physics


def _settings(env_id: str, **kwargs: object) -> PhysicsParams:
    env = gym.make(env_id, **kwargs)
    try:
        return env.unwrapped.sim.settings
    finally:
        env.close()


def test_v1_anchors_the_robots_friction_and_v0_does_not() -> None:
    assert _settings("SlideGym/TopSlideGrasp-v1").friction_anchor
    assert not _settings("SlideGym/TopSlideGrasp-v0").friction_anchor
    assert _settings("SlideGym/TopSlideGoal-v1").friction_anchor


def test_a_physics_dict_overrides_single_settings_of_the_version() -> None:
    both = _settings("SlideGym/TopSlide-v1", physics={"solver_residual_threshold": 2e-4})
    assert both.friction_anchor and both.solver_residual_threshold == 2e-4
    assert not _settings("SlideGym/TopSlide-v1", physics={"friction_anchor": False}).friction_anchor
    whole = PhysicsParams(solver_iterations=50)
    assert versioned_physics(1, whole) is whole
    assert versioned_physics(1, None) == {"friction_anchor": True}
    assert versioned_physics(0, {"solver_iterations": 50}) == {"solver_iterations": 50}


@pytest.mark.parametrize("version", [2, -1, True, "1"])
def test_an_unknown_version_is_a_clear_error(version: object) -> None:
    with pytest.raises(ValueError, match=r"version must be one of 0, 1, got"):
        TopSlideEnv(version=version)  # type: ignore[arg-type]
