"""Export newton_lab datasets to the LeRobot v3.0 layout (pyarrow only) and check such layouts.

``export_lerobot(dataset, root)`` turns the committed demos of an HDF5 / zarr dataset into::

    root/meta/info.json                                  schema, fps, counts, path templates
    root/meta/stats.json                                 per feature min / max / mean / std / count
    root/meta/tasks.parquet                              task_index, task (pandas index "task")
    root/meta/episodes/chunk-000/file-000.parquet        one row per episode: offsets, tasks, stats/...
    root/meta/newton_lab_source.json                     provenance: source path, exported demo ids
    root/data/chunk-000/file-000.parquet                 one row per frame, one row group per episode

Per frame: ``observation.state`` (float32, the concatenated low-dim obs terms), ``action`` (float32),
``observation.images.<term>`` for every uint8 (T, H, W, 3) obs term (PNG bytes in a ``{bytes, path}``
struct: LeRobot's "image" feature, no video), ``timestamp`` (frame_index / fps), ``frame_index``,
``episode_index``, ``index`` and ``task_index``. Data files roll over past ``data_files_size_in_mb``
(uncompressed bytes, like LeRobot); an episode never spans two files.

The export is written into a hidden sibling directory (``.<root name>.partial-*``) and renamed into
place at the end, so ``root`` either holds a complete dataset or does not exist (a killed export can
leave the hidden sibling behind; delete it).

``validate_lerobot_v3(root)`` checks a v3.0 layout structurally (files, info.json, schemas, offsets,
index / frame_index / timestamp consistency) and raises a one-line ``ValueError`` on the first problem.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import struct
import uuid
import zlib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

try:
    import pyarrow as pa
    import pyarrow.parquet as pq
except ImportError as exc:  # pragma: no cover - pyarrow is the "lerobot" extra
    raise ImportError("newton_lab.datasets.lerobot needs pyarrow: pip install 'newton_lab[lerobot]'") from exc

from ._common import fsync_path
from .storage import read_dataset_info, read_episode

__all__ = ["export_lerobot", "validate_lerobot_v3", "CODEBASE_VERSION", "ROBOT_TYPE"]

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
INDEX_FEATURES = {"timestamp": "float32", "frame_index": "int64", "episode_index": "int64",
                  "index": "int64", "task_index": "int64"}
STATS = ("min", "max", "mean", "std", "count")
EPISODE_COLUMNS = ("episode_index", "tasks", "length", "data/chunk_index", "data/file_index",
                   "dataset_from_index", "dataset_to_index")
TIMESTAMP_TOLERANCE_S = 1e-4  # LeRobot's default tolerance_s
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
PNG_LEVEL = 6
IMAGE_BATCH = 256  # frames per arrow chunk of an image column (keeps binary offsets far below 2 GiB)


# ============================================================================ export
@dataclass
class _Plan:
    """Everything decided before the first byte is written."""

    source: Path
    source_format: str
    task_id: str
    repo_id: str
    task: str
    fps: int
    demo_ids: list[int]
    skipped_failed: list[int]
    skipped_empty: list[int]
    state_terms: list[tuple[str, int]]  # (obs term, width), in state column order
    action_dim: int
    action_names: list[str]
    image_terms: list[tuple[str, tuple[int, int, int]]]  # (obs term, (H, W, 3))
    ignored_terms: list[str] = field(default_factory=list)

    @property
    def state_dim(self) -> int:
        return sum(w for _, w in self.state_terms)

    def features(self) -> dict[str, dict[str, Any]]:
        feats: dict[str, dict[str, Any]] = {
            "observation.state": {"dtype": "float32", "shape": [self.state_dim],
                                  "names": [f"{t}.{i}" for t, w in self.state_terms for i in range(w)]},
            "action": {"dtype": "float32", "shape": [self.action_dim], "names": list(self.action_names)},
        }
        for term, shape in self.image_terms:
            feats[IMAGE_PREFIX + term] = {"dtype": "image", "shape": list(shape), "names": list(IMAGE_NAMES)}
        for key, dtype in INDEX_FEATURES.items():
            feats[key] = {"dtype": dtype, "shape": [1], "names": None}
        return feats


def export_lerobot(dataset: Any, root: str | os.PathLike, *, repo_id: str | None = None, fps: int | None = None,
                   include_failed: bool = False, state_keys: Sequence[str] | None = None,
                   task_description: str | None = None,
                   data_files_size_in_mb: int = DATA_FILES_SIZE_IN_MB) -> dict[str, Any]:
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

    Returns:
        ``{"root", "repo_id", "episodes", "frames", "skipped_failed", "fps", "task", "demo_ids",
        "skipped_empty", "state_keys", "image_keys", "data_files"}``; ``demo_ids[i]`` is the source
        demo of LeRobot episode ``i``.
    """
    root = Path(root).expanduser()
    _refuse_existing(root)
    source = _source_path(dataset)
    if not (isinstance(data_files_size_in_mb, int) and not isinstance(data_files_size_in_mb, bool)
            and data_files_size_in_mb > 0):
        raise ValueError(f"data_files_size_in_mb must be a positive int, got {data_files_size_in_mb!r}")
    info = read_dataset_info(source)
    _refuse_nested(root, Path(info["path"]))
    plan, first = _make_plan(info, repo_id=repo_id, fps=fps, include_failed=include_failed,
                             state_keys=state_keys, task_description=task_description)

    root.parent.mkdir(parents=True, exist_ok=True)
    tmp = root.parent / f".{root.name}.partial-{uuid.uuid4().hex}"
    tmp.mkdir()  # not mkdtemp: the renamed root should get the usual (umask) permissions
    try:
        data_files, frames = _write_all(tmp, plan, first, data_files_size_in_mb * 1024 * 1024,
                                        data_files_size_in_mb)
        _fsync_tree(tmp)
        _refuse_existing(root)  # created by someone else meanwhile: keep theirs, drop ours
        os.rename(tmp, root)
        fsync_path(root.parent)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return {"root": str(root), "repo_id": plan.repo_id, "episodes": len(plan.demo_ids), "frames": frames,
            "skipped_failed": len(plan.skipped_failed), "fps": plan.fps, "task": plan.task,
            "demo_ids": list(plan.demo_ids), "skipped_empty": len(plan.skipped_empty),
            "state_keys": [t for t, _ in plan.state_terms],
            "image_keys": [IMAGE_PREFIX + t for t, _ in plan.image_terms], "data_files": data_files}


