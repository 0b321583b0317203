"""Gymnasium environments."""

from slide_gym.envs.top_slide import TopSlideEnv

__all__ = ["TopSlideEnv"]
