"""Split a coherent task's dataset into one dataset per phase (component task), using ``datagen/phase``.

Each episode contributes its contiguous steps of phase ``p`` to ``<out_dir>/<phase name>.<suffix>``, labelled
with the component task id; the actions keep only the component's columns (by joint name) and the
segment's ``initial_state`` is the recorded state at its first step. A segment is successful when the row
moved on to the next phase (the last phase: when the episode succeeded).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..robots.g1 import spec
from ..task_api.registry import lookup
from .ref import DatasetRef
from .storage import open_writer, read_dataset_info, read_episode


def _slice(node: Any, sel: np.ndarray, steps: int) -> Any:
    if isinstance(node, dict):
        return {k: _slice(v, sel, steps) for k, v in node.items()}
    arr = np.asarray(node)
    return arr[sel] if arr.ndim and arr.shape[0] == steps else arr


def split_by_phase(path: str | Path, out_dir: str | Path) -> dict[str, DatasetRef]:
    """Write one dataset per phase of the coherent task that recorded ``path``; returns them by phase name.
    Existing output files are never replaced."""
    path, out_dir = Path(path), Path(out_dir)
    info = read_dataset_info(path)
    task_id = info["task_id"]
    env_args = info["env_args"]
    options = env_args.get("env_kwargs", {}).get("task_options") or {}
    from .. import tasks  # noqa: F401  (deferred: registering the tasks imports Warp; storage stays Warp-free)

    cfg = lookup(task_id).make_cfg(options)
    if not cfg.phases:
        raise ValueError(f"{path} was recorded on {task_id}, which has no phases; nothing to split")
    columns = env_args["newton_lab"]["action_joint_names"]
    outs = {p.name: out_dir / f"{p.name}{path.suffix}" for p in cfg.phases}
    taken = [str(o) for o in outs.values() if o.exists()]
    if taken:
        raise FileExistsError(f"{taken} already exist; split into a new folder")
    out_dir.mkdir(parents=True, exist_ok=True)
    refs: dict[str, DatasetRef] = {}
    last = len(cfg.phases) - 1
    for p, ph in enumerate(cfg.phases):
        comp = lookup(ph.task_id)
        comp = comp.cfg(**comp.accepted(options))
        names = [j for t in comp.actions for j in spec.JOINT_GROUPS[t.group]]
        cols = [columns.index(j) for j in names]
        args = {**env_args, "env_name": ph.task_id,
                "newton_lab": {**env_args["newton_lab"], "action_joint_names": names}}
        saved = []
        with open_writer(outs[ph.name], task_id=ph.task_id, env_args=args) as writer:
            for demo in info["demo_ids"]:
                ep = read_episode(path, demo)
                attrs = ep.pop("attrs")
                phase = np.asarray(ep["datagen"]["phase"]).reshape(-1)
                sel = np.nonzero(phase == p)[0]
                if sel.size == 0:
                    continue
                steps = phase.shape[0]
                seg = _slice({k: v for k, v in ep.items() if k != "initial_state"}, sel, steps)
                seg["actions"] = np.asarray(seg["actions"])[:, cols]
                if "states" in ep:  # (1, ...) like a collected episode's initial_state
                    seg["initial_state"] = _slice(ep["states"], sel[:1], steps)
                success = bool(attrs.get("success", False)) if p == last else bool((phase > p).any())
                saved.append(writer.append_episode(seg, success=success,
                                                   attrs={"source": f"{path.name}:{demo}", "phase": ph.name}))
        ref = DatasetRef(outs[ph.name], task_id=ph.task_id, metadata={"saved_demo_ids": saved, "episodes": len(saved)})
        refs[ph.name] = ref.record("split", config={"source": str(path), "phase": ph.name, "phase_index": p})
    return refs

