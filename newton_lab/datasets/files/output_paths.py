"""Where newton_lab writes an output: one rule for the Python API and the command line.

A dataset (``env.collect``, Mimic, merges, splits: HDF5 or zarr), a checkpoint (policy training), an export
(LeRobot, YOLO), a recording (rerun ``.rrd``), a scenario or a picture is written at a path whose missing parent
folders are created first (``env.collect(..., path="data/demos.hdf5")`` in a fresh folder, like ``newton-lab
collect --dataset-path data/demos.hdf5``). A path with a file where one of those folders should be is refused in
one line that names the problem and the fix::

    OutputPathError (a ValueError): cannot write data/x.hdf5: its parent data is a file; choose another path

Nothing on disk is removed, replaced or written by :func:`output_path` besides the new (empty) folders; whether an
existing output may be appended to or replaced is the writer's own rule. This module imports nothing heavy.
"""

from __future__ import annotations

import os
from pathlib import Path


class OutputPathError(ValueError):
    """An output path that cannot be written: a file stands where one of its folders should be, or a missing folder
    cannot be created."""


def _file_above(path: Path) -> Path | None:
    """The nearest existing ancestor of ``path`` if it is not a folder (a file, a dangling link), else None."""
    for parent in path.parents:
        if os.path.lexists(parent):
            return None if parent.is_dir() else parent
    return None


def _refusal(path: Path, blocker: Path) -> OutputPathError:
    where = f"its parent {blocker}" if blocker == path.parent else f"{blocker}, on its path,"
    return OutputPathError(f"cannot write {path}: {where} is a file; choose another path")


def output_path(path: str | os.PathLike, *, create: bool = True) -> Path:
    """``path`` (``~`` expanded) once its parent folders exist: missing ones are created (none when ``create`` is
    False: a check before any work starts). Raises :class:`OutputPathError` (a ``ValueError``, one line) when a
    file stands where one of those folders should be."""
    p = Path(path).expanduser()
    blocker = _file_above(p)
    if blocker is not None:
        raise _refusal(p, blocker)
    if create:
        try:
            p.parent.mkdir(parents=True, exist_ok=True)
        except (FileExistsError, NotADirectoryError):  # a file put there meanwhile
            raise _refusal(p, _file_above(p) or p.parent) from None
        except OSError as exc:  # permission denied, a read-only file system, a folder that takes none (/proc)
            raise OutputPathError(
                f"cannot write {p}: cannot create the folder {p.parent} ({exc.strerror}); choose a writable path"
            ) from None
    return p


__all__ = ["OutputPathError", "output_path"]
