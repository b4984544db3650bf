"""The validator's checks of meta/episodes, the data files and the videos against each other (``validate``
runs them after the meta checks)."""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from .invalid import Invalid, inside, need, read_parquet
from .tables import EPISODE_COLUMNS, INDEX_FEATURES, PNG_SIGNATURE, TIMESTAMP_TOLERANCE_S
from .video import VIDEO_COLUMNS, probe


@dataclass
class Episodes:
    """meta/episodes: the table, its int columns as arrays (``col``) and each episode's task list."""

    table: pa.Table
    col: dict[str, np.ndarray]
    tasks: list[Any]

    @property
    def n(self) -> int:
        return self.table.num_rows


def read_episodes(root: Path, video_keys: list[str]) -> Episodes:
    """All meta/episodes parquet files, checked for the required columns, as one table."""
    ep_files = sorted((root / "meta/episodes").glob("*/*.parquet"))
    need(ep_files, "meta/episodes/chunk-*/file-*.parquet is missing")
    video_cols = [f"videos/{k}/{c}" for k in video_keys for c in VIDEO_COLUMNS]
    ep_tables = []
    for p in ep_files:
        rel = str(p.relative_to(root))
        names = pq.read_schema(str(p)).names
        missing = [c for c in (*EPISODE_COLUMNS, *video_cols) if c not in names]
        need(not missing, f"{rel} lacks columns {missing}")
        ep_tables.append(read_parquet(p, rel, [*EPISODE_COLUMNS, *video_cols]))
    eps = pa.concat_tables(ep_tables)
    col = {c: np.asarray(eps.column(c).to_numpy(zero_copy_only=False)) for c in EPISODE_COLUMNS if c != "tasks"}
    return Episodes(table=eps, col=col, tasks=eps.column("tasks").to_pylist())


