"""Split a dataset: robomimic train / valid filter keys (:func:`split_train_val`), or one dataset per
phase of a coherent task (:func:`split_by_phase`).

By phase: each episode contributes its contiguous steps of phase ``p`` to ``<out_dir>/<phase kind>.<suffix>`` (the
kind is the phase's name unless several phases share one, as SortToShelf-All's ``pick_1`` .. ``pick_4``: each of
them is one segment there), labelled with the component task id; the actions keep only the component's columns (by
joint name) and the segment's ``initial_state`` is the recorded state at its first step. A segment is successful
when the row moved on to the next phase (the last phase: when the episode succeeded).

Per target (``by_target``): a kind whose phases act on a per-row target (``PhaseCfg.target_option``, e.g.
SortToShelf-All's ``sorting_object``) is written as one dataset per value instead, ``<kind>-<value>``, keyed
``<kind>/<value>``: the segments whose target (the argmax of that observation's one-hot at the segment's first step)
is that value, recorded with the option set to it, so each is a dataset of the component task for one object.
"""

from __future__ import annotations

import errno
import multiprocessing
import os
import shutil
import signal
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from contextlib import closing
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..robots.registry import robot_binding
from ..task_api.catalog import did_you_mean
from ..task_api.compose import TARGET_SEPARATOR, target_choices
from ..task_api.registry import lookup
from .files.errors import DatasetWriteError
from .files.output_paths import output_path
from .filter_keys import read_filter_keys, set_filter_keys
from .hdf5 import store as hdf5_store
from .hdf5.frames import StoredFrames
from .ref import DatasetRef
from .storage import SUFFIXES, open_writer, read_dataset_info, read_episodes
from .writers.child_process import die_with_parent
from .writers.interrupts import Interrupted


def _slice(node: Any, sel: np.ndarray, steps: int) -> Any:
    if isinstance(node, dict):
        return {k: _slice(v, sel, steps) for k, v in node.items()}
    if isinstance(node, StoredFrames):  # compressed frames: the segment's chunks, copied as they are
        return node.select(sel) if node.shape[0] == steps else node
    arr = np.asarray(node)
    return arr[sel] if arr.ndim and arr.shape[0] == steps else arr


SEGMENTS_PER_WRITE = 64
"""Segments a phase writer appends in one durable write (one sync): the stage folder is published only when every
phase is written, so a batch costs nothing on a kill, and a sync per segment was a third of the split's time."""


@dataclass(frozen=True)
class _PhaseJob:
    """What one phase's writer needs (plain values: it is sent to a worker process)."""

    source: Path
    out: Path
    name: str
    indices: tuple[int, ...]
    """The phases of this kind (one segment per episode each)."""
    phase_names: tuple[str, ...]
    last: int
    """Index of the coherent task's last phase."""
    task_id: str
    cols: list[int]
    env_args: dict[str, Any]
    target: tuple[str, int] | None = None
    """Only the segments whose target is this: (observation key of the one-hot, value index)."""


def _write_phase(job: _PhaseJob) -> list[int]:
    """Write ``job``'s phase dataset: every episode's steps of each of its phases, a segment per phase; returns the
    saved demo ids."""
    info = read_dataset_info(job.source)
    saved: list[int] = []
    batch: list[tuple[dict, bool, dict]] = []
    with open_writer(job.out, task_id=job.task_id, env_args=job.env_args) as writer:
        for demo, ep in zip(info["demo_ids"], _episodes(job.source, info["demo_ids"])):
            attrs = ep.pop("attrs")
            phase = np.asarray(ep["datagen"]["phase"]).reshape(-1)
            for index, name in zip(job.indices, job.phase_names):
                sel = np.nonzero(phase == index)[0]
                if sel.size == 0 or not _on_target(ep, sel[0], job.target):
                    continue
                success = bool(attrs.get("success", False)) if index == job.last else bool((phase > index).any())
                seg = _segment(ep, sel, phase.shape[0], job.cols, success)
                batch.append((seg, success, {"source": f"{job.source.name}:{demo}", "phase": name}))
            if len(batch) >= SEGMENTS_PER_WRITE:
                saved += writer.append_episodes(batch)
                batch = []
        saved += writer.append_episodes(batch)
    return saved


