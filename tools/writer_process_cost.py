"""What collect's writer process costs, without physics: real demos of a stored PickCube dataset (``--source``, e.g. a
CPU ``bench-collect`` of PickCube) laid back into the recorder's column blocks and handed to a ``ProcessWriter`` the
way a 4096-row GPU loop hands them: ``--bursts`` blocks of ``--per-burst`` demos, ``--gap-ms`` apart (the GPU step),
into a fresh zarr dataset under ``--dir``. Prints one line: the loop's seconds, the seconds until every demo is
written, and the writer process's batch-write seconds (``writer_s`` of ``bench-collect``, split into files and sync).

    .venv/bin/python tools/writer_process_cost.py --source src.zarr --dir /tmp/wpc [--bursts 600] [--per-burst 28]
        [--gap-ms 6] [--min-batch 256]
"""

from __future__ import annotations

import argparse
import shutil
import time
from pathlib import Path

import numpy as np

from newton_lab.datasets import list_demos, open_writer, read_episodes
from newton_lab.datasets.writers.process import ProcessWriter
from newton_lab.envs import make_env
from newton_lab.envs.recorder import EpisodeRecorder, env_args

TASK = "GalbotG1-PickCube-v0"


def _flat(tree: dict, prefix: str = "") -> dict[str, np.ndarray]:
    out = {}
    for key, value in tree.items():
        if key != "attrs":
            out.update(_flat(value, f"{prefix}{key}/") if isinstance(value, dict) else {prefix + key: value})
    return out


def _frames(layout, episode: dict) -> np.ndarray:
    """One recorded episode back as its rows of a column block (``columns.ColumnLayout``)."""
    flat = _flat(episode)
    steps = flat["actions"].shape[0]
    out = np.zeros((steps, layout.width), np.float32)
    q = layout.frame["states/joint_q"][1] - layout.frame["states/joint_q"][0]
    for key, (a, b) in layout.frame.items():
        value = {"states/joint_q": flat["states"][:, :q], "states/joint_qd": flat["states"][:, q:]}.get(key)
        out[:, a:b] = (flat[key] if value is None else value).reshape(steps, -1)
    out[:, layout.frame_width] = flat["rewards"]
    after = layout.frame_width + 1
    for key, (a, b) in layout.next_obs.items():
        out[:, after + a : after + b] = flat[f"next_obs/{key}"]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--source", required=True)
    ap.add_argument("--dir", required=True)
    ap.add_argument("--bursts", type=int, default=600)
    ap.add_argument("--per-burst", type=int, default=28)
    ap.add_argument("--gap-ms", type=float, default=6.0)
    ap.add_argument("--min-batch", type=int, default=256)
    ap.add_argument("--profile", default=None, help="save a cProfile of the writer process's batch writes here")
    args = ap.parse_args()
    env = make_env(TASK, num_envs=1, device="cpu", seed=0, randomize=True, cameras=False)
    layout = EpisodeRecorder(env, 8).layout
    frames = [_frames(layout, ep) for ep in read_episodes(args.source, list_demos(args.source)[:224])]
    span = max(len(f) for f in frames)
    path = Path(args.dir) / "writer_process_cost.zarr"
    shutil.rmtree(path, ignore_errors=True)
    open_writer(path, task_id=TASK, env_args=env_args(env))
    writer = ProcessWriter(
        path, task_id=TASK, layout=layout, max_queued=4096, min_batch=args.min_batch, profile_to=args.profile
    )
    time.sleep(1.0)  # the process has started
    t0 = time.perf_counter()
    for b in range(args.bursts):
        pick = [(b * args.per_burst + k) % len(frames) for k in range(args.per_burst)]
        block = np.zeros((len(pick), span, layout.width), np.float32)
        for k, i in enumerate(pick):
            block[k, : len(frames[i])] = frames[i]
        writer.put_block(block, {}, [(k, len(frames[i]), True, {"seed": 0}) for k, i in enumerate(pick)])
        time.sleep(args.gap_ms / 1e3)
    loop = time.perf_counter() - t0
    writer.close()
    s = writer.seconds
    print(
        f"{args.bursts * args.per_burst} demos: loop {loop:.2f} s, all written after {time.perf_counter() - t0:.2f} s; "
        f"writer_s {s['write']:.2f} (files {s['files']:.2f}, sync {s['sync']:.2f}), {writer.batches} batches"
    )


if __name__ == "__main__":
    main()
