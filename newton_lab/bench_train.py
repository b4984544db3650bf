"""Diffusion-policy training throughput (``newton-lab bench-train``): optimiser steps/s of the eager and the captured
step side by side on fresh policies of one architecture, per precision, layout, autotuning and compilation; where
an eager step's time goes (data, forward, backward, optimiser), its floating-point work, and with ``profile`` the
operators that spend the device's time."""

from __future__ import annotations

import dataclasses
import itertools
import time
from typing import Any

import torch

from .policies.data import SequenceDataset
from .policies.diffusion import PRESETS, DiffusionPolicy, DiffusionPolicyConfig
from .policies.norm import set_native_norms
from .policies.train_step import CudaGraphTrainStep, EagerTrainStep


def bench_train(
    dataset: str,
    *,
    batch_size: int = 1024,
    steps: int = 200,
    device: str = "cpu",
    preset: str = "default",
    bf16: bool = False,
    channels_last: bool = False,
    obs_keys: tuple[str, ...] | None = None,
    image_keys: tuple[str, ...] | None = None,
    cudnn_benchmark: bool = False,
    compile: bool = False,
    bf16_norms: bool = False,
    native_norms: bool = False,
    profile: bool = False,
) -> dict[str, Any]:
    """Diffusion-policy optimiser steps/s on ``dataset``: the eager step and (on CUDA) the captured step, side by
    side in one process on fresh policies of the same architecture. Variants, each keyed by its tags:
    ``bf16`` each also under bfloat16 autocast (``..._bf16``); ``channels_last`` each also with the network's
    weights in channels-last layout (``..._cl``: the convolutions then run channels-last); ``cudnn_benchmark`` each
    also with cuDNN's autotuner on (``..._tuned``); ``compile`` each step kind also through ``torch.compile`` at the
    last variant's precision and autotuning (``..._compiled...``); ``bf16_norms`` the captured step (the eager one
    off CUDA) under bf16 with its GroupNorms in bf16 too (``..._bf16norms_bf16...``); ``native_norms`` (with
    ``bf16_norms``) that variant again on PyTorch's own group-norm kernels (``policies.norm``; ``..._nativenorms...``).
    ``obs_keys`` / ``image_keys`` replace the preset's (e.g. the long-horizon recipe's two views). Also where a step's
    time goes (``step_breakdown``; with ``profile`` the operators that spend the device's time, ``op_profile``),
    the achieved TFLOP/s at the fastest variant's rate and, on CUDA, the peak GPU memory."""
    fields = {k: v for k, v in PRESETS[preset].items() if k not in ("batch_size", "max_steps", "epochs")}
    fields.update({k: v for k, v in (("obs_keys", obs_keys), ("image_keys", image_keys)) if v})
    cfg = DiffusionPolicyConfig(**fields, batch_size=batch_size, device=device)
    data = SequenceDataset(
        dataset,
        pred_horizon=cfg.pred_horizon,
        obs_horizon=cfg.obs_horizon,
        obs_keys=cfg.obs_keys,
        image_keys=cfg.image_keys,
    )
    on_cuda = torch.device(device).type == "cuda"
    kinds = [EagerTrainStep] + ([CudaGraphTrainStep] if on_cuda else [])
    out: dict[str, Any] = {
        "dataset": dataset,
        "device": device,
        "batch_size": batch_size,
        "preset": preset,
        "device_name": torch.cuda.get_device_name(device) if on_cuda else "cpu",
        "windows": len(data),
        "obs_keys": list(cfg.obs_keys or ()),
        "image_keys": list(data.image_keys),
        "image_shapes": {k: list(v) for k, v in data.image_shapes.items()},
    }
    for kind, name, tuned, layout_cl, overrides in _variants(
        kinds, bf16, channels_last, cudnn_benchmark, compile, bf16_norms, native_norms
    ):
        torch.backends.cudnn.benchmark = tuned
        native = overrides.pop("native_norms")
        run_cfg = dataclasses.replace(cfg, **overrides)
        rate, final = _time_variant(kind, data, run_cfg, layout_cl, steps, native)
        out[f"{name}_steps_per_s"] = rate
        out[f"{name}_samples_per_s"] = rate * batch_size
        out[f"{name}_final_loss"] = final
    if len(kinds) == 2:
        out["speedup"] = out["CudaGraphTrainStep_steps_per_s"] / out["EagerTrainStep_steps_per_s"]
    measured = {"bf16": bf16, "bf16_norms": bf16 and bf16_norms}  # the breakdown and profile's precision
    out["breakdown_config"] = measured
    out.update(step_breakdown(data, dataclasses.replace(cfg, **measured), steps=min(steps, 20), profile=profile))
    best = max(v for k, v in out.items() if k.endswith("_samples_per_s"))
    out["achieved_tflops"] = out["flops_per_sample"] * best / 1e12  # at the fastest variant's samples/s
    if on_cuda:
        out["gpu_mem_peak_mib"] = torch.cuda.max_memory_allocated(device) / 2**20
    return out


