"""Run records: one JSON file per pipeline run or benchmark command, naming what ran (the exact command line), on
which commit, when, on which device, and what it measured (counts, timings, success, the per-phase table).

The results page (``newton-lab results``, ``newton_lab.results``) is generated from the records committed under
``docs/results/``; no figure on it is typed by hand. Light on purpose: no Warp, torch or Prefect import here
(the device name is asked of whichever of them the command already loaded).
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import platform
import shlex
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path
from typing import Any

SCHEMA = 1
"""Version of the record layout (``schema`` in every record)."""
KINDS = ("pipeline", "bench", "bench-collect", "bench-train", "bench-refusals", "train-rl", "evaluate")
"""What a record can describe: a pipeline run, one of the benchmark commands, a PPO run, or an evaluation (with
``--perturb``: its perturbation table)."""
PRODUCT_COMMANDS = ("newton-lab ", "make demo")
"""How a record's ``command`` starts when a user can run it as it is (the CLI, or the README's main job)."""
EVERY_SHAPE = " every shape"
"""How a ``bench --render-orders`` record keys its run at the env's render setting with every shape drawn."""
RECORDS_DIR = Path("outputs/records")
"""Where a command writes its run record when ``--run-record`` is not given."""

_invocation: list[str] | None = None
_started: float | None = None


def set_invocation(argv: list[str]) -> None:
    """Remember the ``newton-lab`` arguments of this process and when it started (the CLI calls it first), for
    ``command_line`` and ``command_wall_s``."""
    global _invocation, _started
    _invocation, _started = list(argv), time.perf_counter()


def command_wall_s() -> float | None:
    """Seconds since the CLI started this command (imports and server start included); None off the CLI."""
    return None if _started is None else time.perf_counter() - _started


def command_line() -> str:
    """The command that is running: ``newton-lab <args>`` from the CLI (``make demo`` when the Makefile says so
    through ``NEWTON_LAB_COMMAND``), else the Python call (``python <script> <args>``)."""
    given = os.environ.get("NEWTON_LAB_COMMAND")
    if given:
        return given
    if _invocation is not None:
        return shlex.join(["newton-lab", *_invocation])
    return shlex.join(["python", *sys.argv])


def commit() -> dict[str, Any]:
    """The checkout's commit (``git rev-parse``) and whether it has uncommitted changes; ``NEWTON_LAB_COMMIT``
    names it where the code travelled without its git folder (an installed copy on a GPU host)."""
    given = os.environ.get("NEWTON_LAB_COMMIT")
    if given:
        sha, _, dirty = given.partition("+")
        return {"sha": sha, "dirty": dirty == "dirty"}
    root = Path(__file__).resolve().parents[1]
    try:
        sha = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, timeout=5, check=True
        ).stdout.strip()
        status = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=root,
            capture_output=True,
            text=True,
            timeout=5,
            check=True,
        ).stdout
    except (OSError, subprocess.SubprocessError):
        return {"sha": "unknown", "dirty": False}
    return {"sha": sha, "dirty": bool(status.strip())}


def _cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _load() -> list[float] | None:
    """The host's load averages over 1, 5 and 15 minutes: above the core count, the figures shared the CPU."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return None


def device_info(device: str | None) -> dict[str, Any]:
    """``{"kind": "cuda" | "cpu", "name", "count", "cpu", "cores", "load_average_1_5_15"}`` of the device a command
    ran on; a CUDA device's name comes from torch or Warp, whichever is loaded (``NVIDIA H200``)."""
    cores = os.cpu_count() or 1
    info: dict[str, Any] = {
        "kind": "cpu",
        "name": f"CPU ({cores} cores)",
        "count": 0,
        "cpu": _cpu_name(),
        "cores": cores,
        "load_average_1_5_15": _load(),
    }
    if device is None or str(device).startswith("cuda"):
        name, count = _cuda_name(device)
        if name:
            info.update(kind="cuda", name=name, count=count)
    return info


def _cuda_name(device: str | None) -> tuple[str | None, int]:
    index = int(str(device).split(":")[1]) if device and ":" in str(device) else 0
    torch = sys.modules.get("torch")
    if torch is None and device is not None and "warp" not in sys.modules:
        import torch  # deferred: only a CUDA run that has not loaded torch or Warp in this process asks it
    if torch is not None and torch.cuda.is_available():
        return torch.cuda.get_device_name(index), torch.cuda.device_count()
    wp = sys.modules.get("warp")
    if wp is not None:
        cudas = [d for d in wp.get_cuda_devices()] if wp.is_cuda_available() else []
        if cudas:
            return cudas[min(index, len(cudas) - 1)].name, len(cudas)
    return None, 0