def check_episodes(
    root: Path, info: dict[str, Any], eps: Episodes, video_keys: list[str], task_names: list[str]
) -> None:
    """Episode count, order, lengths, contiguous offsets, tasks and referenced video files."""
    n_eps, col, ep_tasks = eps.n, eps.col, eps.tasks
    need(
        n_eps == info["total_episodes"],
        f"meta/episodes has {n_eps} episodes, info.json total_episodes is {info['total_episodes']}",
    )
    need(np.array_equal(col["episode_index"], np.arange(n_eps)), "meta/episodes episode_index is not 0..E-1 in order")
    lengths, starts, stops = col["length"], col["dataset_from_index"], col["dataset_to_index"]
    for e in range(n_eps):
        need(lengths[e] > 0, f"episode {e} has length {lengths[e]}")
        need(
            stops[e] - starts[e] == lengths[e],
            f"episode {e} offsets [{starts[e]}, {stops[e]}) disagree with its length {lengths[e]}",
        )
        expected_start = 0 if e == 0 else stops[e - 1]
        need(starts[e] == expected_start, f"episode {e} dataset_from_index is {starts[e]}, expected {expected_start}")
        need(
            isinstance(ep_tasks[e], list) and ep_tasks[e] and all(t in task_names for t in ep_tasks[e]),
            f"episode {e} tasks {ep_tasks[e]!r} are not in meta/tasks.parquet",
        )
    total = int(stops[-1]) if n_eps else 0
    need(
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
            need(inside(root, rel, "info.json video_path").is_file(), f"episode {e} video {rel} is missing")
    check_videos(root, info, eps, video_keys)


def check_videos(root: Path, info: dict[str, Any], eps: Episodes, video_keys: list[str]) -> None:
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
                    raise Invalid(f"video {rel} {exc}; export the dataset again") from None
                got = probed[rel]
                need(
                    (got["height"], got["width"]) == (h, w),
                    f"video {rel} is {got['width']}x{got['height']}, feature {k!r} says {w}x{h}",
                )
                need(abs(got["fps"] - fps) < 1e-3, f"video {rel} runs at {got['fps']} fps, info.json fps is {fps}")
            lo, hi = float(column["from_timestamp"][e]), float(column["to_timestamp"][e])
            need(
                abs((hi - lo) * fps - eps.col["length"][e]) < 1e-3 * fps,
                f"episode {e} video span [{lo}, {hi}) s of {k!r} is not its length {eps.col['length'][e]} / {fps} fps",
            )
            need(
                0 <= lo and hi * fps <= probed[rel]["frames"] + 1e-3,
                f"episode {e} video span [{lo}, {hi}) s lies outside {rel} ({probed[rel]['frames']} frames): "
                "the file is truncated; export the dataset again",
            )


def check_data_paths(root: Path, info: dict[str, Any], eps: Episodes) -> tuple[list[Path], dict[tuple[int, int], str]]:
    """Data files on disk == data files referenced by meta/episodes; returns (on disk, {(chunk, file): rel})."""
    on_disk = sorted((root / "data").glob("*/*.parquet"))  # what LeRobot loads
    disk_rel = [str(p.relative_to(root)) for p in on_disk]
    referenced = sorted({(int(c), int(f)) for c, f in zip(eps.col["data/chunk_index"], eps.col["data/file_index"])})
    ref_paths = {(c, f): info["data_path"].format(chunk_index=c, file_index=f) for c, f in referenced}
    for rel in ref_paths.values():
        need(inside(root, rel, "info.json data_path").is_file(), f"{rel} (referenced by meta/episodes) is missing")
        need(rel in disk_rel, f"{rel} (referenced by meta/episodes) is not at data/<chunk>/<file>.parquet")
    extra = [rel for rel in disk_rel if rel not in set(ref_paths.values())]
    need(not extra, f"{extra[0] if extra else ''} is not referenced by any episode")
    return on_disk, ref_paths


def arrow_scalar(dtype: str) -> pa.DataType | None:
    if dtype == "string":
        return pa.string()
    try:
        return pa.from_numpy_dtype(np.dtype(dtype))
    except TypeError:
        return None


def check_column(key: str, ft: dict[str, Any], col: pa.ChunkedArray, rel: str) -> None:
    typ, shape, dtype = col.type, ft["shape"], ft["dtype"]
    where = f"{rel} column {key!r}"
    if dtype == "image":
        need(
            pa.types.is_struct(typ) and typ.get_field_index("bytes") >= 0,
            f"{where} has type {typ}, not an image struct {{bytes, path}}",
        )
        need(col.null_count == 0, f"{where} has null images")
        for i, b in enumerate(col.combine_chunks().field("bytes").to_pylist()):
            need(b, f"{where} row {i} has no image bytes")
            if b[:8] == PNG_SIGNATURE and len(b) >= 24:
                w, h = struct.unpack(">II", b[16:24])
                need((h, w) == (shape[0], shape[1]), f"{where} row {i} is a {h}x{w} PNG, feature shape is {shape}")
        return
    scalar = arrow_scalar(dtype)
    if shape == [1]:
        need(
            scalar is None or typ == scalar or (dtype == "string" and pa.types.is_large_string(typ)),
            f"{where} has type {typ}; feature says {dtype} shape [1]",
        )
        return
    need(
        pa.types.is_list(typ) or pa.types.is_fixed_size_list(typ) or pa.types.is_large_list(typ),
        f"{where} has type {typ}; feature says {dtype} shape {shape}",
    )
    if len(shape) > 1:
        return  # ArrayND features: nested lists / extension types, not checked further
    need(scalar is None or typ.value_type == scalar, f"{where} holds {typ.value_type}, feature says {dtype}")
    if pa.types.is_fixed_size_list(typ):
        need(typ.list_size == shape[0], f"{where} has width {typ.list_size}, feature shape is {shape}")
    else:
        lengths = pc.list_value_length(col).to_numpy(zero_copy_only=False)
        bad = np.nonzero(lengths != shape[0])[0]
        need(
            bad.size == 0,
            f"{where} row {bad[0] if bad.size else 0} has width "
            f"{lengths[bad[0]] if bad.size else 0}, feature shape is {shape}",
        )


def read_data(
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
        need(
            names == expected_cols,
            f"{rel} columns differ from the features: missing "
            f"{sorted(expected_cols - names)}, unexpected {sorted(names - expected_cols)}",
        )
        table = read_parquet(p, rel)
        for key in sorted(expected_cols):
            check_column(key, feats[key], table.column(key), rel)
        for key in INDEX_FEATURES:
            arrays[key].append(table.column(key).to_numpy())
        key = next(k for k, v in ref_paths.items() if v == rel)
        file_span[key] = (row, row + table.num_rows)
        row += table.num_rows
        del table
    data = {k: np.concatenate(v) if v else np.zeros(0) for k, v in arrays.items()}
    return data, file_span


def check_frames(data: dict[str, np.ndarray], info: dict[str, Any], eps: Episodes) -> None:
    """Frame count, contiguous index, episode_index / frame_index per episode, timestamp == frame_index / fps (s)."""
    lengths, starts = eps.col["length"], eps.col["dataset_from_index"]
    n = len(data["index"])
    need(n == info["total_frames"], f"data files hold {n} frames, info.json total_frames is {info['total_frames']}")
    bad = np.nonzero(data["index"] != np.arange(n))[0]
    need(
        bad.size == 0,
        f"index is not contiguous 0..N-1: row {bad[0] if bad.size else 0} has index "
        f"{data['index'][bad[0]] if bad.size else 0}",
    )
    ep_of_row = np.repeat(np.arange(eps.n), lengths)
    bad = np.nonzero(data["episode_index"] != ep_of_row)[0]
    need(
        bad.size == 0,
        f"row {bad[0] if bad.size else 0} has episode_index "
        f"{data['episode_index'][bad[0]] if bad.size else 0}, but meta/episodes puts it in episode "
        f"{ep_of_row[bad[0]] if bad.size else 0}",
    )
    frame = np.arange(n) - np.repeat(starts, lengths)
    bad = np.nonzero(data["frame_index"] != frame)[0]
    need(
        bad.size == 0,
        f"frame_index does not restart at 0 and count up in every episode (row "
        f"{bad[0] if bad.size else 0}, episode {ep_of_row[bad[0]] if bad.size else 0})",
    )
    err = np.abs(data["timestamp"].astype(np.float64) - data["frame_index"] / info["fps"])
    bad = np.nonzero(~(err <= TIMESTAMP_TOLERANCE_S))[0]
    need(
        bad.size == 0,
        f"timestamp != frame_index / fps at row {bad[0] if bad.size else 0} "
        f"(episode {ep_of_row[bad[0]] if bad.size else 0})",
    )


def check_episode_rows(
    data: dict[str, np.ndarray],
    eps: Episodes,
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
        need(
            lo <= starts[e] and stops[e] <= hi,
            f"episode {e} rows [{starts[e]}, {stops[e]}) are not in {ref_paths[(c, f)]} (rows [{lo}, {hi}))",
        )
        used = {task_of.get(int(t)) for t in np.unique(data["task_index"][starts[e] : stops[e]])}
        need(used <= set(ep_tasks[e]), f"episode {e} frames use task_index outside its tasks {ep_tasks[e]!r}")
