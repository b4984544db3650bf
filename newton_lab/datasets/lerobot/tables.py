"""LeRobot v3.0 layout constants and the arrow / parquet side of the export.

Frame columns (fixed-size float32 lists, PNG image structs, int64 / float32 scalars), per-episode and
dataset stats, the rolling data parquet files, ``meta/episodes`` and ``meta/tasks.parquet``.
"""

from __future__ import annotations

import json
import struct
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

CODEBASE_VERSION = "v3.0"
ROBOT_TYPE = "galbot_g1"
CHUNKS_SIZE = 1000
DATA_FILES_SIZE_IN_MB = 100
VIDEO_FILES_SIZE_IN_MB = 200
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
VIDEO_PATH = "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
EPISODES_PATH = "meta/episodes/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
SOURCE_PATH = "meta/newton_lab_source.json"
IMAGE_PREFIX = "observation.images."
IMAGE_NAMES = ["height", "width", "channels"]
# LeRobot's bookkeeping columns (dtype, shape (1,)), in LeRobot's order.
INDEX_FEATURES = {
    "timestamp": "float32",
    "frame_index": "int64",
    "episode_index": "int64",
    "index": "int64",
    "task_index": "int64",
}
STATS = ("min", "max", "mean", "std", "count")
EPISODE_COLUMNS = (
    "episode_index",
    "tasks",
    "length",
    "data/chunk_index",
    "data/file_index",
    "dataset_from_index",
    "dataset_to_index",
)
TIMESTAMP_TOLERANCE_S = 1e-4  # LeRobot's default tolerance_s
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
PNG_LEVEL = 6
IMAGE_BATCH = 256  # frames per arrow chunk of an image column (keeps binary offsets far below 2 GiB)


# ----------------------------------------------------------------------------- frame columns
def png(image: np.ndarray, level: int = PNG_LEVEL) -> bytes:
    """8-bit RGB PNG of an (H, W, 3) uint8 array; every scanline uses the Paeth filter."""
    h, w, _ = image.shape
    x = image.reshape(h, w * 3).astype(np.int16)
    left = np.zeros_like(x)
    left[:, 3:] = x[:, :-3]
    up = np.zeros_like(x)
    up[1:] = x[:-1]
    up_left = np.zeros_like(x)
    up_left[1:, 3:] = x[:-1, :-3]
    p = left + up - up_left
    da, db, dc = np.abs(p - left), np.abs(p - up), np.abs(p - up_left)
    pred = np.where((da <= db) & (da <= dc), left, np.where(db <= dc, up, up_left))
    rows = np.empty((h, w * 3 + 1), np.uint8)
    rows[:, 0] = 4
    rows[:, 1:] = ((x - pred) & 0xFF).astype(np.uint8)
    return (
        PNG_SIGNATURE
        + _png_chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
        + _png_chunk(b"IDAT", zlib.compress(rows.tobytes(), level))
        + _png_chunk(b"IEND", b"")
    )