def _on_target(ep: dict, step: int, target: tuple[str, int] | None) -> bool:
    """Whether the segment starting at ``step`` acts on ``target`` (always, when ``None``)."""
    if target is None:
        return True
    key, index = target
    return int(np.asarray(ep["obs"][key][step]).argmax()) == index


def _episodes(source: Path, ids: list[int]):
    """The source's episodes with their attrs; from HDF5, image frames as their compressed chunks (an HDF5 phase
    dataset gets the same chunk bytes: no frame is inflated and deflated again)."""
    if SUFFIXES.get(source.suffix.lower()) == "hdf5":
        with closing(hdf5_store.read_many(source, ids, None, attrs=True, stored_frames=True)) as items:
            for tree, attrs in items:
                yield {**tree, "attrs": attrs}
    else:
        yield from read_episodes(source, ids, attrs=True)


def _segment(ep: dict, sel: np.ndarray, steps: int, cols: list[int], success: bool) -> dict:
    """The steps ``sel`` of episode ``ep`` with the component's action ``cols``; ``initial_state`` and robomimic's
    ``dones`` made for the segment."""
    seg = _slice({k: v for k, v in ep.items() if k != "initial_state"}, sel, steps)
    seg["actions"] = np.asarray(seg["actions"])[:, cols]
    if "states" in ep:  # (1, ...) like a collected episode's initial_state
        seg["initial_state"] = _slice(ep["states"], sel[:1], steps)
    if "dones" in seg:  # robomimic: 1 on the last step of a successful segment
        seg["dones"] = np.zeros_like(seg["dones"])
        seg["dones"][-1:] = int(success)
    return seg


def check_phase_names(path: str | Path, task_id: str, names: Sequence[str], wanted: Sequence[str]) -> None:
    """Raise a one-line ``ValueError`` unless the task that recorded ``path`` has phases (``names``, in order) and
    every phase in ``wanted`` is one of them."""
    if not names:
        raise ValueError(f"{path} was recorded on {task_id}, which has no phases; nothing to split")
    for name in wanted:
        if name not in names:
            raise ValueError(
                f"{task_id} has no phase {name!r}{did_you_mean(name, names)}; its phases: {', '.join(names)}"
            )


def split_by_phase(
    path: str | Path,
    out_dir: str | Path,
    *,
    phases: Sequence[str] | None = None,
    workers: int | None = None,
    by_target: Sequence[str] = (),
) -> dict[str, DatasetRef]:
    """Write one dataset per phase kind of the coherent task that recorded ``path`` (only ``phases``, by kind, when
    given), and for the kinds in ``by_target`` one per value of their target (module docstring); returns them by
    kind (``kind/value`` for those). Each phase is written by its own process (at most ``workers``, default
    one per phase up to the CPU count): a phase's writer spends its time compressing frames, and the phases are
    independent. Existing output files are never replaced."""
    path, out_dir = Path(path), Path(out_dir)
    info = read_dataset_info(path)
    task_id = info["task_id"]
    env_args = info["env_args"]
    options = env_args.get("env_kwargs", {}).get("task_options") or {}
    from .. import tasks  # noqa: F401  (deferred: registering the tasks imports Warp; storage stays Warp-free)

    cfg = lookup(task_id).make_cfg(options)
    kinds = cfg.phase_kinds if cfg.phases else {}
    check_phase_names(path, task_id, list(kinds), [*(phases or ()), *by_target])
    chosen = []
    for kind, ix in kinds.items():
        if phases is not None and kind not in phases:
            continue
        members = [(i, cfg.phases[i]) for i in ix]
        if kind not in by_target:
            chosen.append((kind, members, None))
            continue
        option, values = target_choices(cfg, kind)
        chosen += [(f"{kind}{TARGET_SEPARATOR}{v}", members, (option, i, v)) for i, v in enumerate(values)]
    outs = {name: out_dir / f"{name.replace(TARGET_SEPARATOR, '-')}{path.suffix}" for name, _, _ in chosen}
    taken = [str(o) for o in outs.values() if o.exists()]
    if taken:
        raise FileExistsError(f"{taken} already exist; split into a new folder")
    output_path(out_dir / "x", create=False)  # out_dir, or a folder above it, a file: refused now
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_stages(out_dir)
    stage = out_dir.parent / f".{out_dir.name}.{os.getpid()}.partial"  # beside out_dir: renamed into it when done
    stage.mkdir()
    jobs = _phase_jobs(path, stage, outs, chosen, len(cfg.phases), options, env_args)
    saved = _write_phases(jobs, workers, stage, out_dir, [o.name for o in outs.values()])
    refs: dict[str, DatasetRef] = {}
    for job, ids in zip(jobs, saved):
        ref = DatasetRef(outs[job.name], task_id=job.task_id, metadata={"saved_demo_ids": ids, "episodes": len(ids)})
        config = {"source": str(path), "phase": job.name, "phase_index": job.indices[0]}
        if len(job.indices) > 1:
            config["phase_indices"] = list(job.indices)
        refs[job.name] = ref.record("split", config=config)
    return refs