# ----------------------------------------------------------------------------- argument checks
def _refuse_existing(root: Path) -> None:
    if os.path.lexists(root):
        raise FileExistsError(f"LeRobot root {root} already exists; choose a new root or delete it "
                              "(nothing was written)")


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
    raise TypeError(f"dataset must be a path or an object with a .path attribute (e.g. a DatasetRef), "
                    f"got {type(dataset).__name__}")


def _resolve_fps(fps: Any, nl: Mapping[str, Any], source: Path) -> int:
    if fps is None:
        try:
            period = float(nl["sim_dt"]) * int(nl["decimation"])
            value: Any = 1.0 / period
        except (KeyError, TypeError, ValueError, ZeroDivisionError):
            raise ValueError(f"{source} has no usable env_args['newton_lab'] sim_dt/decimation to derive the "
                             "frame rate from; pass fps=<int>") from None
        what = f"the control rate 1/(sim_dt*decimation) = {value:.6g} Hz of {source}"
    else:
        value, what = fps, f"fps={fps!r}"
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{what} is not a number; pass fps=<positive int>")
    value = float(value)
    if not math.isfinite(value) or round(value) < 1 or abs(value - round(value)) > 1e-6 * round(value):
        raise ValueError(f"{what} is not a positive whole number; LeRobot needs an integer fps: pass fps=<int>")
    return int(round(value))


def _text(value: Any, name: str) -> str:
    if not isinstance(value, str) or not value.strip():
        raise ValueError(f"{name} must be a non-empty str, got {value!r}")
    return value


def _obs_kind(arr: np.ndarray) -> str:
    if arr.ndim == 4 and arr.shape[-1] == 3 and arr.dtype == np.uint8:
        return "image"
    if arr.ndim in (1, 2) and arr.dtype.kind in "biuf":
        return "vector"
    return "other"


def _obs_order(nl: Mapping[str, Any], present: Iterable[str]) -> list[str]:
    """Obs terms in the env's column order (env_args obs_terms starts), then any others by name."""
    declared = nl.get("obs_terms") if isinstance(nl.get("obs_terms"), Mapping) else {}

    def start(name: str) -> float:
        span = declared.get(name)
        try:
            return float(span[0])
        except (TypeError, ValueError, IndexError, KeyError):
            return math.inf

    present = list(present)
    known = sorted((t for t in present if t in declared), key=lambda t: (start(t), t))
    return known + sorted(t for t in present if t not in declared)


