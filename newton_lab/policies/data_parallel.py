"""Data-parallel training over several GPUs (or CPU processes): torchrun starts one process per device, each
trains the same model on its slice of every global batch, and their gradients are averaged before each step.

``train(..., gpus=N)`` (``newton-lab train --gpus N``) starts ``torchrun --standalone --nproc-per-node N`` on
this module with a request file and returns the checkpoint of rank 0; a command started under torchrun by hand
(``torchrun --nproc-per-node 2 -m newton_lab.cli train ...``) joins the group the same way. NCCL on CUDA
(each rank on ``cuda:LOCAL_RANK``), gloo on the CPU.

One global step of N ranks equals one single-process step on the same N*batch_size windows: the ranks walk
the same shuffled order and take consecutive slices of each global batch, and every random draw of the step
(diffusion noise, timesteps, crop offsets) is made for the global batch on every rank, which then keeps its
own rows (``draw_rows``). The gradient average is one all-reduce of the flattened gradients, inside the
captured CUDA-graph step on GPUs (NCCL collectives can be captured). Checkpoints are written by rank 0 only
and have the single-process format. ``batch_size`` is per process, as with torch's DistributedDataParallel:
N GPUs see N times the windows per step.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import torch
import torch.distributed as dist

from ..datasets.writers.child_process import die_with_parent


def world() -> tuple[int, int]:
    """(rank, world size) of this process; (0, 1) outside a process group."""
    if dist.is_available() and dist.is_initialized():
        return dist.get_rank(), dist.get_world_size()
    return 0, 1


def is_main() -> bool:
    """Whether this process writes files and progress (rank 0, or no group)."""
    return world()[0] == 0


def join_from_environment(device: str) -> str:
    """Join the process group torchrun describes (``WORLD_SIZE`` > 1 in the environment) and return the device
    this rank trains on (CUDA: its own GPU, made current so that "cuda" means it); outside torchrun, ``device``."""
    if int(os.environ.get("WORLD_SIZE", "1")) <= 1 or world()[1] > 1:
        return device
    if torch.device(device).type == "cuda":
        local = int(os.environ.get("LOCAL_RANK", "0"))
        if local >= torch.cuda.device_count():
            raise ValueError(
                f"rank {local} needs GPU {local}, this host shows {torch.cuda.device_count()}; "
                f"start at most {torch.cuda.device_count()} processes"
            )
        torch.cuda.set_device(local)  # "cuda" now names this rank's GPU (the saved config keeps plain "cuda")
        dist.init_process_group("nccl", device_id=torch.device("cuda", local))
        return "cuda"
    dist.init_process_group("gloo")
    return device


def leave() -> None:
    """Destroy the process group (end of a torchrun worker)."""
    if dist.is_available() and dist.is_initialized():
        dist.destroy_process_group()


def draw_rows(draw: Callable[[int], torch.Tensor], rows: int) -> torch.Tensor:
    """``draw(rows)`` in one process; in a group of N, ``draw(N * rows)`` and this rank's consecutive slice, so
    that the ranks together draw exactly what one process would for the global batch."""
    rank, size = world()
    if size == 1:
        return draw(rows)
    return draw(rows * size)[rank * rows : (rank + 1) * rows]


def average_gradients(parameters: Iterable[torch.nn.Parameter]) -> None:
    """Average the gradients over the group in place (one all-reduce of the flattened gradients)."""
    rank, size = world()
    if size == 1:
        return
    grads = [p.grad for p in parameters if p.grad is not None]
    flat = torch.cat([g.reshape(-1) for g in grads])
    dist.all_reduce(flat)
    flat.div_(size)
    offset = 0
    for g in grads:
        g.copy_(flat[offset : offset + g.numel()].view_as(g))
        offset += g.numel()


def mean_over_ranks(value: torch.Tensor) -> torch.Tensor:
    """The mean of a scalar tensor over the group (an epoch's loss over every rank's windows)."""
    if world()[1] == 1:
        return value
    value = value.detach().clone()
    dist.all_reduce(value)
    return value / world()[1]


def same_start(module: torch.nn.Module) -> None:
    """Make every rank start from rank 0's weights and buffers (the seeds already agree; this is the guarantee)."""
    if world()[1] == 1:
        return
    for tensor in list(module.parameters()) + list(module.buffers()):
        dist.broadcast(tensor.data, src=0)


def shared(value: Any) -> Any:
    """Rank 0's picklable ``value`` on every rank (e.g. a decision taken from wall time: the re-planned step total)."""
    if world()[1] == 1:
        return value
    box = [value]
    dist.broadcast_object_list(box, src=0)
    return box[0]


def launch(datasets: list[str], cfg: dict[str, Any], gpus: int, *, resume: bool = False) -> Path:
    """Train with ``gpus`` processes under torchrun (``cfg["device"]`` "cuda": one GPU each; "cpu": gloo
    processes); the checkpoint path written by rank 0. A failed worker raises with torchrun's exit status."""
    if torch.device(cfg.get("device", "cpu")).type == "cuda" and gpus > torch.cuda.device_count():
        raise ValueError(
            f"--gpus {gpus} needs {gpus} GPUs, this host shows {torch.cuda.device_count()}; "
            f"use --gpus {torch.cuda.device_count()} or fewer"
        )
    cores = os.cpu_count() or 1
    if torch.device(cfg.get("device", "cpu")).type != "cuda" and gpus > cores:  # ~250 MB of memory each
        raise ValueError(
            f"--gpus {gpus}: with --device cpu each is a gloo process on a CPU core, and this host has "
            f"{cores}; use --gpus {cores} or fewer"
        )
    with tempfile.TemporaryDirectory(prefix="newton_lab_ddp_") as folder:
        request, answer = Path(folder) / "request.json", Path(folder) / "checkpoint.json"
        request.write_text(json.dumps({"datasets": datasets, "cfg": cfg, "resume": resume, "answer": str(answer)}))
        command = [
            sys.executable,
            "-m",
            "torch.distributed.run",
            "--standalone",
            f"--nproc-per-node={gpus}",
            "-m",
            "newton_lab.policies.data_parallel_rank",
            str(request),
        ]
        parent = os.getpid()  # torchrun (and so its workers) ends with this process, even when it is SIGKILLed
        code = subprocess.run(
            command, check=False, preexec_fn=lambda: die_with_parent(parent, signal.SIGTERM)
        ).returncode
        if code != 0 or not answer.exists():
            raise RuntimeError(
                f"data-parallel training over {gpus} processes failed (torchrun exit status {code}); "
                "the workers' errors are printed above"
            )
        return Path(json.loads(answer.read_text())["checkpoint"])
