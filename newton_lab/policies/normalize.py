"""Per-dimension min-max normalisation to [-1, 1] (actions must lie there because sampling clips to it)."""

from __future__ import annotations

from typing import Any

import torch

CONSTANT_RANGE = 1e-6  # a dimension whose range is below this is constant: it maps to 0 and back to its value


class MinMaxNormalizer:
    """``normalize``: [low, high] -> [-1, 1] per dimension; ``unnormalize`` is its exact inverse on constant dims."""

    def __init__(self, low: torch.Tensor, high: torch.Tensor) -> None:
        low, high = torch.as_tensor(low, dtype=torch.float32), torch.as_tensor(high, dtype=torch.float32)
        if low.ndim != 1 or low.shape != high.shape:
            raise ValueError(f"low/high must be 1-D of equal length, got {tuple(low.shape)} and {tuple(high.shape)}")
        if not bool(torch.isfinite(low).all() and torch.isfinite(high).all() and (high >= low).all()):
            raise ValueError("normaliser stats must be finite with high >= low")
        self.low, self.high = low, high
        self.constant = (high - low) < CONSTANT_RANGE
        self.scale = torch.where(self.constant, torch.ones_like(low), high - low)
        self._on_device: dict[tuple[torch.device, torch.dtype], tuple[torch.Tensor, ...]] = {}

    @classmethod
    def fit(cls, data: torch.Tensor, *, min_range: float = 0.0) -> MinMaxNormalizer:
        """Stats over every row of ``data`` (N, D). ``min_range`` > 0 widens each dimension's window to at least
        that width, centred on its data, so that a dimension which barely moved in the data (a leg that settled
        to within 0.1 mm, a base that stopped within 0.4 mm) does not turn the same sub-millimetre deviation at
        inference into a value far outside [-1, 1]."""
        data = torch.as_tensor(data, dtype=torch.float32).reshape(-1, data.shape[-1])
        if data.shape[0] == 0:
            raise ValueError("cannot fit a normaliser on zero samples")
        low, high = data.amin(dim=0), data.amax(dim=0)
        if min_range > 0:
            centre, half = (low + high) / 2, torch.clamp((high - low) / 2, min=min_range / 2)
            low, high = centre - half, centre + half
        return cls(low, high)

    @property
    def dim(self) -> int:
        return self.low.shape[0]

    def _stats(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        if x.shape[-1] != self.dim:
            raise ValueError(f"last dimension {x.shape[-1]} does not match the normaliser's {self.dim}")
        key = (x.device, x.dtype)  # cached: no host-to-device copy per call (and a CUDA graph can capture it)
        if key not in self._on_device:
            self._on_device[key] = (
                self.low.to(x.device, x.dtype),
                self.scale.to(x.device, x.dtype),
                self.constant.to(x.device),
            )
        return self._on_device[key]

    def normalize(self, x: torch.Tensor) -> torch.Tensor:
        low, scale, const = self._stats(x)
        return torch.where(const, torch.zeros_like(x), (x - low) / scale * 2 - 1)

    def unnormalize(self, y: torch.Tensor) -> torch.Tensor:
        low, scale, const = self._stats(y)
        return torch.where(const, low.expand_as(y), (y + 1) / 2 * scale + low)

    def state_dict(self) -> dict[str, Any]:
        return {"low": self.low.clone(), "high": self.high.clone()}

    @classmethod
    def from_state_dict(cls, state: dict[str, Any]) -> MinMaxNormalizer:
        return cls(state["low"], state["high"])
