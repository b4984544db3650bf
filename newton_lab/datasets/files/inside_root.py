"""Paths read from files (a LeRobot ``info.json`` template, a pipeline manifest) stay inside their root folder.

A damaged or crafted file must not make newton_lab read, replace or delete anything outside the folder it
describes; every path that comes from file contents goes through :func:`contained` before it is used.
"""

from __future__ import annotations

from pathlib import Path


class OutsidePathError(ValueError):
    """A path read from a file points outside the folder that file describes."""


def contained(root: str | Path, rel: str | Path, what: str) -> Path:
    """``root / rel`` resolved; raises :class:`OutsidePathError` (one line) if it leaves ``root``.

    ``what`` names the file the path came from (e.g. ``"meta/info.json data_path"``). Absolute ``rel`` paths are
    accepted only if they lie inside ``root``; ``..`` and symlinks are resolved before the check.
    """
    base = Path(root).expanduser().resolve()
    target = (base / Path(rel).expanduser()).resolve()
    if target != base and base not in target.parents:
        raise OutsidePathError(
            f"{what} points outside {base} ({str(rel)!r}); the file is damaged or was edited by hand: re-create it"
        )
    return target
