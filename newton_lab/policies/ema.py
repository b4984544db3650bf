"""Exponential moving average of model weights with the Diffusion Policy / robomimic power warm-up."""

from __future__ import annotations

import copy

import torch
from torch import nn


class EMA(nn.Module):
    """``averaged`` tracks ``model``: decay_k = 1 - (1 + k) ** -power, k = max(0, updates - 1), capped at
    ``max_decay`` (the first two updates copy the weights, so early checkpoints are not stuck at init)."""

    def __init__(self, model: nn.Module, *, power: float = 0.75, max_decay: float = 0.9999) -> None:
        super().__init__()
        self.averaged = copy.deepcopy(model).requires_grad_(False).eval()
        self.power, self.max_decay = power, max_decay
        self.num_updates = 0

    def decay(self) -> float:
        k = max(0, self.num_updates - 1)
        return 0.0 if k == 0 else min(self.max_decay, 1.0 - (1.0 + k) ** -self.power)

    def next_weight(self) -> float:
        """Blend weight (1 - decay) of the next update, counting that update."""
        weight = 1.0 - self.decay()
        self.num_updates += 1
        return weight

    @torch.no_grad()
    def update(self, model: nn.Module) -> None:
        self.blend(model, self.next_weight())

    @torch.no_grad()
    def blend(self, model: nn.Module, weight: float | torch.Tensor) -> None:
        """``averaged += weight * (model - averaged)``, in fused multi-tensor kernels (a launch per parameter
        would dominate on a GPU). ``weight`` may be a device tensor: then no host value is read, so a CUDA
        graph can capture the update and the weight is written before each replay."""
        avg = list(self.averaged.parameters())
        delta = torch._foreach_sub([p.detach() for p in model.parameters()], avg)
        torch._foreach_mul_(delta, weight)
        torch._foreach_add_(avg, delta)
        for a, new in zip(self.averaged.buffers(), model.buffers()):
            a.copy_(new)
