"""Append cost vs dataset size: append N small synthetic episodes (T steps x 60 floats) to an HDF5 and a zarr
dataset in batches (``EpisodeWriter.append_episodes``) and print the per-episode cost of the first and the
last 100 episodes (ms, from the wall time of the batches that wrote them), one JSON line per format.

    .venv/bin/python tools/append_cost.py [--episodes 10000] [--batch 64] [--steps 100] [--dir DIR] [--no-fsync]
"""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from newton_lab.datasets import open_writer


def episode(rng: np.random.Generator, steps: int) -> dict:
    """~60 floats per step: actions (8), obs (3 terms, 31), states (18), rewards, dones."""
    f = np.float32
    return {
        "actions": rng.standard_normal((steps, 8)).astype(f),
        "obs": {
            "joint_pos": rng.standard_normal((steps, 17)).astype(f),
            "tcp_pose": rng.standard_normal((steps, 7)).astype(f),
            "cube_pose": rng.standard_normal((steps, 7)).astype(f),
        },
        "states": rng.standard_normal((steps, 18)).astype(f),
        "rewards": rng.standard_normal(steps).astype(f),
        "dones": np.zeros(steps, np.int64),
    }


def run(path: Path, episodes: int, batch: int, steps: int, fsync: bool) -> dict:
    rng = np.random.default_rng(0)
    pool = [episode(rng, steps) for _ in range(8)]  # the content does not change the cost
    per_episode = np.zeros(episodes)  # ms, each episode's share of its batch
    with open_writer(path, task_id="append_cost", env_args={}, fsync=fsync) as w:
        t_all = time.perf_counter()
        for start in range(0, episodes, batch):
            n = min(batch, episodes - start)
            items = [(pool[(start + k) % len(pool)], True, {"k": start + k}) for k in range(n)]
            t0 = time.perf_counter()
            if hasattr(w, "append_episodes"):
                ids = w.append_episodes(items)
            else:  # a newton_lab from before batches (for a before/after figure): one append per episode
                ids = [w.append_episode(ep, success=ok, attrs=attrs) for ep, ok, attrs in items]
            per_episode[start : start + n] = 1e3 * (time.perf_counter() - t0) / n
            assert ids == list(range(start, start + n))
        total_s = time.perf_counter() - t_all
    first, last = per_episode[:100].mean(), per_episode[-100:].mean()
    return {
        "format": path.suffix[1:],
        "episodes": episodes,
        "batch": batch,
        "steps": steps,
        "fsync": fsync,
        "first_100_ms_per_episode": round(float(first), 3),
        "last_100_ms_per_episode": round(float(last), 3),
        "last_over_first": round(float(last / first), 3),
        "total_s": round(total_s, 1),
        "bytes_per_episode": int(
            sum(f.stat().st_size for f in ([path] if path.is_file() else path.rglob("*")) if f.is_file()) / episodes
        ),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=10_000)
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--formats", default="hdf5,zarr")
    ap.add_argument("--dir", type=Path, default=None, help="where to write (default: a temporary folder, removed)")
    ap.add_argument("--no-fsync", action="store_true")
    args = ap.parse_args()
    if args.episodes < 200 or args.batch < 1:
        ap.error("--episodes must be >= 200 (first and last 100) and --batch >= 1")
    root = Path(tempfile.mkdtemp(dir=args.dir, prefix="append_cost_"))
    try:
        for fmt in args.formats.split(","):
            print(
                json.dumps(run(root / f"d.{fmt}", args.episodes, args.batch, args.steps, not args.no_fsync)), flush=True
            )
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
