"""Tuning of zarr batch writes, as one typed object passed down from ``open_writer`` (``zarr_settings=``) to the
store. The settings change how fast a batch is written and how its demos are laid out in files (packs or one group
per demo), never what a reader gets back."""

from __future__ import annotations

import os
from dataclasses import dataclass, field


def _default_pack_threads() -> int:
    return min(8, os.cpu_count() or 2)


@dataclass(frozen=True, kw_only=True)
class ZarrWriteSettings:
    """How the zarr store writes a batch of demos."""

    pack_min_batch: int = 32
    """A batch of at least this many demos (of one layout) is written as one pack (a few files for all of them);
    smaller batches as one ``demo_<i>`` group (~80 files) per demo."""
    write_threads: int = 4
    """Threads writing the demo groups of a small batch (file creation waits on the filesystem, not on the GIL)."""
    pack_threads: int = field(default_factory=_default_pack_threads)
    """Threads encoding (zstd) and writing the chunks of a pack; default: the cores, at most 8."""

    def __post_init__(self) -> None:
        for name in ("pack_min_batch", "write_threads", "pack_threads"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"ZarrWriteSettings.{name} must be an int >= 1, got {value!r}")


DEFAULT_ZARR_SETTINGS = ZarrWriteSettings()
"""The settings a writer uses when it is given none."""
