"""Structural validator of a LeRobot v3.0 dataset directory: ``validate_lerobot_v3``."""

from __future__ import annotations

import json
import os
import re
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from ..files.inside_root import OutsidePathError, contained
from .tables import CODEBASE_VERSION, EPISODE_COLUMNS, INDEX_FEATURES, PNG_SIGNATURE, STATS, TIMESTAMP_TOLERANCE_S
from .video import VIDEO_COLUMNS, probe


class _Invalid(Exception):
    pass


def _inside(root: Path, rel: str, what: str) -> Path:
    """``root / rel`` for a path taken from info.json; a path leaving ``root`` makes the dataset invalid."""
    try:
        return contained(root, rel, what)
    except OutsidePathError as e:
        raise _Invalid(str(e)) from None


def _need(cond: Any, msg: str) -> None:
    if not cond:
        raise _Invalid(msg)


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


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
    except _Invalid as e:
        raise ValueError(f"{root} is not a valid LeRobot v3.0 dataset: {' '.join(str(e).split())}") from None


def _load_json(path: Path, rel: str) -> Any:
    _need(path.is_file(), f"{rel} is missing")
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as e:
        raise _Invalid(f"{rel} is not readable JSON ({e})") from None


def _read_parquet(path: Path, rel: str, columns: list[str] | None = None) -> pa.Table:
    try:
        return pq.read_table(str(path), columns=columns)
    except (OSError, pa.ArrowException) as e:
        raise _Invalid(f"{rel} is not a readable parquet file with columns {columns or 'any'} ({e})") from None


def _check_info(info: Any) -> dict[str, dict[str, Any]]:
    _need(isinstance(info, dict), "meta/info.json is not a JSON object")
    _need(
        info.get("codebase_version") == CODEBASE_VERSION,
        f"info.json codebase_version is {info.get('codebase_version')!r}, not {CODEBASE_VERSION!r}",
    )
    _need(
        _is_int(info.get("fps")) and info["fps"] > 0, f"info.json fps must be a positive int, got {info.get('fps')!r}"
    )
    for key in ("total_episodes", "total_frames", "total_tasks"):
        _need(_is_int(info.get(key)) and info[key] >= 0, f"info.json {key} must be an int >= 0, got {info.get(key)!r}")
    _need(
        _is_int(info.get("chunks_size")) and info["chunks_size"] > 0,
        f"info.json chunks_size must be a positive int, got {info.get('chunks_size')!r}",
    )
    for key in ("data_files_size_in_mb", "video_files_size_in_mb"):
        v = info.get(key)
        _need(
            isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0,
            f"info.json {key} must be a positive number, got {v!r}",
        )
    dp = info.get("data_path")
    _need(
        isinstance(dp, str) and "{chunk_index" in dp and "{file_index" in dp and dp.endswith(".parquet"),
        f"info.json data_path {dp!r} is not a data/...{{chunk_index}}...{{file_index}}....parquet template",
    )
    vp = info.get("video_path")
    _need(
        vp is None or (isinstance(vp, str) and "{video_key}" in vp and "{chunk_index" in vp),
        f"info.json video_path {vp!r} must be null or a template with {{video_key}} and {{chunk_index}}",
    )
    _need(
        info.get("robot_type") is None or isinstance(info.get("robot_type"), str),
        "info.json robot_type must be a string or null",
    )
    splits = info.get("splits", {})
    _need(
        isinstance(splits, dict) and all(isinstance(v, str) and re.fullmatch(r"\d+:\d+", v) for v in splits.values()),
        f"info.json splits must map names to 'start:stop' strings, got {splits!r}",
    )
    feats = info.get("features")
    _need(isinstance(feats, dict) and feats, "info.json features must be a non-empty object")
    for key, ft in feats.items():
        _need(isinstance(ft, dict) and isinstance(ft.get("dtype"), str), f"feature {key!r} has no dtype string")
        shape = ft.get("shape")
        _need(
            isinstance(shape, list) and shape and all(_is_int(s) and s > 0 for s in shape),
            f"feature {key!r} shape must be a non-empty list of positive ints, got {shape!r}",
        )
        names = ft.get("names")
        _need(names is None or isinstance(names, (list, dict)), f"feature {key!r} names must be a list, dict or null")
        if isinstance(names, list) and len(shape) == 1 and shape != [1]:
            _need(len(names) == shape[0], f"feature {key!r} has {len(names)} names for shape {shape}")
        if ft["dtype"] in ("image", "video"):
            _need(len(shape) == 3, f"feature {key!r} ({ft['dtype']}) shape must be [H, W, C], got {shape}")
        if ft["dtype"] == "video":
            _need(vp is not None, f"feature {key!r} is a video but info.json video_path is null")
    for key, dtype in INDEX_FEATURES.items():
        ft = feats.get(key)
        _need(
            isinstance(ft, dict) and ft.get("dtype") == dtype and ft.get("shape") == [1],
            f"feature {key!r} must be {{dtype {dtype}, shape [1]}}, got {ft!r}",
        )
    return feats


