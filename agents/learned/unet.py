"""The noise-prediction network of the diffusion policy: a 1-D temporal U-Net with FiLM
conditioning (the architecture of Chi et al., Diffusion Policy, 2023).

The action chunk ``(B, horizon, action_dim)`` is treated as a 1-D signal with ``action_dim``
channels. Every residual block is conditioned on the diffusion step (a sinusoidal embedding)
and the observation features: a linear layer of that condition gives a per-channel scale
and bias (FiLM). The horizon halves at each level but the last, so it must be divisible by
``2 ** (len(channels) - 1)``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
from torch import nn


class SinusoidalStepEmbedding(nn.Module):
    """Diffusion step ``(B,)`` to ``(B, dim)`` sines and cosines of geometric frequencies."""

    def __init__(self, dim: int) -> None:
        super().__init__()
        if dim % 2:
            raise ValueError(f"the step embedding size must be even, got {dim}")
        self.dim = dim

    def forward(self, step: torch.Tensor) -> torch.Tensor:
        half = self.dim // 2
        freq = torch.exp(
            torch.arange(half, device=step.device, dtype=torch.float32)
            * (-math.log(10_000.0) / max(half - 1, 1))
        )
        angle = step.float()[:, None] * freq[None, :]
        return torch.cat([angle.sin(), angle.cos()], dim=-1)


class ConvBlock(nn.Module):
    """Conv1d, GroupNorm, Mish."""

    def __init__(self, cin: int, cout: int, kernel: int, groups: int) -> None:
        super().__init__()
        self.block = nn.Sequential(
            nn.Conv1d(cin, cout, kernel, padding=kernel // 2),
            nn.GroupNorm(groups, cout),
            nn.Mish(),
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.block(x)


class FiLMResBlock(nn.Module):
    """Two conv blocks; the condition scales and shifts the first one's output per channel."""

    def __init__(self, cin: int, cout: int, cond_dim: int, kernel: int, groups: int) -> None:
        super().__init__()
        self.conv1 = ConvBlock(cin, cout, kernel, groups)
        self.conv2 = ConvBlock(cout, cout, kernel, groups)
        self.film = nn.Sequential(nn.Mish(), nn.Linear(cond_dim, 2 * cout))
        self.skip = nn.Conv1d(cin, cout, 1) if cin != cout else nn.Identity()

    def forward(self, x: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        scale, bias = self.film(cond).unsqueeze(-1).chunk(2, dim=1)
        out = self.conv1(x) * scale + bias
        return self.conv2(out) + self.skip(x)


class ConditionalUnet1D(nn.Module):
    """Predicts the noise in a noisy action chunk, given the step and the observation.

    Args:
        action_dim: channels of the signal (the action size).
        cond_dim: size of the observation condition (flattened history of policy inputs).
        channels: the U-Net's widths, top to bottom (Chi et al.: 256/512/1024; ManiSkill's
            state baseline: 64/128/256).
        step_embed_dim: size of the diffusion-step embedding.
        kernel, groups: convolution kernel size and GroupNorm groups.
    """

    def __init__(
        self,
        action_dim: int,
        cond_dim: int,
        channels: Sequence[int] = (64, 128, 256),
        step_embed_dim: int = 64,
        kernel: int = 5,
        groups: int = 8,
    ) -> None:
        super().__init__()
        channels = list(channels)
        self.step_embed = nn.Sequential(
            SinusoidalStepEmbedding(step_embed_dim),
            nn.Linear(step_embed_dim, 4 * step_embed_dim),
            nn.Mish(),
            nn.Linear(4 * step_embed_dim, step_embed_dim),
        )
        c = step_embed_dim + cond_dim
        widths = [action_dim, *channels]
        self.down = nn.ModuleList()
        for i, (cin, cout) in enumerate(zip(widths[:-1], widths[1:], strict=True)):
            last = i == len(channels) - 1
            self.down.append(
                nn.ModuleList(
                    [
                        FiLMResBlock(cin, cout, c, kernel, groups),
                        FiLMResBlock(cout, cout, c, kernel, groups),
                        nn.Identity() if last else nn.Conv1d(cout, cout, 3, stride=2, padding=1),
                    ]
                )
            )
        mid = channels[-1]
        self.mid = nn.ModuleList(
            [FiLMResBlock(mid, mid, c, kernel, groups), FiLMResBlock(mid, mid, c, kernel, groups)]
        )
        self.up = nn.ModuleList()
        # As in Chi et al.'s U-Net, every up level doubles the horizon and the top level's
        # skip connection goes unused.
        for cout, cin in reversed(list(zip(channels[:-1], channels[1:], strict=True))):
            self.up.append(
                nn.ModuleList(
                    [
                        FiLMResBlock(2 * cin, cout, c, kernel, groups),
                        FiLMResBlock(cout, cout, c, kernel, groups),
                        nn.ConvTranspose1d(cout, cout, 4, 2, 1),
                    ]
                )
            )
        self.final = nn.Sequential(
            ConvBlock(channels[0], channels[0], kernel, groups),
            nn.Conv1d(channels[0], action_dim, 1),
        )

    def forward(self, x: torch.Tensor, step: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        """``x``: (B, horizon, action_dim) noisy actions; ``step``: (B,) diffusion steps;
        ``cond``: (B, cond_dim). Returns the predicted noise, shaped like ``x``."""
        h = x.transpose(1, 2)
        c = torch.cat([self.step_embed(step), cond], dim=-1)
        skips = []
        for block1, block2, down in self.down:
            h = block2(block1(h, c), c)
            skips.append(h)
            h = down(h)
        for block in self.mid:
            h = block(h, c)
        for block1, block2, up in self.up:
            h = torch.cat([h, skips.pop()], dim=1)
            h = up(block2(block1(h, c), c))
        return self.final(h).transpose(1, 2)
