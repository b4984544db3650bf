"""The LeRobot v3.0 export: plan, per-episode arrays, writing, atomic rename into place.

Everything is written into a hidden sibling ``.<root name>.partial-*`` and renamed to ``root`` at the end.
"""

from __future__ import annotations

import json
import os
import shutil
import uuid
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..files.durability import fsync_path
from ..files.output_paths import output_path
from ..storage import read_dataset_info, read_episodes
from .plan import Plan, episode_arrays, make_plan
from .tables import (
    CHUNKS_SIZE,
    CODEBASE_VERSION,
    DATA_FILES_SIZE_IN_MB,
    DATA_PATH,
    EPISODES_PATH,
    IMAGE_PREFIX,
    ROBOT_TYPE,
    SOURCE_PATH,
    VIDEO_FILES_SIZE_IN_MB,
    VIDEO_PATH,
    DataFiles,
    aggregate,
    episode_table,
    image_stats,
    vector_stats,
    write_episodes,
    write_tasks,
)
from .video import VideoFiles


def export_lerobot(
    dataset: Any,
    root: str | os.PathLike,
    *,
    repo_id: str | None = None,
    fps: int | None = None,
    include_failed: bool = False,
    state_keys: Sequence[str] | None = None,
    task_description: str | None = None,
    data_files_size_in_mb: int = DATA_FILES_SIZE_IN_MB,
    video: bool = True,
) -> dict[str, Any]:
    """Write the demos of ``dataset`` as a LeRobot v3.0 dataset at ``root`` (which must not exist).

    Args:
        dataset: path of a newton_lab ``.hdf5`` / ``.h5`` / ``.zarr`` dataset, or any object with a
            ``.path`` attribute (e.g. a DatasetRef).
        root: new directory for the LeRobot dataset; an existing path is refused (nothing is written).
        repo_id: LeRobot repo id; default ``newton_lab/<task id lowercased>``.
        fps: integer frame rate; default ``1 / (sim_dt * decimation)`` from ``env_args['newton_lab']``.
        include_failed: also export demos whose ``success`` attr is False (skipped by default).
        state_keys: obs terms concatenated (in this order) into ``observation.state``; default every
            (T, d) obs term except ``actions``, in the env's obs order (``env_args`` ``obs_terms``).
        task_description: the task string of every frame; default the task id.
        data_files_size_in_mb: start a new data parquet file once the current one would exceed this.
        video: camera terms (uint8 (T, H, W, 3) obs) as mp4 video features (``video.py``: AV1, yuv420p, lossy);
            False: as lossless PNG "image" features inside the data files.

    Returns:
        ``{"root", "repo_id", "episodes", "frames", "skipped_failed", "fps", "task", "demo_ids",
        "skipped_empty", "state_keys", "image_keys", "data_files", "video_files"}``; ``demo_ids[i]`` is the source
        demo of LeRobot episode ``i``.
    """
    root = Path(root).expanduser()
    _refuse_existing(root)
    source = _source_path(dataset)
    if not (
        isinstance(data_files_size_in_mb, int)
        and not isinstance(data_files_size_in_mb, bool)
        and data_files_size_in_mb > 0
    ):
        raise ValueError(f"data_files_size_in_mb must be a positive int, got {data_files_size_in_mb!r}")
    info = read_dataset_info(source)
    _refuse_nested(root, Path(info["path"]))
    plan, first = make_plan(
        info,
        repo_id=repo_id,
        fps=fps,
        include_failed=include_failed,
        state_keys=state_keys,
        task_description=task_description,
    )
    plan.video = bool(video)

    output_path(root)
    tmp = root.parent / f".{root.name}.partial-{uuid.uuid4().hex}"
    tmp.mkdir()  # not mkdtemp: the renamed root should get the usual (umask) permissions
    try:
        data_files, video_files, frames = _write_all(
            tmp, plan, first, data_files_size_in_mb * 1024 * 1024, data_files_size_in_mb
        )
        _fsync_tree(tmp)
        _refuse_existing(root)  # created by someone else meanwhile: keep theirs, drop ours
        os.rename(tmp, root)
        fsync_path(root.parent)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return _export_summary(root, plan, frames, data_files, video_files)


def _export_summary(root: Path, plan: Plan, frames: int, data_files: list, video_files: list) -> dict[str, Any]:
    """``export_lerobot``'s result: what was written where, and which source demos were skipped."""
    return {
        "root": str(root),
        "repo_id": plan.repo_id,
        "episodes": len(plan.demo_ids),
        "frames": frames,
        "skipped_failed": len(plan.skipped_failed),
        "fps": plan.fps,
        "task": plan.task,
        "demo_ids": list(plan.demo_ids),
        "skipped_empty": len(plan.skipped_empty),
        "state_keys": [t for t, _ in plan.state_terms],
        "image_keys": [IMAGE_PREFIX + t for t, _ in plan.image_terms],
        "data_files": data_files,
        "video_files": video_files,
    }


# ----------------------------------------------------------------------------- argument checks
def _refuse_existing(root: Path) -> None:
    if os.path.lexists(root):
        raise FileExistsError(
            f"LeRobot root {root} already exists; choose a new root or delete it (nothing was written)"
        )