def _make_plan(info: dict[str, Any], *, repo_id, fps, include_failed, state_keys,
               task_description) -> tuple[_Plan, dict[str, Any]]:
    source, task_id = Path(info["path"]), info["task_id"]
    nl = info["env_args"].get("newton_lab")
    nl = nl if isinstance(nl, Mapping) else {}
    fps_i = _resolve_fps(fps, nl, source)
    repo = _text(repo_id, "repo_id") if repo_id is not None else f"newton_lab/{task_id.lower()}"
    task = _text(task_description, "task_description") if task_description is not None else task_id
    if state_keys is not None and (isinstance(state_keys, (str, bytes)) or not isinstance(state_keys, Iterable)):
        raise TypeError(f"state_keys must be a list of obs term names, got {state_keys!r}")

    demos = info["demos"]
    failed = [i for i, d in demos.items() if not d["success"]]
    candidates = [i for i, d in demos.items() if include_failed or d["success"]]
    empty = [i for i in candidates if demos[i]["num_samples"] < 1]
    chosen = [i for i in candidates if demos[i]["num_samples"] >= 1]
    if not chosen:
        hint = "" if include_failed or not failed else " (pass include_failed=True to export the failed ones)"
        raise ValueError(f"{source} has no episodes to export: {len(demos)} demos, {len(failed)} failed, "
                         f"{len(empty)} empty{hint}")

    first = read_episode(source, chosen[0])
    obs = {k: np.asarray(v) for k, v in first.get("obs", {}).items() if not isinstance(v, Mapping)}
    kinds = {k: _obs_kind(v) for k, v in obs.items()}
    order = _obs_order(nl, obs)
    where = f"demo_{chosen[0]} of {source}"
    if state_keys is None:
        state = [t for t in order if kinds[t] == "vector" and t != "actions"]
        if not state:
            raise ValueError(f"{where} has no (T, d) obs term for observation.state; pass state_keys=[...]")
    else:
        state = [str(t) for t in state_keys]
        if not state:
            raise ValueError("state_keys is empty; name at least one obs term")
        if len(set(state)) != len(state):
            raise ValueError(f"state_keys has duplicates: {state}")
        for t in state:
            if t not in obs:
                raise ValueError(f"state_keys: no obs term {t!r} in {where}; available: {', '.join(order) or 'none'}")
            if kinds[t] == "image":
                raise ValueError(f"state_keys: {t!r} is an image term (exported as {IMAGE_PREFIX}{t}), "
                                 "not a (T, d) state term")
            if kinds[t] != "vector":
                raise ValueError(f"state_keys: obs term {t!r} has shape {obs[t].shape} dtype {obs[t].dtype}, "
                                 "not a real (T, d) array")
    actions = np.asarray(first["actions"])
    a_dim = int(actions.shape[1])
    names = nl.get("action_joint_names")
    if not (isinstance(names, list) and len(names) == a_dim and all(isinstance(n, str) for n in names)):
        names = [f"action.{i}" for i in range(a_dim)]
    images = [(t, tuple(int(s) for s in obs[t].shape[1:])) for t in order if kinds[t] == "image"]
    ignored = [t for t in order if kinds[t] == "other" or (kinds[t] == "vector" and t not in state)]
    plan = _Plan(source=source, source_format=info["format"], task_id=task_id, repo_id=repo, task=task,
                 fps=fps_i, demo_ids=chosen, skipped_failed=[] if include_failed else failed,
                 skipped_empty=empty, state_terms=[(t, 1 if obs[t].ndim == 1 else int(obs[t].shape[1])) for t in state],
                 action_dim=a_dim, action_names=list(names), image_terms=images, ignored_terms=ignored)
    return plan, first


# ----------------------------------------------------------------------------- per-episode data
def _episode_arrays(ep: Mapping[str, Any], plan: _Plan, demo_id: int) -> tuple[np.ndarray, np.ndarray, dict]:
    where = f"demo_{demo_id} of {plan.source}"
    actions = np.asarray(ep["actions"])
    if actions.ndim != 2 or actions.shape[1] != plan.action_dim:
        raise ValueError(f"{where}: actions have shape {actions.shape}; expected (T, {plan.action_dim}) like "
                         f"demo_{plan.demo_ids[0]}")
    steps = actions.shape[0]
    obs = ep.get("obs", {})
    parts = []
    for term, width in plan.state_terms:
        if term not in obs or isinstance(obs[term], Mapping):
            raise ValueError(f"{where} has no obs term {term!r} (needed for observation.state)")
        arr = np.asarray(obs[term])
        arr = arr.reshape(-1, 1) if arr.ndim == 1 else arr
        if arr.ndim != 2 or arr.shape != (steps, width):
            raise ValueError(f"{where}: obs term {term!r} has shape {arr.shape}; expected ({steps}, {width})")
        parts.append(arr.astype(np.float32, copy=False))
    images = {}
    for term, shape in plan.image_terms:
        arr = np.asarray(obs.get(term)) if term in obs else None
        if arr is None or arr.dtype != np.uint8 or arr.shape != (steps, *shape):
            got = "missing" if arr is None else f"{arr.dtype} {arr.shape}"
            raise ValueError(f"{where}: image obs term {term!r} is {got}; expected uint8 {(steps, *shape)}")
        images[term] = arr
    state = np.ascontiguousarray(np.concatenate(parts, axis=1), dtype=np.float32)
    return state, np.ascontiguousarray(actions, dtype=np.float32), images


