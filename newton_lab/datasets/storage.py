"""Episode storage: robomimic-layout datasets in HDF5 (``.hdf5``/``.h5``) or zarr v3 (``.zarr``).

Layout (both formats)::

    data/            attrs: env_args (JSON), total, num_demos, next_demo_id, task_id, format_version
    data/demo_<i>/   attrs: num_samples, success, extra scalars
        actions (T, A) float32, obs/<term> (T, ...), next_obs/<term> (the observation after each step),
        rewards (T,) float32, dones (T,) int (1 on the last step of a successful episode), states (T, D)
        float32 flat sim state (named by env_args newton_lab.state_layout, see ``states``),
        initial_state (1, D), datagen/<...>, any nested key
    mask/<key>       robomimic filter keys: demo names (HDF5: byte strings; zarr: utf-8 strings), e.g.
                     train / valid written by ``split_train_val`` (``newton-lab split``)

robomimic's ``SequenceDataset`` reads these files as they are. Format 1 datasets (nested ``states``, no
rewards / dones / next_obs) stay readable. zarr packs a large batch's demos (``zarr.packs``:
``data/pack_<first id>/<array>``, the demos one after another, their ids, rows and attrs in the pack's attrs); the
readers return the same trees and attrs for both layouts.

This module writes: :class:`EpisodeWriter` checks episodes and appends them. Reading, deleting demos, setting root
attrs and the dispatch by suffix live in ``access`` (re-exported here: ``from newton_lab.datasets.storage import
read_episode`` keeps working). A new dataset's missing parent folders are created (``outputs.output_path``, the rule
of every output of newton_lab); a file where one of them should be is refused in one line.

Every ``append_episode`` / ``append_episodes`` batch is durable (one fsync) and crash safe before it
returns: a writer killed at any time leaves a dataset holding every episode whose append returned, and
none of a batch cut short. HDF5 writes go through a rollback journal (``<file>-journal``, rolled back
by the next reader/writer); zarr demos are staged, renamed into place and committed by advancing
``next_demo_id``. Half-written demos are invisible to readers and removed by the next append. An append
reads and updates only the root attrs (``next_demo_id``, ``total``, ``num_demos``): its cost does not
grow with the dataset (one written before ``next_demo_id`` existed is walked once, on its first append).
``background.BackgroundWriter`` runs a writer in a thread beside the simulation.

One writer protocol for both formats: every write session (append, delete, attrs) holds an
exclusive ``flock`` (HDF5: on the file; zarr: on the store's root ``zarr.json``), queued fairly and
waited for at most ``files.locking.LOCK_WAIT_S`` (10 s), else a one-line :class:`DatasetLockedError`
naming the holder's pid; demo ids are allocated under that lock from ``next_demo_id``, so
writers in several processes interleave their appends and ids never collide. A write the disk
refuses (ENOSPC, EIO, ...) rolls the session back and raises one line, :class:`DatasetWriteError`
(an ``OSError``): ``disk full after N episodes; <path> holds M finished episodes``.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from .access import (
    BACKENDS,
    SUFFIXES,
    _as_id,
    _backend,
    _episodes,
    _existing,
    _medium_errors,
    _missing_id,
    _root_meta,
    delete_demos,
    list_demos,
    read_dataset_info,
    read_episode,
    read_episodes,
    set_dataset_attrs,
)
from .files.errors import DatasetLockedError, DatasetWriteError
from .files.layout import FORMAT_VERSION, NEXT_ID, RESERVED_DEMO_ATTRS, StoredDemo, dumps_env_args, py_scalar
from .files.output_paths import output_path
from .files.recording import check_same_recording
from .files.write_faults import inject_write_fault
from .hdf5.frames import StoredFrames
from .writers.columns import DemoBlock
from .zarr.settings import DEFAULT_ZARR_SETTINGS, ZarrWriteSettings

TIME_ALIGNED = ("obs", "next_obs", "states", "rewards", "dones")  # every array under these has T rows
EpisodeItem = tuple[Mapping[str, Any], bool, Mapping[str, Any] | None]
"""One entry of :meth:`EpisodeWriter.append_episodes`: (episode, success, attrs or None)."""

__all__ = [
    "EpisodeWriter",
    "open_writer",
    "read_dataset_info",
    "read_episode",
    "read_episodes",
    "list_demos",
    "delete_demos",
    "set_dataset_attrs",
    "SUFFIXES",
    "BACKENDS",
    "FORMAT_VERSION",
    "DatasetLockedError",
    "DatasetWriteError",
    "inject_write_fault",
]


# ----------------------------------------------------------------------------- episode validation
def _to_tree(node: Mapping, prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in node.items():
        if not isinstance(key, str) or not key or "/" in key or key.startswith("."):
            raise ValueError(f"episode key {prefix + str(key)!r} must be a non-empty str without '/'")
        if isinstance(value, Mapping):
            out[key] = _to_tree(value, f"{prefix}{key}/")
            continue
        if isinstance(value, StoredFrames):  # an HDF5 dataset's frames as stored (the split copies them)
            out[key] = value
            continue
        arr = np.asarray(value)
        if arr.dtype.kind not in "biufc":
            raise TypeError(
                f"episode array {prefix + key!r} has unsupported dtype {arr.dtype} (use bool/int/uint/float/complex)"
            )
        out[key] = arr  # strided views too: the writers copy into chunks or packs anyway (off the caller's thread)
    return out


def _normalize_episode(episode: Mapping) -> tuple[dict[str, Any], int]:
    if not isinstance(episode, Mapping):
        raise TypeError(f"episode must be a (nested) dict of arrays, got {type(episode).__name__}")
    if "actions" not in episode or isinstance(episode["actions"], Mapping):
        raise ValueError("episode must contain an 'actions' array of shape (T, A)")
    if "attrs" in episode:
        raise ValueError("episode key 'attrs' is reserved; pass demo attributes via attrs=")
    tree = _to_tree(episode)
    actions = tree["actions"]
    if actions.ndim != 2 or actions.dtype.kind not in "iuf":
        raise ValueError(f"'actions' must be a real (T, A) array, got shape {actions.shape} dtype {actions.dtype}")
    tree["actions"] = actions.astype(np.float32, copy=False)
    steps = actions.shape[0]

    def check(node: Any, name: str) -> None:
        if isinstance(node, dict):
            for k, v in node.items():
                check(v, f"{name}/{k}")
        elif node.ndim == 0 or node.shape[0] != steps:
            raise ValueError(f"episode array {name!r} has shape {node.shape}; expected {steps} rows like 'actions'")

    for key in TIME_ALIGNED:
        if key in tree:
            check(tree[key], key)
    return tree, steps


def _demo_attrs(success: bool, attrs: Mapping | None) -> dict[str, Any]:
    out = {}
    for key, value in (attrs or {}).items():
        if key in RESERVED_DEMO_ATTRS:
            raise ValueError(
                f"attr {key!r} is set by the writer; pass success= instead"
                if key == "success"
                else f"attr {key!r} is set by the writer"
            )
        out[str(key)] = py_scalar(value, key)
    out["success"] = bool(py_scalar(success, "success"))
    return out


# ----------------------------------------------------------------------------- writer
class EpisodeWriter:
    """Appends episodes to one dataset; nothing is held open between appends."""

    def __init__(
        self, path: Path, backend: ModuleType, fmt: str, task_id: str, fsync: bool, zarr_settings: ZarrWriteSettings
    ) -> None:
        self.path, self.format, self.task_id = path, fmt, task_id
        self._backend, self._fsync, self._closed = backend, fsync, False
        self.zarr_settings = zarr_settings
        """How a zarr batch is written (packs, threads); unused by HDF5."""
        self._batch_options = {"settings": zarr_settings} if fmt == "zarr" else {}
        self.appended = 0
        """Episodes this writer has appended."""

    @classmethod
    def open(
        cls,
        path: str | Path,
        *,
        task_id: str,
        env_args: Mapping[str, Any],
        fsync: bool = True,
        option_defaults: Mapping[str, Any] | None = None,
        zarr_settings: ZarrWriteSettings | None = None,
    ) -> EpisodeWriter:
        """Create ``path`` or append to it if it holds a dataset of the same task, recorded with the same cameras,
        observation terms and task options (``check_same_recording``; ``option_defaults``: the task's).
        ``zarr_settings``: how zarr batches are written (default ``DEFAULT_ZARR_SETTINGS``)."""
        if zarr_settings is not None and not isinstance(zarr_settings, ZarrWriteSettings):
            raise TypeError(f"zarr_settings must be a ZarrWriteSettings, got {type(zarr_settings).__name__}")
        zarr_settings = zarr_settings or DEFAULT_ZARR_SETTINGS
        if not isinstance(task_id, str) or not task_id:
            raise ValueError("task_id must be a non-empty str")
        p, backend, fmt = _backend(path)
        env = dict(env_args)
        if env.setdefault("env_name", task_id) != task_id:
            raise ValueError(f"env_args['env_name']={env['env_name']!r} differs from task_id={task_id!r}")
        env.setdefault("type", 2)
        env.setdefault("env_kwargs", {})
        root = {
            "env_args": dumps_env_args(env),
            "total": 0,
            "num_demos": 0,
            NEXT_ID: 0,
            "task_id": task_id,
            "format_version": FORMAT_VERSION,
        }
        if not p.exists():
            output_path(p)  # its missing folders (data/ of data/demos.hdf5)
            try:
                with _medium_errors(p, backend, "while creating it"):
                    backend.create(p, root, fsync)
                return cls(p, backend, fmt, task_id, fsync, zarr_settings)
            except FileExistsError:
                pass  # created concurrently: validate it like any existing dataset
        meta = _root_meta(p, backend.read_root(p))
        existing = meta["task_id"]
        if existing != task_id:
            raise ValueError(
                f"{p} holds a dataset of task {existing!r}, not {task_id!r}; choose another path for {task_id!r}"
            )
        check_same_recording(p, meta["env_args"], env, option_defaults)
        return cls(p, backend, fmt, task_id, fsync, zarr_settings)

    def prepare(
        self, episode: Mapping[str, Any], *, success: bool, attrs: Mapping[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any], int]:
        """Check one episode (one-line errors) and convert it for :meth:`append_prepared`: (tree, attrs, steps).
        The arrays are not copied (strided views stay views; only ``actions`` of another dtype becomes float32):
        do not change them until they are written."""
        tree, steps = _normalize_episode(episode)
        return tree, _demo_attrs(success, attrs), steps

    def append_episodes(self, episodes: Iterable[EpisodeItem]) -> list[int]:
        """Write ``[(episode, success, attrs), ...]`` in one durable write session (one fsync): all of them
        land or none (also on SIGKILL); returns their demo ids. Every episode is checked before any is written."""
        return self.append_prepared([self.prepare(ep, success=ok, attrs=attrs) for ep, ok, attrs in episodes])

    def append_prepared(self, batch: list[tuple[dict[str, Any], dict[str, Any], int]]) -> list[int]:
        """Write episodes returned by :meth:`prepare` as one batch (see :meth:`append_episodes`)."""
        if self._closed:
            raise RuntimeError(f"EpisodeWriter for {self.path} is closed")
        if not batch:
            return []
        with _medium_errors(self.path, self._backend, f"after {_episodes(self.appended)}"):
            ids = self._backend.append(self.path, list(batch), self._fsync, **self._batch_options)
        self.appended += len(ids)
        return ids

    def append_block(self, block: DemoBlock) -> list[int]:
        """Write the demos of a ``columns.DemoBlock`` as one durable batch (see :meth:`append_episodes`); returns
        their ids. zarr packs a batch of ``zarr_settings.pack_min_batch`` demos or more straight from the block's
        joined arrays (no tree per demo, no re-joining); smaller batches, HDF5 and tasks whose trees hold an empty
        group go demo by demo."""
        if self._closed:
            raise RuntimeError(f"EpisodeWriter for {self.path} is closed")
        arrays = block.arrays() if self.format == "zarr" and len(block) >= self.zarr_settings.pack_min_batch else None
        layout = block.pack_layout(arrays) if arrays is not None else None
        if layout is None:
            return self.append_prepared(
                [
                    self.prepare(tree, success=bool(ok), attrs=a)
                    for tree, ok, a in zip(block.trees(), block.successes, block.attrs)
                ]
            )
        attrs = [
            {**_demo_attrs(bool(ok), a), "num_samples": int(n)}
            for ok, a, n in zip(block.successes, block.attrs, block.lengths)
        ]
        with _medium_errors(self.path, self._backend, f"after {_episodes(self.appended)}"):
            ids = self._backend.append_joined(self.path, arrays, layout, attrs, self._fsync, **self._batch_options)
        self.appended += len(ids)
        return ids

    def append_copies(
        self, source: str | Path, demo_ids: Iterable[int | str], attrs: Mapping[int, Mapping[str, Any]] | None = None
    ) -> list[int]:
        """Append demos of ``source``, a dataset of the same task and format, as stored: one durable batch (see
        :meth:`append_episodes`) whose arrays are copied, not decoded and encoded again (zarr: a batch that is
        packed, or a packed source demo, is read and written again). Each copy keeps its source attrs, updated
        with ``attrs[demo_id]``; returns the new ids. Datasets of another format: read them with
        ``read_episodes`` and ``append_episodes``."""
        p, backend, fmt = _existing(source)
        if fmt != self.format:
            raise ValueError(
                f"{p} is {fmt} and {self.path} is {self.format}: copies need one format; "
                f"read_episodes + append_episodes convert between them"
            )
        if p.resolve() == self.path.resolve():
            raise ValueError(f"cannot copy demos of {p} into itself")
        task_id = _root_meta(p, backend.read_root(p))["task_id"]
        if task_id != self.task_id:
            raise ValueError(f"{p} holds task {task_id!r}, not {self.task_id!r}")
        ids = [_as_id(i) for i in demo_ids]
        try:  # the batch's own attrs, each demo looked up by id: no walk over the source per batch
            samples = [stored["num_samples"] for _, stored in backend.read_many(p, ids, (), attrs=True)]
        except KeyError as e:
            raise _missing_id(p, e.args[0], sorted(backend.info(p)["demos"])) from None
        extra = {i: {str(k): py_scalar(v, k) for k, v in (attrs or {}).get(i, {}).items()} for i in ids}
        for i in ids:
            if RESERVED_DEMO_ATTRS[0] in extra[i]:
                raise ValueError(f"attr {RESERVED_DEMO_ATTRS[0]!r} is set by the writer")
        return self.append_prepared([(StoredDemo(p, i), extra[i], n) for i, n in zip(ids, samples)])

    def append_episode(
        self, episode: Mapping[str, Any], *, success: bool, attrs: Mapping[str, Any] | None = None
    ) -> int:
        """Write one episode; returns its demo id once it is durable on disk."""
        if self._closed:
            raise RuntimeError(f"EpisodeWriter for {self.path} is closed")
        return self.append_prepared([self.prepare(episode, success=success, attrs=attrs)])[0]

    def close(self) -> None:
        """Mark the writer closed (every append is already on disk)."""
        self._closed = True

    def __enter__(self) -> EpisodeWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"EpisodeWriter({str(self.path)!r}, task_id={self.task_id!r}, format={self.format!r})"


def open_writer(
    path: str | Path,
    *,
    task_id: str,
    env_args: Mapping[str, Any],
    fsync: bool = True,
    option_defaults: Mapping[str, Any] | None = None,
    zarr_settings: ZarrWriteSettings | None = None,
) -> EpisodeWriter:
    """Alias of :meth:`EpisodeWriter.open`."""
    return EpisodeWriter.open(
        path,
        task_id=task_id,
        env_args=env_args,
        fsync=fsync,
        option_defaults=option_defaults,
        zarr_settings=zarr_settings,
    )