def _arrow_scalar(dtype: str) -> pa.DataType | None:
    if dtype == "string":
        return pa.string()
    try:
        return pa.from_numpy_dtype(np.dtype(dtype))
    except TypeError:
        return None


def _check_column(key: str, ft: dict[str, Any], col: pa.ChunkedArray, rel: str) -> None:
    typ, shape, dtype = col.type, ft["shape"], ft["dtype"]
    where = f"{rel} column {key!r}"
    if dtype == "image":
        _need(
            pa.types.is_struct(typ) and typ.get_field_index("bytes") >= 0,
            f"{where} has type {typ}, not an image struct {{bytes, path}}",
        )
        _need(col.null_count == 0, f"{where} has null images")
        for i, b in enumerate(col.combine_chunks().field("bytes").to_pylist()):
            _need(b, f"{where} row {i} has no image bytes")
            if b[:8] == PNG_SIGNATURE and len(b) >= 24:
                w, h = struct.unpack(">II", b[16:24])
                _need((h, w) == (shape[0], shape[1]), f"{where} row {i} is a {h}x{w} PNG, feature shape is {shape}")
        return
    scalar = _arrow_scalar(dtype)
    if shape == [1]:
        _need(
            scalar is None or typ == scalar or (dtype == "string" and pa.types.is_large_string(typ)),
            f"{where} has type {typ}; feature says {dtype} shape [1]",
        )
        return
    _need(
        pa.types.is_list(typ) or pa.types.is_fixed_size_list(typ) or pa.types.is_large_list(typ),
        f"{where} has type {typ}; feature says {dtype} shape {shape}",
    )
    if len(shape) > 1:
        return  # ArrayND features: nested lists / extension types, not checked further
    _need(scalar is None or typ.value_type == scalar, f"{where} holds {typ.value_type}, feature says {dtype}")
    if pa.types.is_fixed_size_list(typ):
        _need(typ.list_size == shape[0], f"{where} has width {typ.list_size}, feature shape is {shape}")
    else:
        lengths = pc.list_value_length(col).to_numpy(zero_copy_only=False)
        bad = np.nonzero(lengths != shape[0])[0]
        _need(
            bad.size == 0,
            f"{where} row {bad[0] if bad.size else 0} has width "
            f"{lengths[bad[0]] if bad.size else 0}, feature shape is {shape}",
        )


@dataclass
class _Episodes:
    """meta/episodes: the table, its int columns as arrays (``col``) and each episode's task list."""

    table: pa.Table
    col: dict[str, np.ndarray]
    tasks: list[Any]

    @property
    def n(self) -> int:
        return self.table.num_rows


def _validate(root: Path) -> dict[str, Any]:
    _need(root.is_dir(), "the root directory does not exist")
    info = _load_json(root / "meta/info.json", "meta/info.json")
    feats = _check_info(info)
    video_keys = [k for k, f in feats.items() if f["dtype"] == "video"]
    image_keys = [k for k, f in feats.items() if f["dtype"] == "image"]
    _check_stats(_load_json(root / "meta/stats.json", "meta/stats.json"), feats)
    task_of = _check_tasks(root, info)
    eps = _read_episodes(root, video_keys)
    _check_episodes(root, info, eps, video_keys, list(task_of.values()))
    on_disk, ref_paths = _check_data_paths(root, info, eps)
    data, file_span = _read_data(root, on_disk, ref_paths, feats)
    _check_frames(data, info, eps)
    _check_episode_rows(data, eps, task_of, file_span, ref_paths)
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
    _need(isinstance(stats, dict), "meta/stats.json is not a JSON object")
    for key, ft in feats.items():
        if ft["dtype"] in ("string", "language"):
            continue
        st = stats.get(key)
        _need(isinstance(st, dict), f"meta/stats.json has no stats for feature {key!r}")
        for s in STATS:
            _need(s in st, f"meta/stats.json {key!r} lacks {s!r}")
        try:
            shapes = {s: np.asarray(st[s], dtype=np.float64).shape for s in STATS}
        except (TypeError, ValueError):
            raise _Invalid(f"meta/stats.json {key!r} has non-numeric stats") from None
        _need(shapes["count"] == (1,), f"meta/stats.json {key!r} count must be a 1-element list")
        want = None
        if ft["dtype"] in ("image", "video"):
            _need(
                all(len(shapes[s]) == 3 and shapes[s][1:] == (1, 1) for s in STATS[:4]),
                f"meta/stats.json {key!r} image stats must have shape (C, 1, 1)",
            )
        elif len(ft["shape"]) == 1:
            want = tuple(ft["shape"])
        if want is not None:
            for s in STATS[:4]:
                _need(
                    shapes[s] == want,
                    f"meta/stats.json {key!r} {s} has shape {shapes[s]}, feature shape is {list(want)}",
                )