def _png(image: np.ndarray, level: int = PNG_LEVEL) -> bytes:
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

    def chunk(tag: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + tag + body + struct.pack(">I", zlib.crc32(tag + body) & 0xFFFFFFFF)

    return (PNG_SIGNATURE + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(rows.tobytes(), level)) + chunk(b"IEND", b""))


def _image_column(frames: np.ndarray) -> pa.ChunkedArray:
    typ = pa.struct([("bytes", pa.binary()), ("path", pa.string())])
    chunks = []
    for lo in range(0, len(frames), IMAGE_BATCH):
        hi = min(lo + IMAGE_BATCH, len(frames))
        chunks.append(pa.StructArray.from_arrays(
            [pa.array([_png(frames[i]) for i in range(lo, hi)], pa.binary()),
             pa.array([f"frame-{i:06d}.png" for i in range(lo, hi)], pa.string())], fields=list(typ)))
    return pa.chunked_array(chunks, typ)


def _fixed_list(values: np.ndarray) -> pa.FixedSizeListArray:
    return pa.FixedSizeListArray.from_arrays(pa.array(values.reshape(-1), pa.float32()), values.shape[1])


def _episode_table(plan: _Plan, state: np.ndarray, actions: np.ndarray, images: dict,
                   episode_index: int, start: int) -> tuple[pa.Table, dict[str, np.ndarray]]:
    steps = actions.shape[0]
    frame_index = np.arange(steps, dtype=np.int64)
    columns: dict[str, Any] = {"observation.state": _fixed_list(state), "action": _fixed_list(actions)}
    for term, _ in plan.image_terms:
        columns[IMAGE_PREFIX + term] = _image_column(images[term])
    scalars = {"timestamp": (frame_index / plan.fps).astype(np.float32), "frame_index": frame_index,
               "episode_index": np.full(steps, episode_index, np.int64),
               "index": np.arange(start, start + steps, dtype=np.int64),
               "task_index": np.zeros(steps, np.int64)}
    for key, values in scalars.items():
        columns[key] = pa.array(values, pa.from_numpy_dtype(np.dtype(INDEX_FEATURES[key])))
    return pa.table(columns), scalars


# ----------------------------------------------------------------------------- stats
def _vector_stats(x: np.ndarray) -> dict[str, np.ndarray]:
    x = np.asarray(x, np.float64).reshape(len(x), -1)
    return {"min": x.min(0), "max": x.max(0), "mean": x.mean(0), "std": x.std(0),
            "count": np.array([len(x)], np.int64)}


def _image_stats(frames: np.ndarray) -> dict[str, np.ndarray]:
    """Per-channel stats of uint8 frames scaled to [0, 1], shaped (3, 1, 1) like LeRobot's."""
    n = frames.shape[0] * frames.shape[1] * frames.shape[2]
    total, squares = np.zeros(3), np.zeros(3)
    for lo in range(0, len(frames), 64):
        px = frames[lo:lo + 64].reshape(-1, 3).astype(np.float64)
        total += px.sum(0)
        squares += np.square(px).sum(0)
    mean = total / n
    std = np.sqrt(np.maximum(squares / n - mean**2, 0.0))
    shape = (3, 1, 1)
    return {"min": (frames.min(axis=(0, 1, 2)) / 255.0).reshape(shape),
            "max": (frames.max(axis=(0, 1, 2)) / 255.0).reshape(shape),
            "mean": (mean / 255.0).reshape(shape), "std": (std / 255.0).reshape(shape),
            "count": np.array([len(frames)], np.int64)}


def _aggregate(per_episode: list[dict[str, dict[str, np.ndarray]]]) -> dict[str, dict[str, np.ndarray]]:
    """Dataset stats from per-episode stats (count-weighted mean, pooled variance)."""
    out = {}
    for key in per_episode[0]:
        items = [s[key] for s in per_episode]
        counts = np.array([float(s["count"][0]) for s in items])
        weights = (counts / counts.sum()).reshape(-1, *([1] * items[0]["mean"].ndim))
        means = np.stack([s["mean"] for s in items])
        mean = (weights * means).sum(0)
        var = (weights * (np.stack([s["std"] for s in items]) ** 2 + (means - mean) ** 2)).sum(0)
        out[key] = {"min": np.min([s["min"] for s in items], axis=0), "max": np.max([s["max"] for s in items], axis=0),
                    "mean": mean, "std": np.sqrt(np.maximum(var, 0.0)),
                    "count": np.array([int(counts.sum())], np.int64)}
    return out


