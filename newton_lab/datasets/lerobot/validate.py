"""Structural validator of a LeRobot v3.0 dataset directory: ``validate_lerobot_v3``."""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from .invalid import Invalid, is_int, load_json, need, read_parquet
from .tables import CODEBASE_VERSION, INDEX_FEATURES, STATS
from .validate_episodes import (
    check_data_paths,
    check_episode_rows,
    check_episodes,
    check_frames,
    read_data,
    read_episodes,
)


def validate_lerobot_v3(root: str | os.PathLike) -> dict[str, Any]:
    """Structural check of a LeRobot v3.0 dataset directory.

    Checks: meta/info.json fields and types, meta/stats.json, meta/tasks.parquet, meta/episodes/*,
    data parquet columns against the features (dtypes, shapes, image structs), contiguous ``index``
    0..N-1, ``frame_index`` restarting at 0 in every episode, episode offsets and file references
    matching the data, ``timestamp`` == frame_index / fps (within 1e-4 s) and, for video features,
    that every referenced mp4 decodes with the declared size and fps and holds each episode's
    [from_timestamp, to_timestamp) span.

    Returns ``{"root", "codebase_version", "fps", "episodes", "frames", "tasks", "features",
    "image_keys", "video_keys", "data_files"}``; raises a one-line ``ValueError`` naming the first problem.
    """
    root = Path(root).expanduser()
    try:
        return _validate(root)
    except Invalid as e:
        raise ValueError(f"{root} is not a valid LeRobot v3.0 dataset: {' '.join(str(e).split())}") from None


def _check_info(info: Any) -> dict[str, dict[str, Any]]:
    need(isinstance(info, dict), "meta/info.json is not a JSON object")
    need(
        info.get("codebase_version") == CODEBASE_VERSION,
        f"info.json codebase_version is {info.get('codebase_version')!r}, not {CODEBASE_VERSION!r}",
    )
    need(is_int(info.get("fps")) and info["fps"] > 0, f"info.json fps must be a positive int, got {info.get('fps')!r}")
    for key in ("total_episodes", "total_frames", "total_tasks"):
        need(is_int(info.get(key)) and info[key] >= 0, f"info.json {key} must be an int >= 0, got {info.get(key)!r}")
    need(
        is_int(info.get("chunks_size")) and info["chunks_size"] > 0,
        f"info.json chunks_size must be a positive int, got {info.get('chunks_size')!r}",
    )
    for key in ("data_files_size_in_mb", "video_files_size_in_mb"):
        v = info.get(key)
        need(
            isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0,
            f"info.json {key} must be a positive number, got {v!r}",
        )
    dp = info.get("data_path")
    need(
        isinstance(dp, str) and "{chunk_index" in dp and "{file_index" in dp and dp.endswith(".parquet"),
        f"info.json data_path {dp!r} is not a data/...{{chunk_index}}...{{file_index}}....parquet template",
    )
    vp = info.get("video_path")
    need(
        vp is None or (isinstance(vp, str) and "{video_key}" in vp and "{chunk_index" in vp),
        f"info.json video_path {vp!r} must be null or a template with {{video_key}} and {{chunk_index}}",
    )
    need(
        info.get("robot_type") is None or isinstance(info.get("robot_type"), str),
        "info.json robot_type must be a string or null",
    )
    splits = info.get("splits", {})
    need(
        isinstance(splits, dict) and all(isinstance(v, str) and re.fullmatch(r"\d+:\d+", v) for v in splits.values()),
        f"info.json splits must map names to 'start:stop' strings, got {splits!r}",
    )
    feats = info.get("features")
    need(isinstance(feats, dict) and feats, "info.json features must be a non-empty object")
    for key, ft in feats.items():
        need(isinstance(ft, dict) and isinstance(ft.get("dtype"), str), f"feature {key!r} has no dtype string")
        shape = ft.get("shape")
        need(
            isinstance(shape, list) and shape and all(is_int(s) and s > 0 for s in shape),
            f"feature {key!r} shape must be a non-empty list of positive ints, got {shape!r}",
        )
        names = ft.get("names")
        need(names is None or isinstance(names, (list, dict)), f"feature {key!r} names must be a list, dict or null")
        if isinstance(names, list) and len(shape) == 1 and shape != [1]:
            need(len(names) == shape[0], f"feature {key!r} has {len(names)} names for shape {shape}")
        if ft["dtype"] in ("image", "video"):
            need(len(shape) == 3, f"feature {key!r} ({ft['dtype']}) shape must be [H, W, C], got {shape}")
        if ft["dtype"] == "video":
            need(vp is not None, f"feature {key!r} is a video but info.json video_path is null")
    for key, dtype in INDEX_FEATURES.items():
        ft = feats.get(key)
        need(
            isinstance(ft, dict) and ft.get("dtype") == dtype and ft.get("shape") == [1],
            f"feature {key!r} must be {{dtype {dtype}, shape [1]}}, got {ft!r}",
        )
    return feats