def _check_tasks(root: Path, info: dict[str, Any]) -> dict[Any, str]:
    """meta/tasks.parquet: unique non-empty tasks indexed 0..n-1; returns {task_index: task}."""
    tasks_path = root / "meta/tasks.parquet"
    _need(tasks_path.is_file(), "meta/tasks.parquet is missing")
    tasks_t = _read_parquet(tasks_path, "meta/tasks.parquet")
    _need(
        {"task_index", "task"} <= set(tasks_t.column_names),
        f"meta/tasks.parquet columns are {tasks_t.column_names}, need task_index and task",
    )
    task_names = tasks_t.column("task").to_pylist()
    task_idx = tasks_t.column("task_index").to_pylist()
    _need(all(isinstance(t, str) and t for t in task_names), "meta/tasks.parquet has empty or non-string tasks")
    _need(len(set(task_names)) == len(task_names), "meta/tasks.parquet has duplicate tasks")
    _need(sorted(task_idx) == list(range(len(task_idx))), "meta/tasks.parquet task_index is not 0..n-1")
    _need(
        len(task_names) == info["total_tasks"],
        f"meta/tasks.parquet has {len(task_names)} tasks, info.json total_tasks is {info['total_tasks']}",
    )
    return dict(zip(task_idx, task_names))


def _read_episodes(root: Path, video_keys: list[str]) -> _Episodes:
    """All meta/episodes parquet files, checked for the required columns, as one table."""
    ep_files = sorted((root / "meta/episodes").glob("*/*.parquet"))
    _need(ep_files, "meta/episodes/chunk-*/file-*.parquet is missing")
    video_cols = [f"videos/{k}/{c}" for k in video_keys for c in VIDEO_COLUMNS]
    ep_tables = []
    for p in ep_files:
        rel = str(p.relative_to(root))
        names = pq.read_schema(str(p)).names
        missing = [c for c in (*EPISODE_COLUMNS, *video_cols) if c not in names]
        _need(not missing, f"{rel} lacks columns {missing}")
        ep_tables.append(_read_parquet(p, rel, [*EPISODE_COLUMNS, *video_cols]))
    eps = pa.concat_tables(ep_tables)
    col = {c: np.asarray(eps.column(c).to_numpy(zero_copy_only=False)) for c in EPISODE_COLUMNS if c != "tasks"}
    return _Episodes(table=eps, col=col, tasks=eps.column("tasks").to_pylist())