def _variants(
    kinds, bf16: bool, channels_last: bool, cudnn_benchmark: bool, compile: bool, bf16_norms: bool, native_norms: bool
):
    """``bench_train``'s variants in the order they run (the autotuner last: once on, it stays on in the process):
    (step kind, key, autotuned, channels-last, config overrides)."""
    both = {True: [False, True], False: [False]}
    grid = [
        (kind, tuned, layout_cl, precision, False, False, False)
        for tuned, layout_cl, precision, kind in itertools.product(
            both[cudnn_benchmark], both[channels_last], both[bf16], kinds
        )
    ]
    grid += [(kind, cudnn_benchmark, False, bf16, True, False, False) for kind in kinds] if compile else []
    grid += [(kinds[-1], cudnn_benchmark, False, True, False, True, False)] if bf16_norms else []
    grid += [(kinds[-1], cudnn_benchmark, False, True, False, True, True)] if native_norms and bf16_norms else []
    for kind, tuned, layout_cl, precision, compiled, norms, native in grid:
        tags = (
            ("_compiled", compiled),
            ("_nativenorms", native),
            ("_bf16norms", norms),
            ("_bf16", precision),
            ("_cl", layout_cl),
            ("_tuned", tuned),
        )
        name = kind.__name__ + "".join(tag for tag, on in tags if on)
        overrides = {"bf16": precision, "compile": compiled, "bf16_norms": norms, "native_norms": native}
        yield kind, name, tuned, layout_cl, overrides


def _time_variant(
    kind, data: SequenceDataset, cfg: DiffusionPolicyConfig, channels_last: bool, steps: int, native_norms: bool
):
    """(steps/s, final loss) of ``steps`` optimiser steps of ``kind`` on a fresh policy (seed 0), after 10 untimed
    ones (allocation, autotuning, capture, compilation); ``native_norms``: its GroupNorms on PyTorch's own
    kernels."""
    torch.manual_seed(0)
    policy = DiffusionPolicy.from_dataset(data, cfg).to(cfg.device)
    set_native_norms(policy.model, native_norms)
    if channels_last:
        policy.model.to(memory_format=torch.channels_last)
    on_cuda = torch.device(cfg.device).type == "cuda"
    stepper, done, t0, loss = kind(policy, data, cfg), 0, 0.0, None
    while done < steps + 10:
        for loss in stepper.epoch():  # noqa: B007 - the last step's loss is read after the loop
            done += 1
            if done == 10:
                if on_cuda:
                    torch.cuda.synchronize(cfg.device)
                t0 = time.perf_counter()
            if done == steps + 10:
                break
    final = loss.item()  # waits for the queued steps
    return steps / (time.perf_counter() - t0), final


