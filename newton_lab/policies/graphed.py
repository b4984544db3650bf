"""A diffusion policy's action sampling replayed from CUDA graphs, for agents that plan every few env steps.

Why: evaluating PickToShelf's two phase policies on one H200 (100 rows, two 96x72 views) spent 24.5 ms of policy
time per env step against 3.9 ms for the env step itself (``evaluate``'s ``timing``). One ``sample_actions`` call
(the image encoders, 5 DDIM passes of the U-Net, the unnormaliser) is a few hundred small kernels launched from
Python, and rows whose episodes started at different steps re-plan at different steps, so a call is made on most
steps for a few rows. A graph replays those launches in one call.

Rows are padded up to a bucket (a power of two, at most the agent's rows) and each bucket is captured once, on its
first use; the padding rows' noise is zero and their actions are dropped. The caller draws the initial noise for the
rows it asks for, as ``DiffusionPolicy.predict_action`` does, so the random stream is the eager path's. Off CUDA, or
when a capture fails (one warning, then eager for good), the sampler calls ``sample_actions`` eagerly.
``torch.cuda.graphs``'s ``make_graphed_callables`` is for training (it records autograd); inference needs only
``torch.cuda.CUDAGraph``, used here as PyTorch's CUDA-graph notes describe.
"""

from __future__ import annotations

import warnings
from typing import Any

import torch


def bucket(rows: int, most: int) -> int:
    """The batch a call of ``rows`` rows runs at: the next power of two, never above ``most``."""
    return min(1 << max(rows - 1, 0).bit_length(), most)


class GraphedSampler:
    """``policy.sample_actions`` (obs, images, noise) -> actions, from one CUDA graph per bucket of at most ``rows``
    rows. ``static`` runs the padded path without graphs (what a test checks on the CPU)."""

    def __init__(self, policy, rows: int, *, enabled: bool = True, static: bool = False) -> None:
        self.policy, self.rows = policy, rows
        self.graphs = enabled and torch.device(policy.device).type == "cuda"
        self.static = static or self.graphs
        self._buckets: dict[int, dict[str, Any]] = {}

    def __call__(self, obs: torch.Tensor, images: dict[str, torch.Tensor] | None, noise: torch.Tensor) -> torch.Tensor:
        if not self.static:
            return self.policy.sample_actions(obs, images, noise)
        n = obs.shape[0]
        size = bucket(n, max(self.rows, n))
        entry = self._buckets.get(size) or self._build(size, obs, images, noise)
        if entry is None:  # the capture failed: eager from now on
            return self.policy.sample_actions(obs, images, noise)
        entry["obs"][:n].copy_(obs)
        entry["noise"][:n].copy_(noise)
        for key, frames in (images or {}).items():
            entry["images"][key][:n].copy_(frames)
        if self.graphs:
            entry["graph"].replay()
        else:
            entry["out"] = self.policy.sample_actions(entry["obs"], entry["images"] or None, entry["noise"])
        return entry["out"][:n].clone()  # the next replay writes the same memory

    def _build(self, size: int, obs, images, noise) -> dict[str, Any] | None:
        """The bucket's static inputs (zeros: padding rows stay finite) and, with graphs, its captured call."""
        device = torch.device(self.policy.device)

        def static(x: torch.Tensor) -> torch.Tensor:
            return torch.zeros((size, *x.shape[1:]), dtype=x.dtype, device=device)

        entry: dict[str, Any] = {
            "obs": static(obs.to(device, torch.float32)),
            "noise": static(noise),
            "images": {k: static(v) for k, v in (images or {}).items()},
        }
        if self.graphs:
            try:
                entry["graph"], entry["out"] = self._capture(entry)
            except RuntimeError as exc:
                warnings.warn(f"policy sampling runs eagerly: its CUDA graph capture failed ({exc})", stacklevel=3)
                self.graphs = self.static = False
                return None
        self._buckets[size] = entry
        return entry

    def _capture(self, entry: dict[str, Any]) -> tuple[torch.cuda.CUDAGraph, torch.Tensor]:
        def call() -> torch.Tensor:
            return self.policy.sample_actions(entry["obs"], entry["images"] or None, entry["noise"])

        side = torch.cuda.Stream()
        side.wait_stream(torch.cuda.current_stream())
        with torch.cuda.stream(side), torch.no_grad():  # warm-up off the default stream: cuDNN picks its kernels
            for _ in range(2):
                call()
        torch.cuda.current_stream().wait_stream(side)
        graph = torch.cuda.CUDAGraph()
        # thread_local: a Warp or writer thread's CUDA calls meanwhile do not void this capture
        with torch.cuda.graph(graph, capture_error_mode="thread_local"), torch.no_grad():
            out = call()
        return graph, out
