"""What writing camera frames to HDF5 costs, side by side in one run: the demos of a stored HDF5 dataset with frames
(``--source``, e.g. ``newton-lab collect --cameras front_head=96x72:rgb,left_wrist=96x72:rgb ... --dataset-path
src.hdf5``) appended ``--copies`` times to a fresh dataset (a) as the writer does (``hdf5.frames.StoredFrames.deflate``:
every core, ``FRAME_DEFLATE_LEVEL``) and (b) through HDF5's own gzip filter in the writing thread at ``--filter-level``
(the writer's former way, level 4). Prints one JSON line: frames, seconds and MB of each, and the ratio.

    .venv/bin/python tools/frame_deflate_cost.py --source src.hdf5 [--copies 8] [--filter-level 4] [--dir DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path
from unittest import mock

from newton_lab.datasets.hdf5 import store


def _append(path: Path, items: list) -> float:
    store.create(path, {}, fsync=False)
    start = time.perf_counter()
    store.append(path, items, fsync=False)
    return time.perf_counter() - start


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--source", type=Path, required=True)
    ap.add_argument("--copies", type=int, default=8)
    ap.add_argument("--filter-level", type=int, default=4)
    ap.add_argument("--dir", type=Path, default=None)
    args = ap.parse_args()
    ids = sorted(store.info(args.source)["demos"])
    trees = [store.read(args.source, i)[0] for i in ids]
    items = [(t, {}, len(t["actions"])) for t in trees] * args.copies
    frames = sum(v.shape[0] for t in trees for v in t.get("obs", {}).values() if v.ndim >= 3) * args.copies
    with tempfile.TemporaryDirectory(dir=args.dir) as tmp:
        threaded = _append(Path(tmp, "threaded.hdf5"), items)
        with (
            mock.patch.object(store, "_deflated", lambda tree: tree),
            mock.patch.object(store, "FRAME_DEFLATE_LEVEL", args.filter_level),
        ):
            in_filter = _append(Path(tmp, "filter.hdf5"), items)
        sizes = {p.stem: p.stat().st_size / 1e6 for p in Path(tmp).glob("*.hdf5")}
    print(
        json.dumps(
            {
                "frames": frames,
                "cores": os.cpu_count(),
                "threaded_s": round(threaded, 3),
                "threaded_mb": round(sizes["threaded"], 1),
                "hdf5_filter_s": round(in_filter, 3),
                "hdf5_filter_mb": round(sizes["filter"], 1),
                "speedup": round(in_filter / threaded, 2),
            }
        )
    )


if __name__ == "__main__":
    main()
