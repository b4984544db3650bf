"""What file creation costs the zarr writer on one filesystem, and whether two writers at once share it.

Takes one stored demo (``--source``, any dataset), has the zarr store's batch writer write it ``--demos`` times into
``--dir`` as the store does in a batch (``zarr.batch_writes.write_batch``, ``--threads`` threads), then one
``syncfs``: once as one group per demo (``demo_<i>``), once packed (``zarr.packs``, one pack); beside it the same
bytes as one file per demo and as one file, each also synced.
``--copies 2`` runs two such writers at once (two processes, as two Dask workers on one host would), each in its
own folder. One JSON line per writer; the folders are removed afterwards.

    .venv/bin/python tools/zarr_file_cost.py --source D.zarr --dir /path/on/disk [--demos 4096] [--threads 8]
        [--copies 2]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from newton_lab.datasets import list_demos, read_episode
from newton_lab.datasets.files.durability import sync_tree
from newton_lab.datasets.zarr.batch_writes import write_batch
from newton_lab.datasets.zarr.packs import batch_jobs
from newton_lab.datasets.zarr.settings import ZarrWriteSettings


def _arrays(tree: dict) -> dict:
    return {k: _arrays(v) if isinstance(v, dict) else np.asarray(v) for k, v in tree.items() if k != "attrs"}


def _copied(tree: dict) -> dict:
    return {k: _copied(v) if isinstance(v, dict) else v.copy() for k, v in tree.items()}


def _write_files(folder: Path, blob: bytes, count: int) -> None:
    for i in range(count):
        fd = os.open(folder / f"demo_{i}", os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
        try:
            os.write(fd, blob)
        finally:
            os.close(fd)


def _timed(fn, folder: Path) -> tuple[float, float]:
    """(seconds writing, seconds in the ``syncfs`` after it)."""
    t0 = time.perf_counter()
    fn()
    t1 = time.perf_counter()
    sync_tree(folder)
    return t1 - t0, time.perf_counter() - t1


def measure(source: str, root: Path, demos: int, threads: int) -> dict:
    tree = _arrays(read_episode(source, list_demos(source)[0]))
    num_samples = len(tree["actions"])
    shutil.rmtree(root, ignore_errors=True)
    folders = {name: root / name for name in ("zarr", "packed", "per_demo", "single")}
    for folder in folders.values():
        folder.mkdir(parents=True)
    sync_tree(root)
    settings = ZarrWriteSettings(write_threads=threads, pack_threads=threads, pack_min_batch=1)
    trees = [_copied(tree) for _ in range(demos)]  # each demo its own arrays
    jobs = [(folders["zarr"] / f"demo_{i}", {"num_samples": num_samples}, t) for i, t in enumerate(trees)]
    zarr_s = _timed(lambda: write_batch(folders["zarr"], jobs, settings), folders["zarr"])
    packs = batch_jobs(folders["packed"], list(range(demos)), [(t, {}, num_samples) for t in trees], 1)
    packed_s = _timed(lambda: write_batch(folders["packed"], packs, settings), folders["packed"])
    demo = list(folders["zarr"].glob("demo_0/**/*"))
    size = sum(p.stat().st_size for p in demo if p.is_file())
    blob = os.urandom(size)
    per_demo_s = _timed(lambda: _write_files(folders["per_demo"], blob, demos), folders["per_demo"])
    single_s = _timed(lambda: _write_files(folders["single"], blob * demos, 1), folders["single"])
    out = {
        "dir": str(root),
        "demos": demos,
        "threads": threads,
        "bytes_per_demo": size,
        "inodes_per_demo": len(demo) + 1,
        "zarr_write_s": zarr_s[0],
        "zarr_sync_s": zarr_s[1],
        "packs": len(packs),
        "packed_inodes_per_demo": sum(1 for _ in folders["packed"].rglob("*")) / demos,
        "packed_write_s": packed_s[0],
        "packed_sync_s": packed_s[1],
        "one_file_per_demo_write_s": per_demo_s[0],
        "one_file_per_demo_sync_s": per_demo_s[1],
        "one_file_write_s": single_s[0],
        "one_file_sync_s": single_s[1],
    }
    shutil.rmtree(root, ignore_errors=True)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--source", required=True, help="a dataset (.zarr or .hdf5) whose first demo is written")
    parser.add_argument("--dir", required=True, help="a folder on the filesystem to measure (removed afterwards)")
    parser.add_argument("--demos", type=int, default=4096)
    parser.add_argument("--threads", type=int, default=8, help="writer threads per writer")
    parser.add_argument("--copies", type=int, default=1, help="writers at once, each in <dir>/<i>")
    args = parser.parse_args()
    if args.copies == 1:
        print(json.dumps(measure(args.source, Path(args.dir), args.demos, args.threads)))
        return
    runs = [
        subprocess.Popen(
            [
                sys.executable,
                __file__,
                "--source",
                args.source,
                "--dir",
                f"{args.dir}/{i}",
                "--demos",
                str(args.demos),
                "--threads",
                str(args.threads),
            ]
        )
        for i in range(args.copies)
    ]
    sys.exit(max(run.wait() for run in runs))


if __name__ == "__main__":
    main()