def _phase_jobs(path: Path, stage: Path, outs: dict, chosen: list, n_phases: int, options: dict, env_args: dict):
    """One ``_PhaseJob`` per chosen phase kind (per kind and target value, for ``by_target``'s kinds): its component
    task's action columns picked out of the coherent task's, written into the stage folder."""
    columns = env_args["newton_lab"]["action_joint_names"]
    jobs = []
    for kind, members, target in chosen:
        ph = members[0][1]
        if {m.task_id for _, m in members} != {ph.task_id}:
            raise ValueError(f"the phases of kind {kind!r} run different components; give each its own kind")
        own = options if target is None else {**options, target[0]: target[2]}
        comp = lookup(ph.task_id)
        comp = comp.cfg(**comp.accepted(own))
        groups = robot_binding(comp.robot).joint_groups
        joints = [j for t in comp.actions for j in groups[t.group]]
        args = {
            **env_args,
            "env_name": ph.task_id,
            "newton_lab": {**env_args["newton_lab"], "action_joint_names": joints, "phases": []},
        }
        if target is not None:  # recorded as the component with its option set to this value
            args["env_kwargs"] = {**env_args.get("env_kwargs", {}), "task_options": own}
        jobs.append(
            _PhaseJob(
                path,
                stage / outs[kind].name,
                kind,
                tuple(i for i, _ in members),
                tuple(m.name for _, m in members),
                n_phases - 1,
                ph.task_id,
                [columns.index(j) for j in joints],
                args,
                None if target is None else target[:2],
            )
        )
    return jobs


def _write_phases(jobs: list, workers: int | None, stage: Path, out_dir: Path, names: list[str]) -> list:
    """Write the phase datasets into ``stage`` (in processes of their own where more than one), then publish them
    into ``out_dir``; on Ctrl-C, a full disk or a killed writer nothing reaches ``out_dir``. Returns each job's
    saved demo ids."""
    workers = min(len(jobs), workers or os.cpu_count() or 1)
    if multiprocessing.current_process().daemon:  # e.g. a Dask worker: a daemonic process may not start children
        workers = 1
    try:
        if workers > 1:  # spawn: the parent may hold a CUDA context, which a forked child must not inherit
            context = multiprocessing.get_context("spawn")  # the writers die with this process, even on SIGKILL
            with ProcessPoolExecutor(
                workers, mp_context=context, initializer=_phase_writer, initargs=(os.getpid(),)
            ) as pool:
                try:
                    saved = list(pool.map(_write_phase, jobs))
                except KeyboardInterrupt:
                    _stop(pool)
                    raise
        else:
            saved = [_write_phase(job) for job in jobs]
        _publish(stage, out_dir, names)
    except KeyboardInterrupt as exc:  # Ctrl-C / SIGTERM
        raise Interrupted(
            f"interrupted: the split into {out_dir} was dropped, nothing written there; run it again",
            getattr(exc, "signum", signal.SIGINT),
        ) from None
    except DatasetWriteError as exc:  # its message names a file of the stage, which is removed
        what = "disk full" if exc.errno == errno.ENOSPC else os.strerror(exc.errno).lower()
        raise DatasetWriteError(
            f"{what} while splitting into {out_dir}: the split was dropped, nothing written "
            "there; free space and run it again",
            exc.errno,
        ) from None
    except BrokenProcessPool:
        raise DatasetWriteError(
            f"a phase writer of the split into {out_dir} ended abruptly (killed, or out of "
            f"memory); nothing was written to {out_dir}: run the split again",
            errno.EIO,
        ) from None
    finally:
        shutil.rmtree(stage, ignore_errors=True)  # what a failed or interrupted split wrote: never a partial output
    return saved


