"""Room on the dataset's filesystem: a zarr demo written alone is a folder of ~80 files and folders (packed with
others, see ``zarr.packs``, a fraction of one), so a large zarr collection can use up a filesystem's inodes (ext4:
one per 16 KiB of disk by default) long before its bytes. ``check_room`` refuses such a collection before anything
is written; ``out_of_room`` names what a refused write ran out of."""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

from . import packs as zarr_packs
from .nodes import inodes_of
from .settings import DEFAULT_ZARR_SETTINGS, ZarrWriteSettings


def check_room(
    path: str | Path,
    demos: int,
    tree: dict[str, Any],
    batch: int = 1,
    settings: ZarrWriteSettings = DEFAULT_ZARR_SETTINGS,
) -> None:
    """Refuse (one-line ``ValueError``) writing ``demos`` demos shaped like ``tree``, in batches of ``batch`` demos
    (a collection's: its envs, which end together at most), to the zarr dataset ``path`` when even one chunk per
    array would need more inodes than its filesystem has free (``tree`` may be one step long: image arrays, one
    chunk per frame, then count one frame; a batch large enough to be packed, ``settings.pack_min_batch``, counts as
    one pack). HDF5, one file,
    and filesystems that report no inode count pass."""
    path = Path(path)
    folder = next((p for p in (path, *path.parents) if p.is_dir()), None)  # missing folders are made on its filesystem
    if path.suffix != ".zarr" or folder is None:
        return
    st = os.statvfs(folder)
    packed = batch >= settings.pack_min_batch
    need = math.ceil(demos / batch) * zarr_packs.inodes_of_pack(tree, batch) if packed else demos * inodes_of(tree)
    if st.f_files and need > st.f_favail:
        raise ValueError(
            f"{path}: {demos} zarr demos need at least {need:,} inodes ({need / demos:.3g} a demo) "
            f"and the filesystem has {st.f_favail:,} free: write .hdf5 (one file per dataset), "
            "collect fewer episodes, or use a filesystem with more inodes"
        )


def out_of_room(path: Path) -> tuple[str, str]:
    """What a write refused with ENOSPC ran out of, and a hint: ``("disk full", "")``, or the filesystem's inodes
    while bytes are left (a zarr PickCube demo written alone takes 81 inodes: 52 files, 29 folders; ext4 gives one
    inode per 16 KiB of disk by default, so a zarr dataset can use up the inodes long before the bytes)."""
    try:
        st = os.statvfs(path if path.exists() else path.parent)
    except OSError:
        return "disk full", ""
    if st.f_files == 0 or st.f_favail > 0:
        return "disk full", ""
    free = st.f_bavail * st.f_frsize / 2**30
    return "out of inodes", (
        f" ({free:.1f} GiB still free, no file can be made: write .hdf5, one file per dataset, "
        "or use a filesystem with more inodes)"
    )