def _validate(root: Path) -> dict[str, Any]:
    need(root.is_dir(), "the root directory does not exist")
    info = load_json(root / "meta/info.json", "meta/info.json")
    feats = _check_info(info)
    video_keys = [k for k, f in feats.items() if f["dtype"] == "video"]
    image_keys = [k for k, f in feats.items() if f["dtype"] == "image"]
    _check_stats(load_json(root / "meta/stats.json", "meta/stats.json"), feats)
    task_of = _check_tasks(root, info)
    eps = read_episodes(root, video_keys)
    check_episodes(root, info, eps, video_keys, list(task_of.values()))
    on_disk, ref_paths = check_data_paths(root, info, eps)
    data, file_span = read_data(root, on_disk, ref_paths, feats)
    check_frames(data, info, eps)
    check_episode_rows(data, eps, task_of, file_span, ref_paths)
    return {
        "root": str(root),
        "codebase_version": info["codebase_version"],
        "fps": info["fps"],
        "episodes": eps.n,
        "frames": len(data["index"]),
        "tasks": len(task_of),
        "features": list(feats),
        "image_keys": image_keys,
        "video_keys": video_keys,
        "data_files": [str(p.relative_to(root)) for p in on_disk],
    }


def _check_stats(stats: Any, feats: dict[str, dict[str, Any]]) -> None:
    """meta/stats.json: min / max / mean / std / count per non-string feature, with matching shapes."""
    need(isinstance(stats, dict), "meta/stats.json is not a JSON object")
    for key, ft in feats.items():
        if ft["dtype"] in ("string", "language"):
            continue
        st = stats.get(key)
        need(isinstance(st, dict), f"meta/stats.json has no stats for feature {key!r}")
        for s in STATS:
            need(s in st, f"meta/stats.json {key!r} lacks {s!r}")
        try:
            shapes = {s: np.asarray(st[s], dtype=np.float64).shape for s in STATS}
        except (TypeError, ValueError):
            raise Invalid(f"meta/stats.json {key!r} has non-numeric stats") from None
        need(shapes["count"] == (1,), f"meta/stats.json {key!r} count must be a 1-element list")
        want = None
        if ft["dtype"] in ("image", "video"):
            need(
                all(len(shapes[s]) == 3 and shapes[s][1:] == (1, 1) for s in STATS[:4]),
                f"meta/stats.json {key!r} image stats must have shape (C, 1, 1)",
            )
        elif len(ft["shape"]) == 1:
            want = tuple(ft["shape"])
        if want is not None:
            for s in STATS[:4]:
                need(
                    shapes[s] == want,
                    f"meta/stats.json {key!r} {s} has shape {shapes[s]}, feature shape is {list(want)}",
                )


def _check_tasks(root: Path, info: dict[str, Any]) -> dict[Any, str]:
    """meta/tasks.parquet: unique non-empty tasks indexed 0..n-1; returns {task_index: task}."""
    tasks_path = root / "meta/tasks.parquet"
    need(tasks_path.is_file(), "meta/tasks.parquet is missing")
    tasks_t = read_parquet(tasks_path, "meta/tasks.parquet")
    need(
        {"task_index", "task"} <= set(tasks_t.column_names),
        f"meta/tasks.parquet columns are {tasks_t.column_names}, need task_index and task",
    )
    task_names = tasks_t.column("task").to_pylist()
    task_idx = tasks_t.column("task_index").to_pylist()
    need(all(isinstance(t, str) and t for t in task_names), "meta/tasks.parquet has empty or non-string tasks")
    need(len(set(task_names)) == len(task_names), "meta/tasks.parquet has duplicate tasks")
    need(sorted(task_idx) == list(range(len(task_idx))), "meta/tasks.parquet task_index is not 0..n-1")
    need(
        len(task_names) == info["total_tasks"],
        f"meta/tasks.parquet has {len(task_names)} tasks, info.json total_tasks is {info['total_tasks']}",
    )
    return dict(zip(task_idx, task_names))
