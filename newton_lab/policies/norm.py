"""GroupNorm that can stay in the autocast dtype.

CUDA autocast runs every ``group_norm`` in float32 (PyTorch's autocast op table), so under bf16 each norm of the
image encoders and the U-Net casts its bf16 input up, normalises in float32 and hands float32 to the next
convolution, which casts it back down: two extra passes over every activation. With ``low_precision`` on, the
norm runs in the autocast dtype instead (the kernel still accumulates its statistics in float32), as timm's "fast
norm" does. Off, it is ``nn.GroupNorm``; the parameters and the state dict are the same either way.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn


class GroupNorm(nn.GroupNorm):
    """``nn.GroupNorm``; with ``low_precision`` set and autocast on, computed in the autocast dtype."""

    low_precision: bool = False

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        device = x.device.type
        if not (self.low_precision and torch.is_autocast_enabled(device)):
            return super().forward(x)
        dtype = torch.get_autocast_dtype(device)
        with torch.autocast(device, enabled=False):
            weight = None if self.weight is None else self.weight.to(dtype)
            bias = None if self.bias is None else self.bias.to(dtype)
            return F.group_norm(x.to(dtype), self.num_groups, weight, bias, self.eps)


def set_low_precision_norms(module: nn.Module, on: bool) -> None:
    """Turn ``low_precision`` on or off for every ``GroupNorm`` in ``module``."""
    for m in module.modules():
        if isinstance(m, GroupNorm):
            m.low_precision = on
