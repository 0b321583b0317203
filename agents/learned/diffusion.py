"""Denoising diffusion over action chunks: the noise schedule, the training loss, few-step
DDIM sampling, and an exponential moving average of the weights.

:class:`DiffusionModel` owns everything a saved policy needs besides its weights' history:
the U-Net, the dataset's normalisation statistics (observations standardised, actions
scaled to [-1, 1]) and the schedule, all as buffers, so ``state_dict`` is the whole model.
"""

from __future__ import annotations

import copy
import math
from dataclasses import asdict, dataclass

import torch
from torch import nn

from agents.learned.unet import ConditionalUnet1D

OBS_CLIP = 10.0
"""Standardised observation entries are clipped to +-this."""


@dataclass(frozen=True)
class DiffusionConfig:
    """The policy's shape and its diffusion process.

    Args:
        obs_horizon: observations the policy conditions on (the latest and those before).
        pred_horizon: actions each sample predicts (a chunk, starting at the oldest
            observation's step).
        action_horizon: actions of a chunk executed before sampling again (receding horizon).
        channels, step_embed_dim: the U-Net (:class:`ConditionalUnet1D`).
        train_steps: DDPM diffusion steps (squared-cosine schedule).
        inference_steps: DDIM steps when acting.
        with_features: add :func:`agents.learned.features.task_features` to the inputs.
        tip_axes: add :func:`agents.learned.features.fingertip_axes` to the inputs (a
            smooth fingertip orientation, for skills that turn the hand).
        obs_embed: size of the learned embedding of the observation history that conditions
            the U-Net (an MLP; 0: the standardised history itself, as in Chi et al.). A
            small embedding makes the FiLM layers, most of the compute, several times
            cheaper.
        actions: ``"offsets"``, ``"deltas"`` or ``"targets"``, how a chunk holds the arm's motion
            (:data:`agents.learned.data.ACTION_REPRESENTATIONS`).
        scaling: ``"standard"``: each chunk entry (position in the chunk, action entry)
            standardised with the dataset's mean and standard deviation, so the signal has
            unit variance as the noise schedule assumes; ``"minmax"``: scaled to [-1, 1] by
            the dataset's range (Chi et al., ManiSkill). Either way the sampler clips the
            clean estimate to the dataset's range.
        hand: ``"binary"`` where every demonstrated hand command (the last action entry) is
            open (-1) or closed (+1), as the expert's are: that entry keeps its own scale
            (standardising a command that is closed in a few % of the steps puts a close
            several standard deviations out) and the policy executes its sign;
            ``"continuous"`` scales it like the arm's entries and executes it as sampled.
            :func:`agents.learned.train.train_diffusion` sets it from the data.
    """

    obs_horizon: int = 2
    pred_horizon: int = 16
    action_horizon: int = 8
    channels: tuple[int, ...] = (32, 64, 128)
    step_embed_dim: int = 64
    train_steps: int = 100
    inference_steps: int = 10
    with_features: bool = True
    tip_axes: bool = False
    actions: str = "deltas"
    scaling: str = "standard"
    obs_embed: int = 0
    hand: str = "continuous"

    def __post_init__(self) -> None:
        if (
            isinstance(self.obs_embed, bool)
            or not isinstance(self.obs_embed, int)
            or (self.obs_embed < 0)
        ):
            raise ValueError(f"obs_embed must be a whole number >= 0, got {self.obs_embed!r}")
        for name in ("obs_horizon", "pred_horizon", "action_horizon", "train_steps"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be a positive integer, got {value!r}")
        if self.obs_horizon - 1 + self.action_horizon > self.pred_horizon:
            raise ValueError(
                f"obs_horizon - 1 + action_horizon ({self.obs_horizon - 1 + self.action_horizon})"
                f" must not exceed pred_horizon ({self.pred_horizon})"
            )
        if self.pred_horizon % 2 ** (len(self.channels) - 1):
            raise ValueError(
                f"pred_horizon ({self.pred_horizon}) must be divisible by "
                f"2 ** (levels - 1) = {2 ** (len(self.channels) - 1)} for channels "
                f"{list(self.channels)}"
            )
        if self.scaling not in ("standard", "minmax"):
            raise ValueError(f"scaling must be 'standard' or 'minmax', got {self.scaling!r}")
        if self.hand not in ("continuous", "binary"):
            raise ValueError(f"hand must be 'continuous' or 'binary', got {self.hand!r}")
        if self.actions not in ("offsets", "deltas", "targets"):
            raise ValueError(
                f"actions must be 'offsets', 'deltas' or 'targets', got {self.actions!r}"
            )
        if not 1 <= self.inference_steps <= self.train_steps:
            raise ValueError(
                f"inference_steps must be in 1..train_steps ({self.train_steps}), "
                f"got {self.inference_steps!r}"
            )
        object.__setattr__(self, "channels", tuple(int(c) for c in self.channels))

    def to_json(self) -> dict:
        return {**asdict(self), "channels": list(self.channels)}


def squared_cosine_alpha_bar(steps: int, s: float = 0.008) -> torch.Tensor:
    """Cumulative signal fractions of the squared-cosine schedule (Nichol & Dhariwal 2021),
    with each step's beta capped at 0.999."""
    f = [math.cos((t / steps + s) / (1 + s) * math.pi / 2) ** 2 for t in range(steps + 1)]
    betas = torch.tensor([min(1 - f[t + 1] / f[t], 0.999) for t in range(steps)])
    return torch.cumprod(1.0 - betas, dim=0)


def ddim_times(train_steps: int, steps: int) -> list[int]:
    """The diffusion steps DDIM visits, largest first, spaced ``train_steps // steps`` apart
    from 0 ("leading" spacing, diffusers' default): 90, 80, ..., 0 for 10 of 100.

    Starting at the last training step instead (99) is much worse with a squared-cosine
    schedule: there the signal fraction is about 2e-7, the first clean estimate is noise
    amplified some 2000 times and clipped, and deterministic DDIM never recovers from it."""
    stride = max(1, train_steps // steps)
    return list(range(0, stride * steps, stride))[::-1]


class DiffusionModel(nn.Module):
    """The U-Net, the normalisation statistics and the schedule of one policy."""

    def __init__(self, config: DiffusionConfig, input_dim: int, action_dim: int) -> None:
        super().__init__()
        self.config, self.input_dim, self.action_dim = config, int(input_dim), int(action_dim)
        history = config.obs_horizon * input_dim
        self.encoder: nn.Module = (
            nn.Sequential(
                nn.Linear(history, 2 * config.obs_embed),
                nn.Mish(),
                nn.Linear(2 * config.obs_embed, config.obs_embed),
            )
            if config.obs_embed
            else nn.Identity()
        )
        cond_dim = config.obs_embed or history
        self.net = ConditionalUnet1D(action_dim, cond_dim, config.channels, config.step_embed_dim)
        self.register_buffer("obs_mean", torch.zeros(input_dim))
        self.register_buffer("obs_std", torch.ones(input_dim))
        chunk = (config.pred_horizon, action_dim)
        self.register_buffer("action_shift", torch.zeros(chunk))
        self.register_buffer("action_scale", torch.ones(chunk))
        self.register_buffer("clip_low", -torch.ones(chunk))
        self.register_buffer("clip_high", torch.ones(chunk))
        self.register_buffer("alpha_bar", squared_cosine_alpha_bar(config.train_steps))

    def set_stats(
        self,
        obs_mean: torch.Tensor,
        obs_std: torch.Tensor,
        chunk_mean: torch.Tensor,
        chunk_std: torch.Tensor,
        chunk_low: torch.Tensor,
        chunk_high: torch.Tensor,
    ) -> None:
        """Standardise inputs with ``obs_mean``/``obs_std``; scale chunks (``(pred_horizon,
        action_dim)`` statistics) by ``config.scaling``; an entry with no spread keeps scale
        1 (it becomes 0), and a binary hand command keeps its own."""
        self.obs_mean.copy_(obs_mean)
        self.obs_std.copy_(obs_std)
        if self.config.scaling == "minmax":
            shift, scale = (chunk_high + chunk_low) / 2, (chunk_high - chunk_low) / 2
        else:
            shift, scale = chunk_mean, chunk_std
        scale = torch.where(scale < 1e-6, torch.ones_like(scale), scale)
        if self.config.hand == "binary":
            shift, scale = shift.clone(), scale.clone()
            shift[:, -1], scale[:, -1] = 0.0, 1.0
        self.action_shift.copy_(shift)
        self.action_scale.copy_(scale)
        self.clip_low.copy_((chunk_low - shift) / scale)
        self.clip_high.copy_((chunk_high - shift) / scale)

    def normalize_obs(self, x: torch.Tensor) -> torch.Tensor:
        return torch.clamp((x - self.obs_mean) / self.obs_std, -OBS_CLIP, OBS_CLIP)

    def normalize_action(self, a: torch.Tensor) -> torch.Tensor:
        return (a - self.action_shift) / self.action_scale

    def unnormalize_action(self, a: torch.Tensor) -> torch.Tensor:
        return a * self.action_scale + self.action_shift

    def loss(
        self, obs: torch.Tensor, actions: torch.Tensor, generator: torch.Generator | None = None
    ) -> torch.Tensor:
        """Mean squared error of the predicted noise (DDPM's simple loss). ``obs``:
        (B, obs_horizon, input_dim) raw inputs; ``actions``: (B, pred_horizon, action_dim)
        raw actions."""
        x0 = self.normalize_action(actions)
        cond = self.encoder(self.normalize_obs(obs).flatten(1))
        # drawn from the (CPU) generator and moved: the same stream on any device
        noise = torch.randn(x0.shape, generator=generator).to(x0.device)
        t = torch.randint(0, self.config.train_steps, (len(x0),), generator=generator)
        t = t.to(x0.device)
        ab = self.alpha_bar[t].view(-1, 1, 1)
        noisy = ab.sqrt() * x0 + (1 - ab).sqrt() * noise
        return nn.functional.mse_loss(self.net(noisy, t, cond), noise)

    @torch.no_grad()
    def sample(
        self,
        obs: torch.Tensor,
        generator: torch.Generator | None = None,
        steps: int | None = None,
        noise_scale: float = 1.0,
    ) -> torch.Tensor:
        """(B, pred_horizon, action_dim) raw actions for ``obs`` (B, obs_horizon, input_dim),
        by deterministic DDIM (eta 0) over ``steps`` (default ``config.inference_steps``)
        diffusion steps (:func:`ddim_times`); the clean estimate is clipped to the dataset's
        range each step. ``noise_scale`` scales the initial noise (1: a sample of the learned
        distribution; below 1 draws nearer its high-density actions, 0 the same chunk for the
        same observations)."""
        steps = self.config.inference_steps if steps is None else int(steps)
        cond = self.encoder(self.normalize_obs(obs).flatten(1))
        n = len(cond)
        x = torch.randn((n, self.config.pred_horizon, self.action_dim), generator=generator)
        x = x * noise_scale
        times = ddim_times(self.config.train_steps, steps)
        for i, t in enumerate(times):
            ab = self.alpha_bar[t]
            eps = self.net(x, torch.full((n,), t, dtype=torch.long), cond)
            x0 = torch.clamp((x - (1 - ab).sqrt() * eps) / ab.sqrt(), self.clip_low, self.clip_high)
            eps = (x - ab.sqrt() * x0) / (1 - ab).sqrt()
            ab_prev = self.alpha_bar[times[i + 1]] if i + 1 < len(times) else torch.tensor(1.0)
            x = ab_prev.sqrt() * x0 + (1 - ab_prev).sqrt() * eps
        return self.unnormalize_action(x)


class EMA:
    """Exponential moving average of a model's weights, with the warm-up of Chi et al.:
    decay ``min(max_decay, 1 - (1 + step) ** -power)``, so early weights are forgotten fast."""

    def __init__(self, model: nn.Module, power: float = 0.75, max_decay: float = 0.9999) -> None:
        self.model = copy.deepcopy(model).eval()
        for p in self.model.parameters():
            p.requires_grad_(False)
        self.power, self.max_decay, self.step = power, max_decay, 0

    @torch.no_grad()
    def update(self, model: nn.Module) -> None:
        decay = min(self.max_decay, 1 - (1 + self.step) ** -self.power)
        mine = list(self.model.parameters())
        torch._foreach_mul_(mine, decay)
        torch._foreach_add_(mine, [p.detach() for p in model.parameters()], alpha=1 - decay)
        for buffer, theirs in zip(self.model.buffers(), model.buffers(), strict=True):
            buffer.copy_(theirs)
        self.step += 1

    def state_dict(self) -> dict:
        return {"model": self.model.state_dict(), "step": self.step}

    def load_state_dict(self, state: dict) -> None:
        self.model.load_state_dict(state["model"])
        self.step = int(state["step"])
