"""Merge cost: two shards of N demos each merged into a new dataset of each format (``merge_datasets``, the way
``--runner dask`` merges its shards); one JSON line per (shard format -> output format) with ms per demo.
The shards hold the demos of ``--source`` (a collected dataset, cycled) or synthetic ones (``append_cost``).

    .venv/bin/python tools/merge_cost.py [--source DATASET] [--demos 64] [--dir DIR]
"""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
from append_cost import episode

from newton_lab.datasets import list_demos, open_writer, read_episode
from newton_lab.datasets.merge import merge_datasets


def shard(path: Path, demos: list[dict], n: int) -> None:
    with open_writer(path, task_id="merge_cost", env_args={}) as w:
        for start in range(0, n, 64):
            w.append_episodes([(demos[k % len(demos)], True, {"k": k}) for k in range(start, min(n, start + 64))])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--source", type=Path, default=None, help="a dataset whose demos fill the shards")
    ap.add_argument("--demos", type=int, default=64, help="demos per shard")
    ap.add_argument("--dir", type=Path, default=None, help="where to write (default: a temporary folder, removed)")
    args = ap.parse_args()
    if args.source is not None:
        demos = [
            {k: v for k, v in read_episode(args.source, i).items() if k != "attrs"} for i in list_demos(args.source)[:8]
        ]
    else:
        rng = np.random.default_rng(0)
        demos = [episode(rng, 170) for _ in range(8)]
    root = Path(tempfile.mkdtemp(dir=args.dir, prefix="merge_cost_"))
    try:
        for src in ("hdf5", "zarr"):
            shards = [root / f"{src}_{i}.{src}" for i in range(2)]
            for p in shards:
                shard(p, demos, args.demos)
            for out_fmt in ("hdf5", "zarr"):
                out = root / f"out_{src}.{out_fmt}"
                t0 = time.perf_counter()
                merge_datasets(shards, out)
                ms = 1e3 * (time.perf_counter() - t0) / (2 * args.demos)
                print(
                    json.dumps(
                        {
                            "shards": src,
                            "output": out_fmt,
                            "demos": 2 * args.demos,
                            "ms_per_demo": round(ms, 2),
                            "same_format": src == out_fmt,
                        }
                    ),
                    flush=True,
                )
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