# ----------------------------------------------------------------------------- writing
class _DataFiles:
    """Parquet data files: one row group per episode, rolling to the next file past the size limit."""

    def __init__(self, root: Path, limit_bytes: int):
        self.root, self.limit = root, limit_bytes
        self.chunk = self.file = 0
        self.size = 0
        self.writer: pq.ParquetWriter | None = None
        self.paths: list[str] = []

    def write(self, table: pa.Table) -> tuple[int, int]:
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


def _write_all(tmp: Path, plan: _Plan, first: dict[str, Any], limit_bytes: int,
               limit_mb: int) -> tuple[list[str], int]:
    files = _DataFiles(tmp, limit_bytes)
    rows: list[dict[str, Any]] = []
    ep_stats: list[dict[str, dict[str, np.ndarray]]] = []
    start = 0
    try:
        for episode_index, demo_id in enumerate(plan.demo_ids):
            ep = first if episode_index == 0 else read_episode(plan.source, demo_id)
            state, actions, images = _episode_arrays(ep, plan, demo_id)
            del ep
            table, scalars = _episode_table(plan, state, actions, images, episode_index, start)
            chunk, file = files.write(table)
            del table
            stats = {"observation.state": _vector_stats(state), "action": _vector_stats(actions)}
            stats.update({IMAGE_PREFIX + t: _image_stats(images[t]) for t, _ in plan.image_terms})
            stats.update({k: _vector_stats(v) for k, v in scalars.items()})
            steps = len(actions)
            rows.append({"episode_index": episode_index, "tasks": [plan.task], "length": steps,
                         "data/chunk_index": chunk, "data/file_index": file,
                         "dataset_from_index": start, "dataset_to_index": start + steps,
                         "meta/episodes/chunk_index": 0, "meta/episodes/file_index": 0})
            ep_stats.append(stats)
            start += steps
        first.clear()
    finally:
        files.close()

    meta = tmp / "meta"
    meta.mkdir()
    _write_episodes(tmp / EPISODES_PATH.format(chunk_index=0, file_index=0), rows, ep_stats)
    _write_tasks(meta / "tasks.parquet", [plan.task])
    stats = _aggregate(ep_stats)
    _write_json(meta / "stats.json", {k: {s: v.tolist() for s, v in st.items()} for k, st in stats.items()})
    info = {
        "codebase_version": CODEBASE_VERSION, "robot_type": ROBOT_TYPE,
        "total_episodes": len(rows), "total_frames": start, "total_tasks": 1,
        "chunks_size": CHUNKS_SIZE, "data_files_size_in_mb": limit_mb,
        "video_files_size_in_mb": VIDEO_FILES_SIZE_IN_MB, "fps": plan.fps,
        "splits": {"train": f"0:{len(rows)}"}, "data_path": DATA_PATH, "video_path": None,
        "features": plan.features(),
    }
    _write_json(meta / "info.json", info)
    _write_json(tmp / SOURCE_PATH, {
        "exporter": "newton_lab.datasets.lerobot", "source": str(plan.source), "source_format": plan.source_format,
        "task_id": plan.task_id, "demo_ids": plan.demo_ids, "skipped_failed_demo_ids": plan.skipped_failed,
        "skipped_empty_demo_ids": plan.skipped_empty, "state_keys": [t for t, _ in plan.state_terms],
        "image_terms": [t for t, _ in plan.image_terms], "ignored_obs_terms": plan.ignored_terms,
    })
    return files.paths, start


def _write_json(path: Path, obj: Any) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(obj, indent=4) + "\n")


def _write_episodes(path: Path, rows: list[dict[str, Any]], ep_stats: list[dict[str, dict[str, np.ndarray]]]) -> None:
    columns: dict[str, pa.Array] = {}
    for key in rows[0]:
        values = [r[key] for r in rows]
        columns[key] = pa.array(values, pa.list_(pa.string()) if key == "tasks" else pa.int64())
    for feat, stats in ep_stats[0].items():
        for stat, value in stats.items():
            typ: pa.DataType = pa.int64() if stat == "count" else pa.float64()
            for _ in range(value.ndim):
                typ = pa.list_(typ)
            columns[f"stats/{feat}/{stat}"] = pa.array([s[feat][stat].tolist() for s in ep_stats], typ)
    path.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(pa.table(columns), str(path), compression="snappy")


