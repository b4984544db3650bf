"""robomimic filter keys (``mask/<key>``: lists of demo names, e.g. the ``train`` / ``valid`` split), read and
written under the dataset's writer protocol like every other write (see ``storage``)."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path

from .storage import _as_id, _existing, _medium_errors, _missing_id


def read_filter_keys(path: str | Path) -> dict[str, list[str]]:
    """robomimic filter keys of a dataset: ``{key: [demo names]}`` (``mask/<key>``; empty when none)."""
    p, backend, _ = _existing(path)
    return backend.read_masks(p)


def set_filter_keys(path: str | Path, keys: Mapping[str, Iterable[int | str]]) -> dict[str, list[str]]:
    """Write (or replace) robomimic filter keys ``mask/<key>``, each a list of demo ids or names of
    committed demos; other keys are kept. Crash safe like every write. Returns the names written."""
    p, backend, _ = _existing(path)
    present = sorted(backend.info(p)["demos"])
    masks: dict[str, list[str]] = {}
    for key, ids in keys.items():
        if not isinstance(key, str) or not key or "/" in key or key.startswith(("_", ".")):
            raise ValueError(f"filter key {key!r} must be a non-empty str without '/' or a leading '_' / '.'")
        wanted = [_as_id(i) for i in ids]
        for i in wanted:
            if i not in present:
                raise _missing_id(p, i, present)
        masks[key] = [f"demo_{i}" for i in sorted(set(wanted))]
    with _medium_errors(p, backend, "while writing filter keys"):
        backend.set_masks(p, masks)
    return masks