def versions() -> dict[str, str]:
    """Installed versions of the packages a figure depends on."""
    out = {}
    for name in ("newton_lab", "warp-lang", "newton", "mujoco-warp", "torch", "prefect"):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            mod = sys.modules.get(name.replace("-lang", "").replace("-", "_"))
            if mod is not None and hasattr(mod, "__version__"):
                out[name] = str(mod.__version__)
    return out


def make_record(
    kind: str,
    *,
    task: str | None,
    device: str | None,
    results: dict[str, Any],
    wall_s: float | None = None,
    command: str | None = None,
) -> dict[str, Any]:
    """A record of ``kind`` (``KINDS``): what ran and where, then ``results`` (the command's own figures)."""
    if kind not in KINDS:
        raise ValueError(f"unknown record kind {kind!r}; valid kinds: {', '.join(KINDS)}")
    now = _dt.datetime.now(_dt.UTC).replace(microsecond=0)
    return {
        "schema": SCHEMA,
        "kind": kind,
        "task": task,
        "command": command or command_line(),
        "commit": commit(),
        "date": now.isoformat().replace("+00:00", "Z"),
        "device": device_info(device),
        "versions": versions(),
        "wall_s": None if wall_s is None else round(float(wall_s), 2),
        "results": results,
    }


def write_record(record: dict[str, Any], path: str | os.PathLike) -> Path:
    """Write ``record`` as JSON to ``path`` (atomically: a reader never sees half a record); returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(record, indent=1, default=_plain) + "\n")
    tmp.replace(path)
    return path


def write_run_record(
    kind: str, path: str | os.PathLike | None, *, task: str | None, device: str | None, results: dict[str, Any]
) -> Path:
    """The record of the command that is running (its wall time so far, ``command_wall_s``), written at ``path`` (the
    command's ``--run-record``; ``default_path`` when ``None``), its path said on stderr; returns the path."""
    record = make_record(kind, task=task, device=device, results=results, wall_s=command_wall_s())
    written = write_record(record, path or default_path(kind, task))
    print(f"run record: {written}", file=sys.stderr)
    return written


def default_path(kind: str, task: str | None) -> Path:
    """``outputs/records/<kind>-<task>-<UTC time>.json`` for a command run without ``--run-record``."""
    stamp = _dt.datetime.now(_dt.UTC).strftime("%Y%m%dT%H%M%SZ")
    short = (task or "all").replace("GalbotG1-", "").replace("-v0", "")
    return RECORDS_DIR / f"{kind}-{short}-{stamp}.json"


def read_record(path: str | os.PathLike) -> dict[str, Any]:
    """A record read back, checked for the fields the results page needs (one-line error otherwise)."""
    path = Path(path)
    try:
        record = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"run record {path} is unreadable ({exc}); re-run its command to write it again") from None
    missing = [k for k in ("schema", "kind", "command", "commit", "date", "device", "results") if k not in record]
    if missing:
        raise ValueError(f"run record {path} lacks {missing}; it was not written by a newton-lab command")
    return record


def device_slug(record: dict[str, Any]) -> str:
    """``h200`` for an NVIDIA H200, ``cpu`` for the CPU: the device part of a committed record's name
    (``<row>-<device>.json``, a variant of the row's run ``<row>-<device>-<variant>.json``)."""
    device = record["device"]
    if device["kind"] != "cuda":
        return "cpu"
    return device["name"].replace("NVIDIA", "").strip().split()[0].lower()


def is_product_command(command: str) -> bool:
    """Whether ``command`` is one a user runs as it is: ``newton-lab ...`` or ``make demo ...``."""
    return command.startswith(PRODUCT_COMMANDS)


def _plain(value: Any) -> Any:
    """JSON for what ``json`` does not know (numpy scalars, paths, tuples stay as lists)."""
    if hasattr(value, "item"):
        return value.item()
    return str(value)


def stage_seconds(out: dict[str, Any]) -> dict[str, float]:
    """A ``bench-collect`` result's stages [s]: the env step with its render (``physics + render`` with cameras:
    ``physics_s`` + ``record_s``, the render and frames), the agent's ``act``, the loop's hand-over of ended episodes
    to the writer, and the writer's batch writes (a writer process writes beside the loop: the loop waits for it only
    through the hand-over)."""
    render = out.get("record_s", 0.0) if out.get("cameras") else 0.0
    return {
        "physics + render" if out.get("cameras") else "physics": out["physics_s"] + render,
        "agent": out["agent_s"],
        "hand-over": out["hand_over_s"],
        "writer": out["writer_s"],
    }
