"""Policies learned from the expert's demonstrations: a diffusion policy over action chunks
(Chi et al. 2023), trained on plain, DART or DAgger data.

- :mod:`~agents.learned.features`: what the policy sees (the state observation, plus the
  plate in the fingertip frame, the nearest table edge and the overhang, all from the
  observation alone);
- :mod:`~agents.learned.data`: demonstrations as windows of inputs and action chunks;
- :mod:`~agents.learned.frames`: chunks of fingertip targets in the plate's edge frame
  (``--actions targets``) and the step toward one;
- :mod:`~agents.learned.unet`, :mod:`~agents.learned.diffusion`: the network, the noise
  schedule, DDIM sampling, EMA;
- :mod:`~agents.learned.train`: ``slide-gym train-dp`` (checkpoints, validation, resume);
- :mod:`~agents.learned.policy`: :class:`DiffusionPolicy`, SB3's ``predict`` with a
  receding-horizon action queue per env;
- :mod:`~agents.learned.dagger`: ``slide-gym dagger`` with the replanning expert's labels.
"""

from agents.learned.diffusion import DiffusionConfig
from agents.learned.policy import DiffusionPolicy
from agents.learned.train import TrainConfig, train_diffusion

__all__ = ["DiffusionConfig", "DiffusionPolicy", "TrainConfig", "train_diffusion"]
