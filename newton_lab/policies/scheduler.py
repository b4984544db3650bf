"""DDPM training noise schedule and DDIM sampling for epsilon-prediction diffusion policies.

Written here instead of depending on ``diffusers``: that is a heavy extra dependency (and its
transitive pins) for about 60 lines of maths, and owning the maths keeps checkpoints independent of
another library's scheduler config format.

Conventions: ``alphas_cumprod[t]`` is the signal fraction after ``t + 1`` noising steps
(``t = 0 .. T-1``); samples live in [-1, 1] (``clip_sample``), so actions are min-max normalised.
The network predicts the noise (``"epsilon"``) or the clean sample (``"sample"``, x0); DDIM takes either.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import torch

PREDICTION_TYPES = ("epsilon", "sample")
"""What the denoising network outputs: the added noise, or the clean sample x0."""


def squaredcos_cap_v2(num_steps: int, max_beta: float = 0.999) -> torch.Tensor:
    """Cosine schedule (Nichol & Dhariwal 2021): betas from alpha_bar(s) = cos^2((s + 0.008) / 1.008 * pi / 2)."""

    def alpha_bar(s: float) -> float:
        return math.cos((s + 0.008) / 1.008 * math.pi / 2) ** 2

    betas = [min(1 - alpha_bar((i + 1) / num_steps) / alpha_bar(i / num_steps), max_beta) for i in range(num_steps)]
    return torch.tensor(betas, dtype=torch.float64)


class NoiseScheduler:
    """DDPM forward process (``add_noise``) plus deterministic/stochastic DDIM reverse sampling."""

    def __init__(self, num_train_timesteps: int = 100, *, clip_sample: bool = True) -> None:
        if num_train_timesteps < 1:
            raise ValueError(f"num_train_timesteps must be >= 1, got {num_train_timesteps}")
        self.num_train_timesteps = num_train_timesteps
        self.clip_sample = clip_sample
        self.betas = squaredcos_cap_v2(num_train_timesteps)
        self.alphas_cumprod = torch.cumprod(1.0 - self.betas, dim=0)  # float64, strictly decreasing
        self._tables: dict[tuple[torch.device, torch.dtype], torch.Tensor] = {}

    def _abar(self, t: torch.Tensor, like: torch.Tensor) -> torch.Tensor:
        """alpha_bar at integer steps ``t`` (negative = clean, alpha_bar 1), shaped to broadcast over ``like``."""
        t = torch.as_tensor(t, device=like.device).long()
        table = self._table(like)  # indexed where ``t`` lives: no device round trip (a sync per training step)
        # index_select, not table[t]: a 0-d index tensor is read on the host (a sync that voids a CUDA graph capture)
        picked = table.index_select(0, t.clamp(min=0).reshape(-1)).reshape(t.shape)
        a = torch.where(t >= 0, picked, torch.ones((), dtype=like.dtype, device=like.device))
        return a.reshape(a.shape + (1,) * (like.ndim - a.ndim))

    def _table(self, like: torch.Tensor) -> torch.Tensor:
        """``alphas_cumprod`` in ``like``'s device and dtype (cached)."""
        key = (like.device, like.dtype)
        if key not in self._tables:
            self._tables[key] = self.alphas_cumprod.to(device=like.device, dtype=like.dtype)
        return self._tables[key]

    def sample_timesteps(
        self, batch: int, device: torch.device | str = "cpu", generator: torch.Generator | None = None
    ) -> torch.Tensor:
        """Uniform training timesteps (batch,) in [0, T)."""
        return torch.randint(0, self.num_train_timesteps, (batch,), device=device, generator=generator)

    def add_noise(self, x0: torch.Tensor, noise: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
        """q(x_t | x_0): sqrt(abar_t) x0 + sqrt(1 - abar_t) noise; ``t`` is (B,) or a scalar."""
        a = self._abar(t, x0)
        return a.sqrt() * x0 + (1 - a).sqrt() * noise

    def ddim_timesteps(self, num_inference_steps: int) -> list[int]:
        """Descending DDIM steps, "trailing" spacing: starts at T-1 (pure noise), e.g. 99, 89, ..., 9 for 10/100."""
        if not 1 <= num_inference_steps <= self.num_train_timesteps:
            raise ValueError(f"num_inference_steps must be in 1..{self.num_train_timesteps}, got {num_inference_steps}")
        ratio = self.num_train_timesteps / num_inference_steps
        return [int(round(self.num_train_timesteps - i * ratio)) - 1 for i in range(num_inference_steps)]

    def ddim_step(
        self,
        eps: torch.Tensor,
        t: int,
        t_prev: int,
        x_t: torch.Tensor,
        *,
        eta: float = 0.0,
        generator: torch.Generator | None = None,
        prediction_type: str = "epsilon",
    ) -> torch.Tensor:
        """One DDIM update x_t -> x_{t_prev} (``t_prev < 0`` means the clean sample); ``eps`` is the model
        output: the noise, or with ``prediction_type="sample"`` the clean sample x0."""
        # steps filled on x_t's device, not copied from the host: a CUDA graph can capture the sampling loop
        a_t, a_prev = (self._abar(torch.full((), s, dtype=torch.long, device=x_t.device), x_t) for s in (t, t_prev))
        if prediction_type == "sample":  # direction term from the (clipped) predicted x0
            x0 = eps.clamp(-1.0, 1.0) if self.clip_sample else eps
            eps = (x_t - a_t.sqrt() * x0) / (1 - a_t).sqrt()
        elif prediction_type == "epsilon":
            x0 = (x_t - (1 - a_t).sqrt() * eps) / a_t.sqrt()
            if self.clip_sample:
                # The model's eps stays the direction term: re-deriving it from the clipped x0 sampled worse in tests.
                x0 = x0.clamp(-1.0, 1.0)
        else:
            raise ValueError(f"prediction_type must be one of {PREDICTION_TYPES}, got {prediction_type!r}")
        sigma = eta * ((1 - a_prev) / (1 - a_t) * (1 - a_t / a_prev)).sqrt()
        x_prev = a_prev.sqrt() * x0 + (1 - a_prev - sigma**2).clamp(min=0).sqrt() * eps
        if eta > 0:
            x_prev = x_prev + sigma * torch.randn(x_t.shape, generator=generator, device=x_t.device, dtype=x_t.dtype)
        return x_prev

    def sample(
        self,
        denoise: Callable[[torch.Tensor, torch.Tensor], torch.Tensor],
        x_T: torch.Tensor,
        *,
        num_inference_steps: int = 10,
        eta: float = 0.0,
        generator: torch.Generator | None = None,
        prediction_type: str = "epsilon",
    ) -> torch.Tensor:
        """DDIM from ``x_T`` (usually N(0, I)); ``denoise(x_t, t (B,))`` -> eps (or x0 for ``"sample"``).
        Returns x_0."""
        steps = self.ddim_timesteps(num_inference_steps)
        x = x_T
        for t, t_prev in zip(steps, steps[1:] + [-1]):
            tt = torch.full((x.shape[0],), t, dtype=torch.long, device=x.device)
            x = self.ddim_step(
                denoise(x, tt), t, t_prev, x, eta=eta, generator=generator, prediction_type=prediction_type
            )
        return x
