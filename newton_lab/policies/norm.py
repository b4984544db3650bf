"""GroupNorm that can stay in the autocast dtype, and is then fast on CUDA.

Precision: CUDA autocast runs every ``group_norm`` and ``layer_norm`` in float32 (PyTorch's autocast op table), so
under bf16 each norm casts its bf16 input up, normalises in float32 and hands float32 to the next convolution, which
casts it back down: two extra passes over every activation. With ``low_precision`` on, the norm runs in the autocast
dtype instead (the kernel still accumulates its statistics in float32), as timm's "fast norm" does. Off, it is
``nn.GroupNorm``; the parameters and the state dict are the same either way.

Speed: PyTorch's own ``group_norm`` kernels are slow for the image encoders' many small groups: on an H200 (two-view
vision preset, batch 2048, bf16 norms) they spent 66 ms of a 168 ms training step, against about 3 ms that reading and
writing the activations takes (``bench-train --profile``). So a low-precision norm on CUDA computes the same function
through the layer-norm kernels (each sample's groups as rows, each group's channels x pixels as the normalised axis,
then the per-channel affine): faster by more the larger the batch (``bench-train --bf16-norms --native-norms`` times
both; docs/benchmarks.md). A float32 norm keeps PyTorch's kernels: there the layer-norm route measured no faster.
``set_native_norms`` keeps a network on PyTorch's kernels throughout.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn


class GroupNorm(nn.GroupNorm):
    """``nn.GroupNorm``; with ``low_precision`` set and autocast on, computed in the autocast dtype (on CUDA through
    the layer-norm kernels unless ``native``)."""

    low_precision: bool = False
    native: bool = False
    """PyTorch's own group-norm kernels for the low-precision norm on CUDA too (the comparison's other side)."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        device = x.device.type
        if not (self.low_precision and torch.is_autocast_enabled(device)):
            return super().forward(x)
        dtype = torch.get_autocast_dtype(device)
        with torch.autocast(device, enabled=False):
            if x.is_cuda and not self.native:
                return group_norm_by_rows(x.to(dtype), self.num_groups, self.weight, self.bias, self.eps)
            weight = None if self.weight is None else self.weight.to(dtype)
            bias = None if self.bias is None else self.bias.to(dtype)
            return F.group_norm(x.to(dtype), self.num_groups, weight, bias, self.eps)


def group_norm_by_rows(
    x: torch.Tensor, groups: int, weight: torch.Tensor | None, bias: torch.Tensor | None, eps: float
) -> torch.Tensor:
    """``F.group_norm`` of (N, C, ...) ``x`` computed as a layer norm of its (N, groups, C / groups * ...) rows, then
    the per-channel affine (``weight``, ``bias`` cast to ``x``'s dtype)."""
    n, c = x.shape[:2]
    rows = x.reshape(n, groups, -1)
    y = F.layer_norm(rows, rows.shape[-1:], eps=eps).reshape(x.shape)
    if weight is None:
        return y
    shape = (1, c) + (1,) * (x.dim() - 2)
    w = weight.to(x.dtype).view(shape)
    return y * w if bias is None else torch.addcmul(bias.to(x.dtype).view(shape), y, w)


def set_low_precision_norms(module: nn.Module, on: bool) -> None:
    """Turn ``low_precision`` on or off for every ``GroupNorm`` in ``module``."""
    for m in module.modules():
        if isinstance(m, GroupNorm):
            m.low_precision = on


def set_native_norms(module: nn.Module, on: bool) -> None:
    """Run every low-precision ``GroupNorm`` in ``module`` through PyTorch's own group-norm kernels on CUDA too
    (``on``), or through the layer-norm kernels (off, the default)."""
    for m in module.modules():
        if isinstance(m, GroupNorm):
            m.native = on
