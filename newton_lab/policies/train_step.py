"""One optimiser step of diffusion-policy training, run eagerly or replayed from a captured CUDA graph.

A step is: gather a batch of sequence windows, noise it, predict the noise, back-propagate, AdamW, EMA.
On a GPU the state-based U-Net runs about a thousand small kernels per step and the eager step is bound by
their launches (34 steps/s at batch 1024 on an H100), so on CUDA the whole step is captured once with
``torch.cuda.graph`` and replayed (60 steps/s, ``newton-lab bench-train``): the windows live on the GPU, the batch's indices, the learning rate and the EMA weight are device
tensors written before each replay, and the diffusion noise comes from the graph-safe CUDA generator.
"""

from __future__ import annotations

from collections.abc import Iterator

import torch
from torch.utils.data import DataLoader, RandomSampler

from .data import SequenceDataset, collate_batch
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


class EagerTrainStep:
    """Batches from a torch DataLoader over the in-memory windows; one Python-driven step per call."""

    def __init__(self, policy: DiffusionPolicy, data: SequenceDataset, cfg: DiffusionPolicyConfig) -> None:
        self.policy = policy
        fused = {"fused": True} if policy.device.type == "cuda" else {}
        self.optimizer = torch.optim.AdamW(policy.model.parameters(), lr=cfg.lr, betas=cfg.betas,
                                           weight_decay=cfg.weight_decay, **fused)
        # An epoch visits every window once in random order; a dataset smaller than one batch is repeated (fresh
        # permutations) up to batch_size windows, so every step sees batch_size differently-noised windows.
        sampler = RandomSampler(data, num_samples=max(len(data), cfg.batch_size),
                                generator=torch.Generator().manual_seed(cfg.seed))
        self.loader = DataLoader(data, batch_size=cfg.batch_size, sampler=sampler, drop_last=True,
                                 num_workers=cfg.num_workers, collate_fn=collate_batch,
                                 persistent_workers=cfg.num_workers > 0)

    def epoch(self) -> Iterator[torch.Tensor]:
        """Run the epoch's steps, yielding each step's (device, detached) loss."""
        policy, optimizer = self.policy, self.optimizer
        for batch in self.loader:
            loss = policy.compute_loss(batch)
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            optimizer.step()
            policy.ema.update(policy.model)
            yield loss.detach()


class CudaGraphTrainStep:
    """The same step with windows on the GPU, captured on the 4th call and replayed from then on."""

    def __init__(self, policy: DiffusionPolicy, data: SequenceDataset, cfg: DiffusionPolicyConfig) -> None:
        device = policy.device
        self.policy, self.batch_size = policy, cfg.batch_size
        self.optimizer = torch.optim.AdamW(policy.model.parameters(), lr=torch.tensor(cfg.lr, device=device),
                                           betas=cfg.betas, weight_decay=cfg.weight_decay, fused=True,
                                           capturable=True)
        self.obs, self.actions = data.obs.to(device), data.actions.to(device)
        self.obs_index, self.action_index = data.obs_index.to(device), data.action_index.to(device)
        self.num_windows, self.steps = len(data), steps_per_epoch(data, cfg.batch_size)
        self.generator = torch.Generator(device=device).manual_seed(cfg.seed)  # batch order
        self.index = torch.zeros(cfg.batch_size, dtype=torch.long, device=device)
        self.ema_weight = torch.zeros((), device=device)
        self.calls, self.graph, self.loss = 0, None, None

    def _body(self) -> torch.Tensor:
        batch = {"obs": self.obs[self.obs_index[self.index]], "actions": self.actions[self.action_index[self.index]]}
        loss = self.policy.compute_loss(batch)
        loss.backward()
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
        n, b = self.num_windows, self.batch_size
        reps = -(-max(n, b) // n)
        order = torch.cat([torch.randperm(n, device=self.index.device, generator=self.generator) for _ in range(reps)])
        for k in range(self.steps):
            self.index.copy_(order[k * b:(k + 1) * b])
            yield self._run()


def make_train_step(policy: DiffusionPolicy, data: SequenceDataset,
                    cfg: DiffusionPolicyConfig) -> EagerTrainStep | CudaGraphTrainStep:
    """The captured step on CUDA (unless ``cfg.cuda_graph`` is off), the eager one elsewhere."""
    if policy.device.type == "cuda" and cfg.cuda_graph:
        return CudaGraphTrainStep(policy, data, cfg)
    return EagerTrainStep(policy, data, cfg)