def _refuse_nested(root: Path, source: Path) -> None:
    src, dst = source.resolve(), root.resolve()
    if dst == src or src in dst.parents:
        raise ValueError(f"LeRobot root {root} lies inside the source dataset {source}; choose a root outside it")


def _source_path(dataset: Any) -> Path:
    if isinstance(dataset, (str, os.PathLike)):
        return Path(dataset)
    path = getattr(dataset, "path", None)
    if isinstance(path, (str, os.PathLike)):
        return Path(path)
    raise TypeError(
        f"dataset must be a path or an object with a .path attribute (e.g. a DatasetRef), got {type(dataset).__name__}"
    )


# ----------------------------------------------------------------------------- per-episode data
# ----------------------------------------------------------------------------- writing
def _write_all(
    tmp: Path, plan: Plan, first: dict[str, Any], limit_bytes: int, limit_mb: int
) -> tuple[list[str], list[str], int]:
    """Write data files, videos and meta/ into ``tmp``; returns (data file paths, video file paths, frames)."""
    files = DataFiles(tmp, limit_bytes)
    limit = VIDEO_FILES_SIZE_IN_MB << 20
    videos = {t: VideoFiles(tmp, IMAGE_PREFIX + t, plan.fps, limit) for t, _ in plan.image_terms} if plan.video else {}
    rows: list[dict[str, Any]] = []
    ep_stats: list[dict[str, dict[str, np.ndarray]]] = []
    start = 0
    rest = read_episodes(plan.source, plan.demo_ids[1:], attrs=True)  # one open dataset (zarr packs: shared chunks)
    try:
        for episode_index, demo_id in enumerate(plan.demo_ids):
            ep = first if episode_index == 0 else next(rest)
            state, actions, images = episode_arrays(ep, plan, demo_id)
            del ep
            in_table = {} if plan.video else images  # PNG columns in the data file, or mp4 files beside it
            table, scalars = episode_table(state, actions, in_table, plan.fps, episode_index, start)
            chunk, file = files.write(table)
            located = {k: v for t, frames in images.items() if plan.video for k, v in videos[t].write(frames).items()}
            del table
            stats = {"observation.state": vector_stats(state), "action": vector_stats(actions)}
            stats.update({IMAGE_PREFIX + t: image_stats(images[t]) for t, _ in plan.image_terms})
            stats.update({k: vector_stats(v) for k, v in scalars.items()})
            steps = len(actions)
            rows.append(
                {
                    "episode_index": episode_index,
                    "tasks": [plan.task],
                    "length": steps,
                    "data/chunk_index": chunk,
                    "data/file_index": file,
                    "dataset_from_index": start,
                    "dataset_to_index": start + steps,
                    "meta/episodes/chunk_index": 0,
                    "meta/episodes/file_index": 0,
                    **located,
                }
            )
            ep_stats.append(stats)
            start += steps
        first.clear()
    finally:
        files.close()
        for v in videos.values():
            v.close()
    _write_meta(tmp, plan, rows, ep_stats, start, limit_mb)
    return files.paths, [p for v in videos.values() for p in v.paths], start


def _write_meta(
    tmp: Path,
    plan: Plan,
    rows: list[dict[str, Any]],
    ep_stats: list[dict[str, dict[str, np.ndarray]]],
    frames: int,
    limit_mb: int,
) -> None:
    """meta/: episodes, tasks, stats.json, info.json and the newton_lab provenance file."""
    meta = tmp / "meta"
    meta.mkdir()
    write_episodes(tmp / EPISODES_PATH.format(chunk_index=0, file_index=0), rows, ep_stats)
    write_tasks(meta / "tasks.parquet", [plan.task])
    stats = aggregate(ep_stats)
    _write_json(meta / "stats.json", {k: {s: v.tolist() for s, v in st.items()} for k, st in stats.items()})
    info = {
        "codebase_version": CODEBASE_VERSION,
        "robot_type": ROBOT_TYPE,
        "total_episodes": len(rows),
        "total_frames": frames,
        "total_tasks": 1,
        "chunks_size": CHUNKS_SIZE,
        "data_files_size_in_mb": limit_mb,
        "video_files_size_in_mb": VIDEO_FILES_SIZE_IN_MB,
        "fps": plan.fps,
        "splits": {"train": f"0:{len(rows)}"},
        "data_path": DATA_PATH,
        "video_path": VIDEO_PATH if plan.image_terms and plan.video else None,
        "features": plan.features(),
    }
    _write_json(meta / "info.json", info)
    _write_json(
        tmp / SOURCE_PATH,
        {
            "exporter": "newton_lab.datasets.lerobot",
            "source": str(plan.source),
            "source_format": plan.source_format,
            "task_id": plan.task_id,
            "demo_ids": plan.demo_ids,
            "skipped_failed_demo_ids": plan.skipped_failed,
            "skipped_empty_demo_ids": plan.skipped_empty,
            "state_keys": [t for t, _ in plan.state_terms],
            "image_terms": [t for t, _ in plan.image_terms],
            "ignored_obs_terms": plan.ignored_terms,
        },
    )


def _write_json(path: Path, obj: Any) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(obj, indent=4) + "\n")


def _fsync_tree(top: Path) -> None:
    for dirpath, _, names in os.walk(top):
        for name in names:
            fsync_path(Path(dirpath, name))
        fsync_path(Path(dirpath))