def _write_tasks(path: Path, tasks: list[str]) -> None:
    """tasks.parquet as pandas writes a frame indexed by "task" (LeRobot reads it with pandas)."""
    pandas_meta = {
        "index_columns": ["task"],
        "column_indexes": [{"name": None, "field_name": None, "pandas_type": "unicode", "numpy_type": "object",
                            "metadata": {"encoding": "UTF-8"}}],
        "columns": [{"name": "task_index", "field_name": "task_index", "pandas_type": "int64",
                     "numpy_type": "int64", "metadata": None},
                    {"name": "task", "field_name": "task", "pandas_type": "unicode", "numpy_type": "object",
                     "metadata": None}],
        "attributes": {}, "creator": {"library": "pyarrow", "version": pa.__version__}, "pandas_version": "2.2.3",
    }
    schema = pa.schema([("task_index", pa.int64()), ("task", pa.string())],
                       metadata={b"pandas": json.dumps(pandas_meta).encode()})
    table = pa.table({"task_index": pa.array(range(len(tasks)), pa.int64()), "task": pa.array(tasks, pa.string())},
                     schema=schema)
    pq.write_table(table, str(path))


def _fsync_tree(top: Path) -> None:
    for dirpath, _, names in os.walk(top):
        for name in names:
            fsync_path(Path(dirpath, name))
        fsync_path(Path(dirpath))


# ============================================================================ validation
class _Invalid(Exception):
    pass


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
    that the referenced video files exist (their content is not decoded).

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
    _need(info.get("codebase_version") == CODEBASE_VERSION,
          f"info.json codebase_version is {info.get('codebase_version')!r}, not {CODEBASE_VERSION!r}")
    _need(_is_int(info.get("fps")) and info["fps"] > 0,
          f"info.json fps must be a positive int, got {info.get('fps')!r}")
    for key in ("total_episodes", "total_frames", "total_tasks"):
        _need(_is_int(info.get(key)) and info[key] >= 0, f"info.json {key} must be an int >= 0, got {info.get(key)!r}")
    _need(_is_int(info.get("chunks_size")) and info["chunks_size"] > 0,
          f"info.json chunks_size must be a positive int, got {info.get('chunks_size')!r}")
    for key in ("data_files_size_in_mb", "video_files_size_in_mb"):
        v = info.get(key)
        _need(isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0,
              f"info.json {key} must be a positive number, got {v!r}")
    dp = info.get("data_path")
    _need(isinstance(dp, str) and "{chunk_index" in dp and "{file_index" in dp and dp.endswith(".parquet"),
          f"info.json data_path {dp!r} is not a data/...{{chunk_index}}...{{file_index}}....parquet template")
    vp = info.get("video_path")
    _need(vp is None or (isinstance(vp, str) and "{video_key}" in vp and "{chunk_index" in vp),
          f"info.json video_path {vp!r} must be null or a template with {{video_key}} and {{chunk_index}}")
    _need(info.get("robot_type") is None or isinstance(info.get("robot_type"), str),
          "info.json robot_type must be a string or null")
    splits = info.get("splits", {})
    _need(isinstance(splits, dict) and all(isinstance(v, str) and re.fullmatch(r"\d+:\d+", v) for v in splits.values()),
          f"info.json splits must map names to 'start:stop' strings, got {splits!r}")
    feats = info.get("features")
    _need(isinstance(feats, dict) and feats, "info.json features must be a non-empty object")
    for key, ft in feats.items():
        _need(isinstance(ft, dict) and isinstance(ft.get("dtype"), str), f"feature {key!r} has no dtype string")
        shape = ft.get("shape")
        _need(isinstance(shape, list) and shape and all(_is_int(s) and s > 0 for s in shape),
              f"feature {key!r} shape must be a non-empty list of positive ints, got {shape!r}")
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
        _need(isinstance(ft, dict) and ft.get("dtype") == dtype and ft.get("shape") == [1],
              f"feature {key!r} must be {{dtype {dtype}, shape [1]}}, got {ft!r}")
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
        _need(pa.types.is_struct(typ) and typ.get_field_index("bytes") >= 0,
              f"{where} has type {typ}, not an image struct {{bytes, path}}")
        _need(col.null_count == 0, f"{where} has null images")
        for i, b in enumerate(col.combine_chunks().field("bytes").to_pylist()):
            _need(b, f"{where} row {i} has no image bytes")
            if b[:8] == PNG_SIGNATURE and len(b) >= 24:
                w, h = struct.unpack(">II", b[16:24])
                _need((h, w) == (shape[0], shape[1]), f"{where} row {i} is a {h}x{w} PNG, feature shape is {shape}")
        return
    scalar = _arrow_scalar(dtype)
    if shape == [1]:
        _need(scalar is None or typ == scalar or (dtype == "string" and pa.types.is_large_string(typ)),
              f"{where} has type {typ}; feature says {dtype} shape [1]")
        return
    _need(pa.types.is_list(typ) or pa.types.is_fixed_size_list(typ) or pa.types.is_large_list(typ),
          f"{where} has type {typ}; feature says {dtype} shape {shape}")
    if len(shape) > 1:
        return  # ArrayND features: nested lists / extension types, not checked further
    _need(scalar is None or typ.value_type == scalar, f"{where} holds {typ.value_type}, feature says {dtype}")
    if pa.types.is_fixed_size_list(typ):
        _need(typ.list_size == shape[0], f"{where} has width {typ.list_size}, feature shape is {shape}")
    else:
        import pyarrow.compute as pc

        lengths = pc.list_value_length(col).to_numpy(zero_copy_only=False)
        bad = np.nonzero(lengths != shape[0])[0]
        _need(bad.size == 0, f"{where} row {bad[0] if bad.size else 0} has width "
              f"{lengths[bad[0]] if bad.size else 0}, feature shape is {shape}")


