"""LeRobot's own loader (lerobot 0.4.4 ``LeRobotDataset``) reads ``export_lerobot`` folders: an AV1 video export
(lossy: frames within ``VIDEO_ERROR`` of the source, identical to PyAV's decode of the same file) and a PNG export
(exact). LeRobot runs in the overlay environment that ``tools/lerobot_env.sh`` builds next to this venv (why it
holds what it holds: the script's header). Never skipped: an overlay that cannot be built fails the test."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_lerobot_export import IMAGE, STATE_ORDER, TASK, make_dataset

from newton_lab.datasets import read_episode
from newton_lab.datasets.lerobot import export_lerobot
from newton_lab.datasets.lerobot.video import decode_frames

REPO = Path(__file__).resolve().parents[1]
LEROBOT_PYTHON = "NEWTON_LAB_LEROBOT_PYTHON"
"""Names another Python with lerobot 0.4.4 and torchcodec (e.g. a full ``pip install lerobot``) to use instead."""
KEY = f"observation.images.{IMAGE}"
VIDEO_ERROR = {"mean": 2.0, "p99": 8.0, "max": 24.0}
"""Bounds (of 255) on an episode's decoded AV1 frames against their source: mean and 99th percentile of the per-value
error, and its largest value (isolated values at sharp edges: yuv420p halves the chroma resolution). Measured on
these frames: mean 0.53-0.62, p99 4, max 9-12 (LeRobot's encoder settings: AV1, CRF 30)."""
LOADER = """
import json, sys
import numpy as np
from lerobot.datasets.lerobot_dataset import LeRobotDataset
for root, repo_id, out in zip(*[iter(sys.argv[1:])] * 3):
    ds = LeRobotDataset(repo_id, root=root)
    items = [ds[i] for i in range(len(ds))]
    np.savez(out, **{k: np.stack([np.asarray(it[k]) for it in items]) for k in items[0] if k != "task"})
    print(json.dumps({"root": root, "episodes": ds.num_episodes, "fps": ds.fps, "frames": len(ds),
                      "video_backend": ds.video_backend, "tasks": sorted({it["task"] for it in items})}))
"""


def lerobot_python() -> str:
    """``NEWTON_LAB_LEROBOT_PYTHON``, else the overlay's Python (built by tools/lerobot_env.sh if missing or stale)."""
    if os.environ.get(LEROBOT_PYTHON):
        return os.environ[LEROBOT_PYTHON]
    proc = subprocess.run(
        ["bash", str(REPO / "tools/lerobot_env.sh"), sys.executable, str(REPO / ".venv-lerobot")],
        capture_output=True,
        text=True,
        timeout=900,
    )
    if proc.returncode != 0:
        pytest.fail(f"tools/lerobot_env.sh failed (exit {proc.returncode}):\n{proc.stderr[-4000:]}", pytrace=False)
    return proc.stdout.strip().splitlines()[-1]


@pytest.fixture(scope="module")
def loaded(tmp_path_factory):
    """Both exports of one source, and what LeRobot read from each: {kind: (source, root, summary, meta, arrays)}."""
    tmp = tmp_path_factory.mktemp("lerobot")
    src = make_dataset(tmp / "src.hdf5", image=(72, 96), motion=4)  # frames 4 levels apart
    exports = {kind: (tmp / kind, export_lerobot(src, tmp / kind, video=kind == "video")) for kind in ("video", "png")}
    env = dict(os.environ, HF_HUB_OFFLINE="1", HF_DATASETS_OFFLINE="1", HF_HOME=str(tmp / "hf"))
    args = [a for kind, (root, s) in exports.items() for a in (str(root), s["repo_id"], str(tmp / f"{kind}.npz"))]
    proc = subprocess.run([lerobot_python(), "-c", LOADER, *args], capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr[-4000:]
    metas = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
    return {
        kind: (src, root, summary, meta, dict(np.load(tmp / f"{kind}.npz")))
        for (kind, (root, summary)), meta in zip(exports.items(), metas)
    }


def check_low_dim(src: Path, summary: dict, meta: dict, arrays: dict) -> None:
    """Counts, indexes, timestamps and the task as exported; actions and state bit for bit."""
    assert (meta["episodes"], meta["fps"], meta["frames"]) == (2, 20, summary["frames"])
    assert meta["tasks"] == [TASK]
    lo = 0
    for e, demo in enumerate(summary["demo_ids"]):
        ep = read_episode(src, demo)
        hi = lo + len(ep["actions"])
        assert arrays["episode_index"][lo:hi].tolist() == [e] * (hi - lo)
        assert arrays["frame_index"][lo:hi].tolist() == list(range(hi - lo))
        np.testing.assert_array_equal(arrays["timestamp"][lo:hi], (np.arange(hi - lo) / 20).astype(np.float32))
        assert arrays["action"].dtype == np.float32 and np.array_equal(arrays["action"][lo:hi], ep["actions"])
        state = np.concatenate([ep["obs"][t].astype(np.float32) for t in STATE_ORDER], axis=1)
        assert np.array_equal(arrays["observation.state"][lo:hi], state)
        lo = hi
    assert arrays["index"].tolist() == list(range(summary["frames"]))


def as_uint8(images: np.ndarray) -> np.ndarray:
    """LeRobot's (N, 3, H, W) float frames in [0, 1] back to (N, H, W, 3) uint8 (they are uint8 / 255)."""
    assert images.dtype == np.float32 and images.min() >= 0 and images.max() <= 1
    out = np.rint(images * 255)
    assert np.abs(out - images * 255).max() < 1e-3  # whole levels: nothing resampled or filtered
    return out.astype(np.uint8).transpose(0, 2, 3, 1)


def test_lerobot_reads_the_png_export_exactly(loaded):
    src, _root, summary, meta, arrays = loaded["png"]
    check_low_dim(src, summary, meta, arrays)
    got = as_uint8(arrays[KEY])
    want = np.concatenate([read_episode(src, d)["obs"][IMAGE] for d in summary["demo_ids"]])
    assert np.array_equal(got, want)


def test_lerobot_reads_the_video_export_within_the_codec_error(loaded):
    """torchcodec (through FFmpeg 8) decodes the frame LeRobot picks by timestamp: equal to PyAV's decode of the same
    frame of the mp4, and within the stated error of the source (AV1, CRF 30, yuv420p: lossy)."""
    src, root, summary, meta, arrays = loaded["video"]
    assert meta["video_backend"] == "torchcodec"
    check_low_dim(src, summary, meta, arrays)
    got = as_uint8(arrays[KEY])
    decoded, _ = decode_frames(root / summary["video_files"][0])
    assert all(not np.array_equal(a, b) for a, b in zip(decoded, decoded[1:]))  # so equality pins each frame
    assert np.array_equal(got, decoded)  # the right frame for every timestamp, decoded alike
    lo = 0
    for demo in summary["demo_ids"]:
        source = read_episode(src, demo)["obs"][IMAGE]
        error = np.abs(got[lo : lo + len(source)].astype(np.int16) - source)
        stats = {"mean": error.mean(), "p99": np.percentile(error, 99), "max": error.max()}
        print(f"demo {demo}: error / 255", {k: round(float(v), 2) for k, v in stats.items()})
        assert all(stats[k] <= VIDEO_ERROR[k] for k in VIDEO_ERROR), (stats, VIDEO_ERROR)
        lo += len(source)
