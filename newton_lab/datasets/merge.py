"""Merge datasets of one task (e.g. shards collected on several workers) into a new one."""

from __future__ import annotations

from pathlib import Path

from .ref import DatasetRef
from .storage import open_writer, read_dataset_info, read_episodes
from .zarr.settings import ZarrWriteSettings

MERGE_BATCH = 256
"""Demos per write session (one durable batch each). One session per demo made a merge cost 30-80 ms a demo
on this 2-core machine, so merging the shards of a multi-GPU run took longer than collecting them."""


def merge_datasets(paths, out, *, progress=None, zarr_settings: ZarrWriteSettings | None = None) -> DatasetRef:
    """Append every demo of ``paths`` (in order) to the new dataset ``out``; demo ids are renumbered
    0..N-1, each demo's attrs gain ``source`` (``<file name>:<id>``), and each source's provenance is kept in the
    merged dataset's provenance. A source of ``out``'s format is copied as stored (``append_copies``: no
    decode / encode, except into zarr packs); another is read and written again. Writes ``MERGE_BATCH`` demos per
    durable batch; ``progress(done, total)`` is called after each. ``zarr_settings``: how a zarr ``out`` is written
    (``open_writer``)."""
    paths = [Path(p) for p in paths]
    out = Path(out)
    if out.exists():
        raise FileExistsError(f"{out} already exists; merge into a new path")
    infos = [read_dataset_info(p) for p in paths]
    tasks = {i["task_id"] for i in infos}
    if len(tasks) != 1:
        raise ValueError(f"cannot merge datasets of different tasks {sorted(tasks)}")
    task_id = tasks.pop()
    saved, total = [], sum(i["num_demos"] for i in infos)
    with open_writer(out, task_id=task_id, env_args=infos[0]["env_args"], zarr_settings=zarr_settings) as writer:
        for p, info in zip(paths, infos):
            ids = info["demo_ids"]
            for start in range(0, len(ids), MERGE_BATCH):
                batch = ids[start : start + MERGE_BATCH]
                if info["format"] == writer.format:
                    saved += writer.append_copies(p, batch, attrs={i: {"source": f"{p.name}:{i}"} for i in batch})
                else:
                    saved += writer.append_episodes(_converted(p, batch))
                if progress is not None:
                    progress(len(saved), total)
    ref = DatasetRef(out, task_id=task_id, metadata={"saved_demo_ids": saved, "episodes": len(saved)})
    sources = [{"path": str(p), "provenance": i["provenance"]} for p, i in zip(paths, infos)]
    return ref.record("merge", config={"sources": [str(p) for p in paths]}, metadata={"sources": sources})


def _converted(path: Path, ids: list[int]):
    """(episode, success, attrs + ``source``) of each demo of ``path``, read for a dataset of another format."""
    for i, ep in zip(ids, read_episodes(path, ids, attrs=True)):
        attrs = ep.pop("attrs")
        success = bool(attrs.pop("success", False))
        attrs.pop("num_samples", None)
        yield ep, success, {**attrs, "source": f"{path.name}:{i}"}