def _validate(root: Path) -> dict[str, Any]:
    _need(root.is_dir(), "the root directory does not exist")
    info = _load_json(root / "meta/info.json", "meta/info.json")
    feats = _check_info(info)
    fps = info["fps"]
    video_keys = [k for k, f in feats.items() if f["dtype"] == "video"]
    image_keys = [k for k, f in feats.items() if f["dtype"] == "image"]

    # stats.json
    stats = _load_json(root / "meta/stats.json", "meta/stats.json")
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
            _need(all(len(shapes[s]) == 3 and shapes[s][1:] == (1, 1) for s in STATS[:4]),
                  f"meta/stats.json {key!r} image stats must have shape (C, 1, 1)")
        elif len(ft["shape"]) == 1:
            want = tuple(ft["shape"])
        if want is not None:
            for s in STATS[:4]:
                _need(shapes[s] == want,
                      f"meta/stats.json {key!r} {s} has shape {shapes[s]}, feature shape is {list(want)}")

    # tasks
    tasks_path = root / "meta/tasks.parquet"
    _need(tasks_path.is_file(), "meta/tasks.parquet is missing")
    tasks_t = _read_parquet(tasks_path, "meta/tasks.parquet")
    _need({"task_index", "task"} <= set(tasks_t.column_names),
          f"meta/tasks.parquet columns are {tasks_t.column_names}, need task_index and task")
    task_names = tasks_t.column("task").to_pylist()
    task_idx = tasks_t.column("task_index").to_pylist()
    _need(all(isinstance(t, str) and t for t in task_names), "meta/tasks.parquet has empty or non-string tasks")
    _need(len(set(task_names)) == len(task_names), "meta/tasks.parquet has duplicate tasks")
    _need(sorted(task_idx) == list(range(len(task_idx))), "meta/tasks.parquet task_index is not 0..n-1")
    _need(len(task_names) == info["total_tasks"],
          f"meta/tasks.parquet has {len(task_names)} tasks, info.json total_tasks is {info['total_tasks']}")
    task_of = dict(zip(task_idx, task_names))

    # episodes
    ep_files = sorted((root / "meta/episodes").glob("*/*.parquet"))
    _need(ep_files, "meta/episodes/chunk-*/file-*.parquet is missing")
    video_cols = [f"videos/{k}/{c}" for k in video_keys for c in ("chunk_index", "file_index")]
    ep_tables = []
    for p in ep_files:
        rel = str(p.relative_to(root))
        names = pq.read_schema(str(p)).names
        missing = [c for c in (*EPISODE_COLUMNS, *video_cols) if c not in names]
        _need(not missing, f"{rel} lacks columns {missing}")
        ep_tables.append(_read_parquet(p, rel, [*EPISODE_COLUMNS, *video_cols]))
    eps = pa.concat_tables(ep_tables)
    n_eps = eps.num_rows
    col = {c: np.asarray(eps.column(c).to_numpy(zero_copy_only=False)) for c in EPISODE_COLUMNS if c != "tasks"}
    ep_tasks = eps.column("tasks").to_pylist()
    _need(n_eps == info["total_episodes"], f"meta/episodes has {n_eps} episodes, info.json total_episodes is "
          f"{info['total_episodes']}")
    _need(np.array_equal(col["episode_index"], np.arange(n_eps)), "meta/episodes episode_index is not 0..E-1 in order")
    lengths, starts, stops = col["length"], col["dataset_from_index"], col["dataset_to_index"]
    for e in range(n_eps):
        _need(lengths[e] > 0, f"episode {e} has length {lengths[e]}")
        _need(stops[e] - starts[e] == lengths[e], f"episode {e} offsets [{starts[e]}, {stops[e]}) disagree with its "
              f"length {lengths[e]}")
        expected_start = 0 if e == 0 else stops[e - 1]
        _need(starts[e] == expected_start, f"episode {e} dataset_from_index is {starts[e]}, expected {expected_start}")
        _need(isinstance(ep_tasks[e], list) and ep_tasks[e] and all(t in task_names for t in ep_tasks[e]),
              f"episode {e} tasks {ep_tasks[e]!r} are not in meta/tasks.parquet")
    total = int(stops[-1]) if n_eps else 0
    _need(total == info["total_frames"],
          f"episodes cover {total} frames, info.json total_frames is {info['total_frames']}")
    for e in range(n_eps):
        for k in video_keys:
            rel = info["video_path"].format(video_key=k,
                                            chunk_index=int(eps.column(f"videos/{k}/chunk_index")[e].as_py()),
                                            file_index=int(eps.column(f"videos/{k}/file_index")[e].as_py()))
            _need((root / rel).is_file(), f"episode {e} video {rel} is missing")

    # data files
    on_disk = sorted((root / "data").glob("*/*.parquet"))  # what LeRobot loads
    disk_rel = [str(p.relative_to(root)) for p in on_disk]
    referenced = sorted({(int(c), int(f)) for c, f in zip(col["data/chunk_index"], col["data/file_index"])})
    ref_paths = {(c, f): info["data_path"].format(chunk_index=c, file_index=f) for c, f in referenced}
    for rel in ref_paths.values():
        _need((root / rel).is_file(), f"{rel} (referenced by meta/episodes) is missing")
        _need(rel in disk_rel, f"{rel} (referenced by meta/episodes) is not at data/<chunk>/<file>.parquet")
    extra = [rel for rel in disk_rel if rel not in set(ref_paths.values())]
    _need(not extra, f"{extra[0] if extra else ''} is not referenced by any episode")
    expected_cols = {k for k, f in feats.items() if f["dtype"] != "video"}
    file_span: dict[tuple[int, int], tuple[int, int]] = {}
    arrays: dict[str, list[np.ndarray]] = {k: [] for k in INDEX_FEATURES}
    row = 0
    for p in on_disk:  # LeRobot concatenates the data files in sorted path order
        rel = str(p.relative_to(root))
        schema = pq.read_schema(str(p))
        names = set(schema.names)
        _need(names == expected_cols, f"{rel} columns differ from the features: missing "
              f"{sorted(expected_cols - names)}, unexpected {sorted(names - expected_cols)}")
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
    n = len(data["index"])
    _need(n == info["total_frames"], f"data files hold {n} frames, info.json total_frames is {info['total_frames']}")
    bad = np.nonzero(data["index"] != np.arange(n))[0]
    _need(bad.size == 0, f"index is not contiguous 0..N-1: row {bad[0] if bad.size else 0} has index "
          f"{data['index'][bad[0]] if bad.size else 0}")
    ep_of_row = np.repeat(np.arange(n_eps), lengths)
    bad = np.nonzero(data["episode_index"] != ep_of_row)[0]
    _need(bad.size == 0, f"row {bad[0] if bad.size else 0} has episode_index "
          f"{data['episode_index'][bad[0]] if bad.size else 0}, but meta/episodes puts it in episode "
          f"{ep_of_row[bad[0]] if bad.size else 0}")
    frame = np.arange(n) - np.repeat(starts, lengths)
    bad = np.nonzero(data["frame_index"] != frame)[0]
    _need(bad.size == 0, f"frame_index does not restart at 0 and count up in every episode (row "
          f"{bad[0] if bad.size else 0}, episode {ep_of_row[bad[0]] if bad.size else 0})")
    err = np.abs(data["timestamp"].astype(np.float64) - data["frame_index"] / fps)
    bad = np.nonzero(~(err <= TIMESTAMP_TOLERANCE_S))[0]
    _need(bad.size == 0, f"timestamp != frame_index / fps at row {bad[0] if bad.size else 0} "
          f"(episode {ep_of_row[bad[0]] if bad.size else 0})")
    for e in range(n_eps):
        c, f = int(col["data/chunk_index"][e]), int(col["data/file_index"][e])
        lo, hi = file_span[(c, f)]
        _need(lo <= starts[e] and stops[e] <= hi,
              f"episode {e} rows [{starts[e]}, {stops[e]}) are not in {ref_paths[(c, f)]} (rows [{lo}, {hi}))")
        used = {task_of.get(int(t)) for t in np.unique(data["task_index"][starts[e]:stops[e]])}
        _need(used <= set(ep_tasks[e]), f"episode {e} frames use task_index outside its tasks {ep_tasks[e]!r}")

    return {"root": str(root), "codebase_version": info["codebase_version"], "fps": fps, "episodes": n_eps,
            "frames": n, "tasks": len(task_names), "features": list(feats), "image_keys": image_keys,
            "video_keys": video_keys, "data_files": [str(p.relative_to(root)) for p in on_disk]}
