"""Merge datasets of one task (e.g. shards collected on several workers) into a new one."""

from __future__ import annotations

from pathlib import Path

from .ref import DatasetRef
from .storage import open_writer, read_dataset_info, read_episode


def merge_datasets(paths, out) -> DatasetRef:
    """Append every demo of ``paths`` (in order) to the new dataset ``out``; demo ids are renumbered
    0..N-1 and each source's provenance is kept in the merged dataset's provenance."""
    paths = [Path(p) for p in paths]
    out = Path(out)
    if out.exists():
        raise FileExistsError(f"{out} already exists; merge into a new path")
    infos = [read_dataset_info(p) for p in paths]
    tasks = {i["task_id"] for i in infos}
    if len(tasks) != 1:
        raise ValueError(f"cannot merge datasets of different tasks {sorted(tasks)}")
    task_id = tasks.pop()
    saved = []
    with open_writer(out, task_id=task_id, env_args=infos[0]["env_args"]) as writer:
        for p, info in zip(paths, infos):
            for demo in info["demo_ids"]:
                ep = read_episode(p, demo)
                attrs = ep.pop("attrs")
                success = bool(attrs.pop("success", False))
                attrs.pop("num_samples", None)
                attrs["source"] = f"{p.name}:{demo}"
                saved.append(writer.append_episode(ep, success=success, attrs=attrs))
    ref = DatasetRef(out, task_id=task_id, metadata={"saved_demo_ids": saved, "episodes": len(saved)})
    return ref.record("merge", config={"sources": [str(p) for p in paths]},
                      metadata={"sources": [{"path": str(p), "provenance": i["provenance"]} for p, i in zip(paths, infos)]})