def _png_chunk(tag: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + tag + body + struct.pack(">I", zlib.crc32(tag + body) & 0xFFFFFFFF)


def image_column(frames: np.ndarray) -> pa.ChunkedArray:
    """(T, H, W, 3) uint8 frames as LeRobot "image" structs ``{bytes: PNG, path}``."""
    typ = pa.struct([("bytes", pa.binary()), ("path", pa.string())])
    chunks = []
    for lo in range(0, len(frames), IMAGE_BATCH):
        hi = min(lo + IMAGE_BATCH, len(frames))
        chunks.append(
            pa.StructArray.from_arrays(
                [
                    pa.array([png(frames[i]) for i in range(lo, hi)], pa.binary()),
                    pa.array([f"frame-{i:06d}.png" for i in range(lo, hi)], pa.string()),
                ],
                fields=list(typ),
            )
        )
    return pa.chunked_array(chunks, typ)


def _fixed_list(values: np.ndarray) -> pa.FixedSizeListArray:
    return pa.FixedSizeListArray.from_arrays(pa.array(values.reshape(-1), pa.float32()), values.shape[1])


def episode_table(
    state: np.ndarray, actions: np.ndarray, images: dict[str, np.ndarray], fps: int, episode_index: int, start: int
) -> tuple[pa.Table, dict[str, np.ndarray]]:
    """One episode's frame rows (``images`` in feature order, ``start`` = its first global index)."""
    steps = actions.shape[0]
    frame_index = np.arange(steps, dtype=np.int64)
    columns: dict[str, Any] = {"observation.state": _fixed_list(state), "action": _fixed_list(actions)}
    for term, frames in images.items():
        columns[IMAGE_PREFIX + term] = image_column(frames)
    scalars = {
        "timestamp": (frame_index / fps).astype(np.float32),
        "frame_index": frame_index,
        "episode_index": np.full(steps, episode_index, np.int64),
        "index": np.arange(start, start + steps, dtype=np.int64),
        "task_index": np.zeros(steps, np.int64),
    }
    for key, values in scalars.items():
        columns[key] = pa.array(values, pa.from_numpy_dtype(np.dtype(INDEX_FEATURES[key])))
    return pa.table(columns), scalars


# ----------------------------------------------------------------------------- stats
def vector_stats(x: np.ndarray) -> dict[str, np.ndarray]:
    """Per-dimension min / max / mean / std (float64) and count of (T, ...) values."""
    x = np.asarray(x, np.float64).reshape(len(x), -1)
    return {"min": x.min(0), "max": x.max(0), "mean": x.mean(0), "std": x.std(0), "count": np.array([len(x)], np.int64)}


def image_stats(frames: np.ndarray) -> dict[str, np.ndarray]:
    """Per-channel stats of uint8 frames scaled to [0, 1], shaped (3, 1, 1) like LeRobot's."""
    n = frames.shape[0] * frames.shape[1] * frames.shape[2]
    total, squares = np.zeros(3), np.zeros(3)
    for lo in range(0, len(frames), 64):
        px = frames[lo : lo + 64].reshape(-1, 3).astype(np.float64)
        total += px.sum(0)
        squares += np.square(px).sum(0)
    mean = total / n
    std = np.sqrt(np.maximum(squares / n - mean**2, 0.0))
    shape = (3, 1, 1)
    return {
        "min": (frames.min(axis=(0, 1, 2)) / 255.0).reshape(shape),
        "max": (frames.max(axis=(0, 1, 2)) / 255.0).reshape(shape),
        "mean": (mean / 255.0).reshape(shape),
        "std": (std / 255.0).reshape(shape),
        "count": np.array([len(frames)], np.int64),
    }


def aggregate(per_episode: list[dict[str, dict[str, np.ndarray]]]) -> dict[str, dict[str, np.ndarray]]:
    """Dataset stats from per-episode stats (count-weighted mean, pooled variance)."""
    out = {}
    for key in per_episode[0]:
        items = [s[key] for s in per_episode]
        counts = np.array([float(s["count"][0]) for s in items])
        weights = (counts / counts.sum()).reshape(-1, *([1] * items[0]["mean"].ndim))
        means = np.stack([s["mean"] for s in items])
        mean = (weights * means).sum(0)
        var = (weights * (np.stack([s["std"] for s in items]) ** 2 + (means - mean) ** 2)).sum(0)
        out[key] = {
            "min": np.min([s["min"] for s in items], axis=0),
            "max": np.max([s["max"] for s in items], axis=0),
            "mean": mean,
            "std": np.sqrt(np.maximum(var, 0.0)),
            "count": np.array([int(counts.sum())], np.int64),
        }
    return out


# ----------------------------------------------------------------------------- files
class DataFiles:
    """Parquet data files: one row group per episode, rolling to the next file past ``limit_bytes``."""

    def __init__(self, root: Path, limit_bytes: int):
        self.root, self.limit = root, limit_bytes
        self.chunk = self.file = 0
        self.size = 0
        self.writer: pq.ParquetWriter | None = None
        self.paths: list[str] = []

    def write(self, table: pa.Table) -> tuple[int, int]:
        """Append one episode's rows; returns its (chunk_index, file_index)."""
        if self.writer is not None and self.size + table.nbytes > self.limit:
            self.writer.close()
            self.writer = None
            self.file += 1
            if self.file == CHUNKS_SIZE:
                self.chunk, self.file = self.chunk + 1, 0
        if self.writer is None:
            rel = DATA_PATH.format(chunk_index=self.chunk, file_index=self.file)
            (self.root / rel).parent.mkdir(parents=True, exist_ok=True)
            self.writer = pq.ParquetWriter(str(self.root / rel), table.schema, compression="snappy")
            self.paths.append(rel)
            self.size = 0
        self.writer.write_table(table, row_group_size=max(1, table.num_rows))
        self.size += table.nbytes
        return self.chunk, self.file

    def close(self) -> None:
        if self.writer is not None:
            self.writer.close()
            self.writer = None


def write_episodes(path: Path, rows: list[dict[str, Any]], ep_stats: list[dict[str, dict[str, np.ndarray]]]) -> None:
    """meta/episodes parquet: the ``rows`` columns plus ``stats/<feature>/<stat>`` per episode."""
    columns: dict[str, pa.Array] = {}
    for key in rows[0]:
        values = [r[key] for r in rows]
        typ = pa.list_(pa.string()) if key == "tasks" else pa.float64() if isinstance(values[0], float) else pa.int64()
        columns[key] = pa.array(values, typ)
    for feat, stats in ep_stats[0].items():
        for stat, value in stats.items():
            typ: pa.DataType = pa.int64() if stat == "count" else pa.float64()
            for _ in range(value.ndim):
                typ = pa.list_(typ)
            columns[f"stats/{feat}/{stat}"] = pa.array([s[feat][stat].tolist() for s in ep_stats], typ)
    path.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(pa.table(columns), str(path), compression="snappy")


def write_tasks(path: Path, tasks: list[str]) -> None:
    """tasks.parquet as pandas writes a frame indexed by "task" (LeRobot reads it with pandas)."""
    pandas_meta = {
        "index_columns": ["task"],
        "column_indexes": [
            {
                "name": None,
                "field_name": None,
                "pandas_type": "unicode",
                "numpy_type": "object",
                "metadata": {"encoding": "UTF-8"},
            }
        ],
        "columns": [
            {
                "name": "task_index",
                "field_name": "task_index",
                "pandas_type": "int64",
                "numpy_type": "int64",
                "metadata": None,
            },
            {"name": "task", "field_name": "task", "pandas_type": "unicode", "numpy_type": "object", "metadata": None},
        ],
        "attributes": {},
        "creator": {"library": "pyarrow", "version": pa.__version__},
        "pandas_version": "2.2.3",
    }
    schema = pa.schema(
        [("task_index", pa.int64()), ("task", pa.string())], metadata={b"pandas": json.dumps(pandas_meta).encode()}
    )
    table = pa.table(
        {"task_index": pa.array(range(len(tasks)), pa.int64()), "task": pa.array(tasks, pa.string())}, schema=schema
    )
    pq.write_table(table, str(path))
