"""Conditional 1-D temporal U-Net (Diffusion Policy CNN backbone) with FiLM conditioning.

Input: a noisy action sequence (B, T, A); condition: diffusion step + a global vector (the flattened
observation history). Each level halves T, so T must be divisible by 2 ** (len(down_dims) - 1).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
from torch import nn

from .norm import GroupNorm


class SinusoidalStepEmbedding(nn.Module):
    """Transformer-style sin/cos embedding of the (integer) diffusion step."""

    def __init__(self, dim: int) -> None:
        super().__init__()
        if dim < 4 or dim % 2:
            raise ValueError(f"step embedding dim must be even and >= 4, got {dim}")
        half = dim // 2
        self.register_buffer("freqs", torch.exp(-math.log(10000.0) * torch.arange(half) / (half - 1)), persistent=False)

    def forward(self, t: torch.Tensor) -> torch.Tensor:
        angles = t.float()[:, None] * self.freqs[None, :]
        return torch.cat([angles.sin(), angles.cos()], dim=-1)


ACTIVATIONS: dict[str, type[nn.Module]] = {"mish": nn.Mish, "silu": nn.SiLU}
"""Activation of every block: Mish (Chi et al.) or SiLU (on 2 CPU cores PyTorch's Mish and its backward take ~20 %
of a training step of the quarter-width U-Net, SiLU about a quarter of that)."""


class ConvNormAct(nn.Sequential):
    """Conv1d (same padding) -> GroupNorm -> activation."""

    def __init__(self, c_in: int, c_out: int, kernel_size: int, n_groups: int, act: type[nn.Module] = nn.Mish) -> None:
        super().__init__(
            nn.Conv1d(c_in, c_out, kernel_size, padding=kernel_size // 2), GroupNorm(n_groups, c_out), act()
        )


class FiLMResBlock(nn.Module):
    """Two conv blocks; the condition sets a per-channel scale and bias between them; residual 1x1 conv."""

    def __init__(
        self, c_in: int, c_out: int, cond_dim: int, kernel_size: int, n_groups: int, act: type[nn.Module] = nn.Mish
    ) -> None:
        super().__init__()
        self.block1 = ConvNormAct(c_in, c_out, kernel_size, n_groups, act)
        self.block2 = ConvNormAct(c_out, c_out, kernel_size, n_groups, act)
        self.film = nn.Sequential(act(), nn.Linear(cond_dim, 2 * c_out))
        self.residual = nn.Conv1d(c_in, c_out, 1) if c_in != c_out else nn.Identity()

    def forward(self, x: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        scale, bias = self.film(cond).unsqueeze(-1).chunk(2, dim=1)
        h = self.block1(x) * (1 + scale) + bias
        return self.block2(h) + self.residual(x)


class ConditionalUnet1D(nn.Module):
    """Epsilon predictor ``forward(x (B, T, A), t (B,), global_cond (B, G)) -> (B, T, A)``."""

    def __init__(
        self,
        action_dim: int,
        global_cond_dim: int,
        *,
        down_dims: Sequence[int] = (64, 128, 256),
        diffusion_step_embed_dim: int = 128,
        kernel_size: int = 5,
        n_groups: int = 8,
        activation: str = "mish",
    ) -> None:
        super().__init__()
        if activation not in ACTIVATIONS:
            raise ValueError(f"unknown activation {activation!r}; valid: {', '.join(ACTIVATIONS)}")
        act = ACTIVATIONS[activation]
        dims = [int(d) for d in down_dims]
        if not dims or any(d % n_groups for d in dims):
            raise ValueError(f"down_dims {tuple(dims)} must be non-empty multiples of n_groups={n_groups}")
        if kernel_size % 2 == 0:
            raise ValueError(f"kernel_size must be odd, got {kernel_size}")
        self.num_downsamples = len(dims) - 1
        e = diffusion_step_embed_dim
        self.step_encoder = nn.Sequential(SinusoidalStepEmbedding(e), nn.Linear(e, 4 * e), act(), nn.Linear(4 * e, e))
        cond_dim = e + global_cond_dim

        def block(c_in: int, c_out: int) -> FiLMResBlock:
            return FiLMResBlock(c_in, c_out, cond_dim, kernel_size, n_groups, act)

        levels = list(zip([action_dim] + dims[:-1], dims))
        self.down = nn.ModuleList()
        for i, (c_in, c_out) in enumerate(levels):
            last = i == len(levels) - 1
            downsample = nn.Identity() if last else nn.Conv1d(c_out, c_out, 3, stride=2, padding=1)
            self.down.append(nn.ModuleList([block(c_in, c_out), block(c_out, c_out), downsample]))
        self.mid = nn.ModuleList([block(dims[-1], dims[-1]), block(dims[-1], dims[-1])])
        self.up = nn.ModuleList()
        for c_low, c_high in reversed(levels[1:]):  # upsample, then concat the skip of that resolution
            self.up.append(
                nn.ModuleList(
                    [
                        nn.ConvTranspose1d(c_high, c_high, 4, stride=2, padding=1),
                        block(c_high + c_low, c_low),
                        block(c_low, c_low),
                    ]
                )
            )
        self.head = nn.Sequential(
            ConvNormAct(dims[0], dims[0], kernel_size, n_groups, act), nn.Conv1d(dims[0], action_dim, 1)
        )

    def forward(self, x: torch.Tensor, t: torch.Tensor, global_cond: torch.Tensor) -> torch.Tensor:
        horizon = x.shape[1]
        if horizon % (2**self.num_downsamples):
            raise ValueError(f"horizon {horizon} must be divisible by 2**{self.num_downsamples} (len(down_dims) - 1)")
        t = torch.as_tensor(t, device=x.device).reshape(-1).expand(x.shape[0])
        cond = torch.cat([self.step_encoder(t), global_cond], dim=-1)
        h = x.transpose(1, 2)  # (B, A, T): channels = action dims
        skips = []
        for res1, res2, downsample in self.down:
            h = res2(res1(h, cond), cond)
            skips.append(h)
            h = downsample(h)
        for res in self.mid:
            h = res(h, cond)
        skips.pop()  # the deepest level feeds the mid blocks directly
        for upsample, res1, res2 in self.up:
            h = res2(res1(torch.cat([upsample(h), skips.pop()], dim=1), cond), cond)
        return self.head(h).transpose(1, 2)