def step_breakdown(
    data: SequenceDataset, cfg: DiffusionPolicyConfig, steps: int = 20, profile: bool = False
) -> dict[str, Any]:
    """Where one training step's time goes, each stage timed apart with the device synchronised around it
    (``breakdown_ms``: the batch's gather from the windows, the forward pass and loss, the backward pass, the
    optimiser step with the EMA update; eager, so the sum exceeds a captured step), and the step's floating-point
    work (``flops_per_sample``: forward and backward, counted by ``torch.utils.flop_counter`` on one step)."""
    from torch.utils.flop_counter import FlopCounterMode  # deferred: only this measurement counts operations

    torch.manual_seed(0)
    device = torch.device(cfg.device)
    policy = DiffusionPolicy.from_dataset(data, cfg).to(device)
    opt = torch.optim.AdamW(policy.model.parameters(), lr=cfg.lr, fused=device.type in ("cuda", "cpu"))
    windows = data.windows(device)
    gen = torch.Generator(device=device).manual_seed(0)

    def sync() -> float:
        if device.type == "cuda":
            torch.cuda.synchronize(device)
        return time.perf_counter()

    def batch() -> dict[str, Any]:
        return windows.batch(torch.randint(len(data), (cfg.batch_size,), device=device, generator=gen))

    spent = {"data": 0.0, "forward": 0.0, "backward": 0.0, "optimizer": 0.0}
    warmup = 3
    for i in range(steps + warmup):
        t0 = sync()
        b = batch()
        t1 = sync()
        loss = policy.compute_loss(b)
        t2 = sync()
        loss.backward()
        t3 = sync()
        opt.step()
        opt.zero_grad(set_to_none=True)
        policy.ema.update(policy.model)
        t4 = sync()
        if i >= warmup:
            for name, dt in zip(spent, (t1 - t0, t2 - t1, t3 - t2, t4 - t3)):
                spent[name] += dt
    with FlopCounterMode(display=False) as counter:
        policy.compute_loss(batch()).backward()
    opt.zero_grad(set_to_none=True)
    out = {
        "breakdown_ms": {k: 1e3 * v / steps for k, v in spent.items()},
        "flops_per_sample": counter.get_total_flops() / cfg.batch_size,
    }
    if profile:

        def one_step() -> None:
            policy.compute_loss(batch()).backward()
            opt.step()
            opt.zero_grad(set_to_none=True)
            policy.ema.update(policy.model)

        out["profile"] = op_profile(one_step, device, steps=min(steps, 10))
    return out


OP_FAMILIES = (
    ("convolution", ("conv",)),
    ("normalisation", ("group_norm", "layer_norm", "batch_norm")),
    ("matmul", ("mm", "linear", "matmul")),
    ("cast and copy", ("copy", "cat", "clone", "index", "gather")),
    ("optimiser", ("adam", "foreach", "lerp")),
)
"""Operator families of ``op_profile``'s summary: the first family with a word in an operator's name
(``aten::cudnn_convolution`` -> convolution); the rest are ``elementwise and other``."""


def _family(name: str) -> str:
    op = name.removeprefix("aten::")
    return next((family for family, words in OP_FAMILIES if any(w in op for w in words)), "elementwise and other")


def op_profile(step, device: torch.device, steps: int = 10, top: int = 20) -> dict[str, Any]:
    """``torch.profiler`` over ``steps`` calls of ``step`` (after two untimed ones): the device's time per step
    [ms] by operator (``self`` time: what the operator's own kernels spent, on CUDA, or its own CPU time), the
    ``top`` operators with their share and calls per step, and the time per ``OP_FAMILIES`` family."""
    from torch.profiler import ProfilerActivity, profile  # deferred: only this measurement profiles

    on_cuda = device.type == "cuda"
    for _ in range(2):
        step()
    activities = [ProfilerActivity.CPU] + ([ProfilerActivity.CUDA] if on_cuda else [])
    with profile(activities=activities) as prof:
        for _ in range(steps):
            step()
        if on_cuda:
            torch.cuda.synchronize(device)
    rows = []
    for evt in prof.key_averages():
        us = evt.self_device_time_total if on_cuda else evt.self_cpu_time_total
        if us > 0 and evt.key.startswith("aten::"):
            rows.append((evt.key, us / 1e3 / steps, evt.count / steps))
    total = sum(ms for _, ms, _ in rows) or 1.0
    rows.sort(key=lambda r: -r[1])
    families: dict[str, float] = {}
    for name, ms, _ in rows:
        families[_family(name)] = families.get(_family(name), 0.0) + ms
    return {
        "clock": "device" if on_cuda else "cpu",
        "ms_per_step": total,
        "top": [
            {"op": name, "ms_per_step": ms, "share": ms / total, "calls_per_step": calls}
            for name, ms, calls in rows[:top]
        ],
        "families_ms_per_step": dict(sorted(families.items(), key=lambda kv: -kv[1])),
    }