def _check_episodes(
    root: Path, info: dict[str, Any], eps: _Episodes, video_keys: list[str], task_names: list[str]
) -> None:
    """Episode count, order, lengths, contiguous offsets, tasks and referenced video files."""
    n_eps, col, ep_tasks = eps.n, eps.col, eps.tasks
    _need(
        n_eps == info["total_episodes"],
        f"meta/episodes has {n_eps} episodes, info.json total_episodes is {info['total_episodes']}",
    )
    _need(np.array_equal(col["episode_index"], np.arange(n_eps)), "meta/episodes episode_index is not 0..E-1 in order")
    lengths, starts, stops = col["length"], col["dataset_from_index"], col["dataset_to_index"]
    for e in range(n_eps):
        _need(lengths[e] > 0, f"episode {e} has length {lengths[e]}")
        _need(
            stops[e] - starts[e] == lengths[e],
            f"episode {e} offsets [{starts[e]}, {stops[e]}) disagree with its length {lengths[e]}",
        )
        expected_start = 0 if e == 0 else stops[e - 1]
        _need(starts[e] == expected_start, f"episode {e} dataset_from_index is {starts[e]}, expected {expected_start}")
        _need(
            isinstance(ep_tasks[e], list) and ep_tasks[e] and all(t in task_names for t in ep_tasks[e]),
            f"episode {e} tasks {ep_tasks[e]!r} are not in meta/tasks.parquet",
        )
    total = int(stops[-1]) if n_eps else 0
    _need(
        total == info["total_frames"],
        f"episodes cover {total} frames, info.json total_frames is {info['total_frames']}",
    )
    for e in range(n_eps):
        for k in video_keys:
            rel = info["video_path"].format(
                video_key=k,
                chunk_index=int(eps.table.column(f"videos/{k}/chunk_index")[e].as_py()),
                file_index=int(eps.table.column(f"videos/{k}/file_index")[e].as_py()),
            )
            _need(_inside(root, rel, "info.json video_path").is_file(), f"episode {e} video {rel} is missing")
    _check_videos(root, info, eps, video_keys)


def _check_videos(root: Path, info: dict[str, Any], eps: _Episodes, video_keys: list[str]) -> None:
    """Each referenced mp4 decodes, has the feature's width / height and the dataset's fps, and holds every
    episode's [from_timestamp, to_timestamp) span, which is ``length / fps`` long."""
    fps, probed = info["fps"], {}
    for k in video_keys:
        h, w = info["features"][k]["shape"][:2]
        column = {c: eps.table.column(f"videos/{k}/{c}").to_pylist() for c in VIDEO_COLUMNS}
        for e in range(eps.n):
            rel = info["video_path"].format(
                video_key=k, chunk_index=int(column["chunk_index"][e]), file_index=int(column["file_index"][e])
            )
            if rel not in probed:
                try:
                    probed[rel] = probe(root / rel)
                except ValueError as exc:
                    raise _Invalid(f"video {rel} {exc}; export the dataset again") from None
                got = probed[rel]
                _need(
                    (got["height"], got["width"]) == (h, w),
                    f"video {rel} is {got['width']}x{got['height']}, feature {k!r} says {w}x{h}",
                )
                _need(abs(got["fps"] - fps) < 1e-3, f"video {rel} runs at {got['fps']} fps, info.json fps is {fps}")
            lo, hi = float(column["from_timestamp"][e]), float(column["to_timestamp"][e])
            _need(
                abs((hi - lo) * fps - eps.col["length"][e]) < 1e-3 * fps,
                f"episode {e} video span [{lo}, {hi}) s of {k!r} is not its length {eps.col['length'][e]} / {fps} fps",
            )
            _need(
                0 <= lo and hi * fps <= probed[rel]["frames"] + 1e-3,
                f"episode {e} video span [{lo}, {hi}) s lies outside {rel} ({probed[rel]['frames']} frames): "
                "the file is truncated; export the dataset again",
            )


def _check_data_paths(
    root: Path, info: dict[str, Any], eps: _Episodes
) -> tuple[list[Path], dict[tuple[int, int], str]]:
    """Data files on disk == data files referenced by meta/episodes; returns (on disk, {(chunk, file): rel})."""
    on_disk = sorted((root / "data").glob("*/*.parquet"))  # what LeRobot loads
    disk_rel = [str(p.relative_to(root)) for p in on_disk]
    referenced = sorted({(int(c), int(f)) for c, f in zip(eps.col["data/chunk_index"], eps.col["data/file_index"])})
    ref_paths = {(c, f): info["data_path"].format(chunk_index=c, file_index=f) for c, f in referenced}
    for rel in ref_paths.values():
        _need(_inside(root, rel, "info.json data_path").is_file(), f"{rel} (referenced by meta/episodes) is missing")
        _need(rel in disk_rel, f"{rel} (referenced by meta/episodes) is not at data/<chunk>/<file>.parquet")
    extra = [rel for rel in disk_rel if rel not in set(ref_paths.values())]
    _need(not extra, f"{extra[0] if extra else ''} is not referenced by any episode")
    return on_disk, ref_paths


