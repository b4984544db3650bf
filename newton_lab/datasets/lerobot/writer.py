"""The LeRobot v3.0 export: plan, per-episode arrays, writing, atomic rename into place.

Everything is written into a hidden sibling ``.<root name>.partial-*`` and renamed to ``root`` at the end.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import uuid
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..files.durability import fsync_path
from ..files.output_paths import output_path
from ..storage import read_dataset_info, read_episode, read_episodes
from .tables import (
    CHUNKS_SIZE,
    CODEBASE_VERSION,
    DATA_FILES_SIZE_IN_MB,
    DATA_PATH,
    EPISODES_PATH,
    IMAGE_NAMES,
    IMAGE_PREFIX,
    INDEX_FEATURES,
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
from .video import VideoFiles, even_shape, video_info


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
    video: bool = True  # image terms as mp4 "video" features (else PNG "image" features in the data files)

    @property
    def state_dim(self) -> int:
        return sum(w for _, w in self.state_terms)

    def features(self) -> dict[str, dict[str, Any]]:
        feats: dict[str, dict[str, Any]] = {
            "observation.state": {
                "dtype": "float32",
                "shape": [self.state_dim],
                "names": [f"{t}.{i}" for t, w in self.state_terms for i in range(w)],
            },
            "action": {"dtype": "float32", "shape": [self.action_dim], "names": list(self.action_names)},
        }
        for term, shape in self.image_terms:
            feats[IMAGE_PREFIX + term] = (
                {
                    "dtype": "video",
                    "shape": list(even_shape(shape)),
                    "names": list(IMAGE_NAMES),
                    "info": video_info(shape, self.fps),
                }
                if self.video
                else {"dtype": "image", "shape": list(shape), "names": list(IMAGE_NAMES)}
            )
        for key, dtype in INDEX_FEATURES.items():
            feats[key] = {"dtype": dtype, "shape": [1], "names": None}
        return feats


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
    plan, first = _make_plan(
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


def _resolve_fps(fps: Any, nl: Mapping[str, Any], source: Path) -> int:
    if fps is None:
        try:
            period = float(nl["sim_dt"]) * int(nl["decimation"])
            value: Any = 1.0 / period
        except (KeyError, TypeError, ValueError, ZeroDivisionError):
            raise ValueError(
                f"{source} has no usable env_args['newton_lab'] sim_dt/decimation to derive the "
                "frame rate from; pass fps=<int>"
            ) from None
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


def _make_plan(
    info: dict[str, Any], *, repo_id, fps, include_failed, state_keys, task_description
) -> tuple[_Plan, dict[str, Any]]:
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
        raise ValueError(
            f"{source} has no episodes to export: {len(demos)} demos, {len(failed)} failed, {len(empty)} empty{hint}"
        )

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
                raise ValueError(
                    f"state_keys: {t!r} is an image term (exported as {IMAGE_PREFIX}{t}), not a (T, d) state term"
                )
            if kinds[t] != "vector":
                raise ValueError(
                    f"state_keys: obs term {t!r} has shape {obs[t].shape} dtype {obs[t].dtype}, not a real (T, d) array"
                )
    actions = np.asarray(first["actions"])
    a_dim = int(actions.shape[1])
    names = nl.get("action_joint_names")
    if not (isinstance(names, list) and len(names) == a_dim and all(isinstance(n, str) for n in names)):
        names = [f"action.{i}" for i in range(a_dim)]
    images = [(t, tuple(int(s) for s in obs[t].shape[1:])) for t in order if kinds[t] == "image"]
    ignored = [t for t in order if kinds[t] == "other" or (kinds[t] == "vector" and t not in state)]
    plan = _Plan(
        source=source,
        source_format=info["format"],
        task_id=task_id,
        repo_id=repo,
        task=task,
        fps=fps_i,
        demo_ids=chosen,
        skipped_failed=[] if include_failed else failed,
        skipped_empty=empty,
        state_terms=[(t, 1 if obs[t].ndim == 1 else int(obs[t].shape[1])) for t in state],
        action_dim=a_dim,
        action_names=list(names),
        image_terms=images,
        ignored_terms=ignored,
    )
    return plan, first


# ----------------------------------------------------------------------------- per-episode data
def _episode_arrays(ep: Mapping[str, Any], plan: _Plan, demo_id: int) -> tuple[np.ndarray, np.ndarray, dict]:
    where = f"demo_{demo_id} of {plan.source}"
    actions = np.asarray(ep["actions"])
    if actions.ndim != 2 or actions.shape[1] != plan.action_dim:
        raise ValueError(
            f"{where}: actions have shape {actions.shape}; expected (T, {plan.action_dim}) like demo_{plan.demo_ids[0]}"
        )
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


# ----------------------------------------------------------------------------- writing
def _write_all(
    tmp: Path, plan: _Plan, first: dict[str, Any], limit_bytes: int, limit_mb: int
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
            state, actions, images = _episode_arrays(ep, plan, demo_id)
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
    plan: _Plan,
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
