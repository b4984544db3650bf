"""One optimiser step of diffusion-policy training, run eagerly or replayed from a captured CUDA graph.

A step is: gather a batch of sequence windows, noise it, predict the noise, back-propagate, AdamW, EMA.
On a GPU the state-based U-Net runs about a thousand small kernels per step and the eager step is bound by
their launches (34 steps/s at batch 1024 on an H100), so on CUDA the whole step is captured once with
``torch.cuda.graph`` and replayed (60 steps/s, ``newton-lab bench-train``): the windows live on the GPU, the batch's
indices, the learning rate and the EMA weight are device tensors written before each replay, and the diffusion noise
comes from the graph-safe CUDA generator.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import torch
from torch.utils.data import BatchSampler, DataLoader, RandomSampler

from .data import SequenceDataset, collate_batch
from .data_parallel import average_gradients, world
from .diffusion import DiffusionPolicy, DiffusionPolicyConfig

WARMUP_STEPS_BEFORE_CAPTURE = 3
"""Eager steps on a side stream before capture: AdamW creates its state, cuDNN/cuBLAS pick their kernels."""


def steps_per_epoch(data: SequenceDataset, batch_size: int) -> int:
    """Optimiser steps per epoch: every window once; a dataset smaller than one batch fills one batch."""
    return max(len(data), batch_size) // batch_size


def set_lr(optimizer: torch.optim.Optimizer, lr: float) -> None:
    """Write the learning rate in place (a device tensor for a captured step, else a float)."""
    for group in optimizer.param_groups:
        if isinstance(group["lr"], torch.Tensor):
            group["lr"].fill_(lr)
        else:
            group["lr"] = lr


def load_optimizer_state(optimizer: torch.optim.Optimizer, state: dict[str, Any]) -> None:
    """``optimizer.load_state_dict`` that keeps the optimizer's own learning-rate objects (a captured step's
    device tensors); the caller sets the rate of the next step."""
    lrs = [group["lr"] for group in optimizer.param_groups]
    optimizer.load_state_dict(state)
    for group, lr in zip(optimizer.param_groups, lrs):
        group["lr"] = lr


class ResumableOrder:
    """Data-order state of a step: the batch-order generator's state at the start of the running epoch and the
    steps taken in it. ``load_state_dict`` makes the next ``epoch()`` rewind to that epoch, pass over the steps
    already taken, then call ``then`` (which restores the global RNGs: the DataLoader draws from them when an
    epoch starts) before the first new step."""

    generator: torch.Generator

    def _init_order(self) -> None:
        self.epoch_start: torch.Tensor | None = None
        self.position = 0
        self._pending: tuple[dict[str, Any], Callable[[], None] | None] | None = None

    def state_dict(self) -> dict[str, Any]:
        return {"kind": type(self).__name__, "generator": self.epoch_start, "position": self.position}

    def load_state_dict(self, state: dict[str, Any], then: Callable[[], None] | None = None) -> None:
        if state.get("kind") != type(self).__name__:
            raise ValueError(
                f"the interrupted run used the {state.get('kind')} step, this one the "
                f"{type(self).__name__}; resume on the same kind of device with the same cuda_graph "
                "setting"
            )
        self._pending = (state, then)

    def _begin_epoch(self) -> int:
        """Remember the generator state at the epoch start (or rewind to a resumed one); the steps to pass over."""
        if self._pending is None:
            self.epoch_start, self.position = self.generator.get_state(), 0
            return 0
        state = self._pending[0]
        self.generator.set_state(state["generator"])
        self.epoch_start, self.position = state["generator"].clone(), state["position"]
        return self.position

    def _resumed(self) -> None:
        if self._pending is not None:
            then, self._pending = self._pending[1], None
            if then is not None:
                then()


class EagerTrainStep(ResumableOrder):
    """Batches from a torch DataLoader over the in-memory windows; one Python-driven step per call."""

    def __init__(self, policy: DiffusionPolicy, data: SequenceDataset, cfg: DiffusionPolicyConfig) -> None:
        self.policy = policy
        self._init_order()
        fused = {"fused": True} if policy.device.type in ("cuda", "cpu") else {}  # one kernel for all tensors
        if cfg.compile:
            policy.compile_for_training()
        self.optimizer = torch.optim.AdamW(
            policy.model.parameters(), lr=cfg.lr, betas=cfg.betas, weight_decay=cfg.weight_decay, **fused
        )
        # An epoch visits every window once in random order; a dataset smaller than one batch is repeated (fresh
        # permutations) up to batch_size windows, so every step sees batch_size differently-noised windows.
        # Data-parallel: every rank walks the same order in global batches of batch_size * processes windows
        # and keeps its own slice of each.
        self.generator = torch.Generator().manual_seed(cfg.seed)
        rank, size = world()
        sampler = RandomSampler(data, num_samples=max(len(data), cfg.batch_size * size), generator=self.generator)
        batches = RankSlice(BatchSampler(sampler, cfg.batch_size * size, drop_last=True), rank, cfg.batch_size)
        self.loader = DataLoader(
            data,
            batch_sampler=batches,
            num_workers=cfg.num_workers,
            collate_fn=collate_batch,
            persistent_workers=cfg.num_workers > 0,
        )

    def epoch(self) -> Iterator[torch.Tensor]:
        """Run the epoch's steps, yielding each step's (device, detached) loss."""
        policy, optimizer = self.policy, self.optimizer
        skip = self._begin_epoch()
        batches = iter(self.loader)
        for _ in range(skip):  # a resumed epoch: the batches the interrupted run trained on are drawn, not used
            next(batches)
        self._resumed()
        for batch in batches:
            loss = policy.compute_loss(batch)
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            average_gradients(policy.model.parameters())
            optimizer.step()
            policy.ema.update(policy.model)
            self.position += 1
            yield loss.detach()


class CudaGraphTrainStep(ResumableOrder):
    """The same step with windows on the GPU, captured on the 4th call and replayed from then on (a resumed run
    loads its weights, optimizer and RNG states before its first call, so before the capture)."""

    def __init__(self, policy: DiffusionPolicy, data: SequenceDataset, cfg: DiffusionPolicyConfig) -> None:
        device = policy.device
        self._init_order()
        self.policy, self.batch_size = policy, cfg.batch_size
        if cfg.compile:  # compiled during the warm-up steps; the capture records its fused kernels
            policy.compile_for_training()
        self.optimizer = torch.optim.AdamW(
            policy.model.parameters(),
            lr=torch.tensor(cfg.lr, device=device),
            betas=cfg.betas,
            weight_decay=cfg.weight_decay,
            fused=True,
            capturable=True,
        )
        self.windows = data.windows(device)  # uint8 frames: the whole set on the GPU
        self.rank, self.processes = world()
        self.num_windows, self.steps = len(data), steps_per_epoch(data, cfg.batch_size * self.processes)
        self.generator = torch.Generator(device=device).manual_seed(cfg.seed)  # batch order
        self.index = torch.zeros(cfg.batch_size, dtype=torch.long, device=device)
        self.ema_weight = torch.zeros((), device=device)
        self.calls, self.graph, self.loss = 0, None, None

    def _body(self) -> torch.Tensor:
        loss = self.policy.compute_loss(self.windows.batch(self.index))
        loss.backward()
        average_gradients(self.policy.model.parameters())  # an NCCL all-reduce, captured with the rest
        self.optimizer.step()
        self.policy.ema.blend(self.policy.model, self.ema_weight)
        return loss.detach()

    def _run(self) -> torch.Tensor:
        self.ema_weight.fill_(self.policy.ema.next_weight())
        self.calls += 1
        if self.graph is not None:
            self.graph.replay()
            return self.loss.clone()
        if self.calls <= WARMUP_STEPS_BEFORE_CAPTURE:
            side = torch.cuda.Stream(self.index.device)
            side.wait_stream(torch.cuda.current_stream())
            with torch.cuda.stream(side):
                self.optimizer.zero_grad(set_to_none=True)
                loss = self._body()
            torch.cuda.current_stream().wait_stream(side)
            return loss
        # Gradients unset before capture: backward allocates them in the graph's pool and writes (not adds) them.
        self.optimizer.zero_grad(set_to_none=True)
        self.graph = torch.cuda.CUDAGraph()
        with torch.cuda.graph(self.graph):
            self.loss = self._body()
        self.graph.replay()  # capturing records the step without running it
        return self.loss.clone()

    def epoch(self) -> Iterator[torch.Tensor]:
        n, b, size = self.num_windows, self.batch_size, self.processes
        reps = -(-max(n, b * size) // n)
        skip = self._begin_epoch()
        order = torch.cat([torch.randperm(n, device=self.index.device, generator=self.generator) for _ in range(reps)])
        self._resumed()
        for k in range(skip, self.steps):
            first = (k * size + self.rank) * b  # this rank's slice of the k-th global batch
            self.index.copy_(order[first : first + b])
            self.position = k + 1
            yield self._run()


class RankSlice:
    """Batches of indices: this rank's ``batch_size`` consecutive indices of each global batch."""

    def __init__(self, batches: BatchSampler, rank: int, batch_size: int) -> None:
        self.batches, self.rank, self.batch_size = batches, rank, batch_size

    def __iter__(self) -> Iterator[list[int]]:
        first = self.rank * self.batch_size
        for batch in self.batches:
            yield batch[first : first + self.batch_size]

    def __len__(self) -> int:
        return len(self.batches)


def make_train_step(
    policy: DiffusionPolicy, data: SequenceDataset, cfg: DiffusionPolicyConfig
) -> EagerTrainStep | CudaGraphTrainStep:
    """The captured step on CUDA (unless ``cfg.cuda_graph`` is off), the eager one elsewhere."""
    if policy.device.type == "cuda" and cfg.cuda_graph:
        return CudaGraphTrainStep(policy, data, cfg)
    return EagerTrainStep(policy, data, cfg)