def _phase_writer(parent: int) -> None:
    """A phase writer's start: it dies with the splitting process (even on SIGKILL) and leaves Ctrl-C to it."""
    die_with_parent(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _stop(pool: ProcessPoolExecutor) -> None:
    """End a pool's phase writers now (their unfinished files are in the stage, removed after)."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        process.kill()
    for process in processes:
        process.join()


def _publish(stage: Path, out_dir: Path, names: list[str]) -> None:
    """Move a finished split from ``stage`` into ``out_dir``: one rename of the folder when ``out_dir`` is new or
    empty (all phases appear at once), else file by file (none replaces an existing file)."""
    if not out_dir.exists() or (out_dir.is_dir() and not any(out_dir.iterdir())):
        os.replace(stage, out_dir)  # rename(2) replaces an empty folder
        return
    for name in names:
        if (out_dir / name).exists():
            raise FileExistsError(f"{out_dir / name} appeared while the split ran; split into a new folder")
        os.rename(stage / name, out_dir / name)


def remove_stale_stages(out_dir: Path) -> None:
    """Remove what splits into ``out_dir`` that were killed left beside it (``.<name>.<pid>.partial``, its process
    gone)."""
    for stage in out_dir.parent.glob(f".{out_dir.name}.*.partial"):
        try:
            os.kill(int(stage.name.rsplit(".", 2)[-2]), 0)
        except ValueError:
            continue
        except ProcessLookupError:
            shutil.rmtree(stage, ignore_errors=True)
        except PermissionError:  # alive, another user's
            continue


def split_train_val(
    path: str | Path, val_ratio: float = 0.1, *, seed: int = 0, filter_key: str | None = None
) -> dict[str, list[str]]:
    """Write robomimic filter keys ``mask/train`` and ``mask/valid`` (``<filter_key>_train`` / ``_valid``
    when splitting the demos of an existing key), as robomimic's ``split_train_val.py`` does with the same
    seed: ``int(val_ratio * n)`` demos, drawn by a seeded shuffle, go to valid. Also writes
    ``mask/successful`` (the demos marked successful). Returns the keys written."""
    if isinstance(val_ratio, bool) or not isinstance(val_ratio, (int, float)) or not 0 <= val_ratio < 1:
        raise ValueError(f"val_ratio must be a fraction in [0, 1), got {val_ratio!r}")
    info = read_dataset_info(path)
    masks = {"successful": [d for d in info["demo_ids"] if info["demos"][d]["success"]]}
    if filter_key is None:
        demos = sorted(f"demo_{d}" for d in info["demo_ids"])  # robomimic sorts the names as strings
    else:
        keys = {**read_filter_keys(path), "successful": [f"demo_{d}" for d in masks["successful"]]}
        if filter_key not in keys:
            raise ValueError(f"{path} has no filter key {filter_key!r}; available: {sorted(keys)}")
        demos = sorted(keys[filter_key])
    mask = np.zeros(len(demos))
    mask[: int(val_ratio * len(demos))] = 1.0
    np.random.RandomState(seed).shuffle(mask)  # robomimic: np.random.seed(0); np.random.shuffle(mask)
    prefix = f"{filter_key}_" if filter_key else ""
    masks[f"{prefix}train"] = [d for d, m in zip(demos, mask) if not m]
    masks[f"{prefix}valid"] = [d for d, m in zip(demos, mask) if m]
    return set_filter_keys(path, masks)