def _read_data(
    root: Path, on_disk: list[Path], ref_paths: dict[tuple[int, int], str], feats: dict[str, dict[str, Any]]
) -> tuple[dict[str, np.ndarray], dict[tuple[int, int], tuple[int, int]]]:
    """Check every data file's columns; returns (index columns of all files, {(chunk, file): row span})."""
    expected_cols = {k for k, f in feats.items() if f["dtype"] != "video"}
    file_span: dict[tuple[int, int], tuple[int, int]] = {}
    arrays: dict[str, list[np.ndarray]] = {k: [] for k in INDEX_FEATURES}
    row = 0
    for p in on_disk:  # LeRobot concatenates the data files in sorted path order
        rel = str(p.relative_to(root))
        schema = pq.read_schema(str(p))
        names = set(schema.names)
        _need(
            names == expected_cols,
            f"{rel} columns differ from the features: missing "
            f"{sorted(expected_cols - names)}, unexpected {sorted(names - expected_cols)}",
        )
        table = _read_parquet(p, rel)
        for key in sorted(expected_cols):
            _check_column(key, feats[key], table.column(key), rel)
        for key in INDEX_FEATURES:
            arrays[key].append(table.column(key).to_numpy())
        key = next(k for k, v in ref_paths.items() if v == rel)
        file_span[key] = (row, row + table.num_rows)
        row += table.num_rows
        del table
    data = {k: np.concatenate(v) if v else np.zeros(0) for k, v in arrays.items()}
    return data, file_span


def _check_frames(data: dict[str, np.ndarray], info: dict[str, Any], eps: _Episodes) -> None:
    """Frame count, contiguous index, episode_index / frame_index per episode, timestamp == frame_index / fps (s)."""
    lengths, starts = eps.col["length"], eps.col["dataset_from_index"]
    n = len(data["index"])
    _need(n == info["total_frames"], f"data files hold {n} frames, info.json total_frames is {info['total_frames']}")
    bad = np.nonzero(data["index"] != np.arange(n))[0]
    _need(
        bad.size == 0,
        f"index is not contiguous 0..N-1: row {bad[0] if bad.size else 0} has index "
        f"{data['index'][bad[0]] if bad.size else 0}",
    )
    ep_of_row = np.repeat(np.arange(eps.n), lengths)
    bad = np.nonzero(data["episode_index"] != ep_of_row)[0]
    _need(
        bad.size == 0,
        f"row {bad[0] if bad.size else 0} has episode_index "
        f"{data['episode_index'][bad[0]] if bad.size else 0}, but meta/episodes puts it in episode "
        f"{ep_of_row[bad[0]] if bad.size else 0}",
    )
    frame = np.arange(n) - np.repeat(starts, lengths)
    bad = np.nonzero(data["frame_index"] != frame)[0]
    _need(
        bad.size == 0,
        f"frame_index does not restart at 0 and count up in every episode (row "
        f"{bad[0] if bad.size else 0}, episode {ep_of_row[bad[0]] if bad.size else 0})",
    )
    err = np.abs(data["timestamp"].astype(np.float64) - data["frame_index"] / info["fps"])
    bad = np.nonzero(~(err <= TIMESTAMP_TOLERANCE_S))[0]
    _need(
        bad.size == 0,
        f"timestamp != frame_index / fps at row {bad[0] if bad.size else 0} "
        f"(episode {ep_of_row[bad[0]] if bad.size else 0})",
    )


def _check_episode_rows(
    data: dict[str, np.ndarray],
    eps: _Episodes,
    task_of: dict[Any, str],
    file_span: dict[tuple[int, int], tuple[int, int]],
    ref_paths: dict[tuple[int, int], str],
) -> None:
    """Every episode's rows lie in its data file and use only its tasks."""
    col, ep_tasks = eps.col, eps.tasks
    starts, stops = col["dataset_from_index"], col["dataset_to_index"]
    for e in range(eps.n):
        c, f = int(col["data/chunk_index"][e]), int(col["data/file_index"][e])
        lo, hi = file_span[(c, f)]
        _need(
            lo <= starts[e] and stops[e] <= hi,
            f"episode {e} rows [{starts[e]}, {stops[e]}) are not in {ref_paths[(c, f)]} (rows [{lo}, {hi}))",
        )
        used = {task_of.get(int(t)) for t in np.unique(data["task_index"][starts[e] : stops[e]])}
        _need(used <= set(ep_tasks[e]), f"episode {e} frames use task_index outside its tasks {ep_tasks[e]!r}")
