"""Image recording: collect and mimic write the env's image terms per frame into HDF5 (one frame per chunk) and zarr
(~1 MB chunks along time), compressed; the recorded frames are what ``env.sensors.images`` showed at that step; a
SIGKILLed image collect keeps every finished episode readable; a state-only env renders nothing."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
import zarr
from test_crash_campaign import read_all

from newton_lab.agents import BaseAgent
from newton_lab.datasets import read_dataset_info, read_episode

TASK = "GalbotG1-PickCube-v0"
SMALL = (96, 72)
ALL_DATA = ("rgb", "depth", "segmentation")


def cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "newton_lab.cli", *args]


def image_chunks(path: Path, key: str) -> tuple[tuple[int, ...], str]:
    """(chunk shape, codec name) of the array ``data/demo_0/<key>``."""
    if path.suffix == ".zarr":
        a = zarr.open_group(str(path), mode="r")[f"data/demo_0/{key}"]
        return tuple(a.chunks), a.metadata.codecs[-1].to_dict()["name"]
    with h5py.File(path, "r") as f:
        d = f[f"data/demo_0/{key}"]
        return tuple(d.chunks), d.compression


@pytest.fixture(scope="module")
def cam_env():
    """PickCube with front_head RGB + depth + segmentation at 96x72, 2 rows."""
    from newton_lab.envs import make_env

    return make_env(
        TASK,
        num_envs=2,
        device="cpu",
        seed=0,
        randomize=True,
        cameras={"front_head": {"resolution": SMALL, "data": ALL_DATA}},
    )


@pytest.mark.parametrize("suffix", [".zarr", ".hdf5"])
def test_cli_collect_writes_full_size_rgb_frames_in_compressed_chunks(tmp_path, suffix):
    path = tmp_path / f"d{suffix}"
    proc = subprocess.run(
        cli(
            "collect",
            "--task",
            TASK,
            "--episodes",
            "2",
            "--num-envs",
            "2",
            "--max-steps",
            "6",
            "--device",
            "cpu",
            "--no-progress",
            "--dataset-path",
            str(path),
        ),
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    info = read_dataset_info(path)
    assert info["num_demos"] == 2
    cams = info["env_args"]["newton_lab"]["cameras"]
    fh = cams["front_head"]
    assert (fh["width"], fh["height"], fh["data"]) == (298, 224, ["rgb"])
    assert np.allclose(fh["intrinsics"], [[1.1453 * 298, 0, 149], [0, 1.1453 * 298, 112], [0, 0, 1]], rtol=1e-3)
    assert "cube" in fh["segmentation_names"] and fh["segmentation_names"][0] == "background"
    for demo in info["demo_ids"]:
        ep = read_episode(path, demo)
        rgb = ep["obs"]["front_head_rgb"]
        assert rgb.shape == (6, 224, 298, 3) and rgb.dtype == np.uint8
        assert len(np.unique(rgb.reshape(-1, 3), axis=0)) > 4  # a rendered scene, not a cleared buffer
        poses = ep["datagen"]["camera_poses"]["front_head"]
        assert poses.shape == (6, 7) and np.allclose(np.linalg.norm(poses[:, 3:], axis=1), 1, atol=1e-4)
        assert set(ep["obs"]) - {"front_head_rgb"} == set(ep["next_obs"])  # images: obs only
    chunks, codec = image_chunks(path, "obs/front_head_rgb")
    frames = 5 if suffix == ".zarr" else 1  # zarr: ~1 MB along time (a chunk is a file); HDF5: one frame a chunk
    assert chunks == (frames, 224, 298, 3) and codec == ("zstd" if suffix == ".zarr" else "gzip")
    from newton_lab.datasets.lerobot import export_lerobot, validate_lerobot_v3  # deferred: pyarrow, PyAV

    export_lerobot(path, tmp_path / "lerobot", include_failed=True)  # the 6-step episodes did not succeed
    report = validate_lerobot_v3(tmp_path / "lerobot")  # decodes the mp4 of the camera stream
    assert report["video_keys"] == ["observation.images.front_head_rgb"] and report["episodes"] == 2


class Capture(BaseAgent):
    """Wraps an agent; keeps a copy of every image term and camera pose as the agent saw them before each step."""

    def __init__(self, inner):
        self.inner, self.frames = inner, []

    def reset(self, *a, **k):
        return self.inner.reset(*a, **k)

    def act(self, env):
        shot = {name: env.sensors.images[name].clone() for name in env.sensors.image_terms}
        shot["pose"] = env.sensors.cameras.poses("front_head").clone()
        self.frames.append(shot)
        return self.inner.act(env)


@pytest.mark.parametrize(("suffix", "writer"), [(".hdf5", "thread"), (".zarr", "process")])
def test_recorded_frames_equal_env_images(cam_env, tmp_path, suffix, writer):
    """Both writers: the writer process writes the frames straight from its ring (``RowPieces``)."""
    from newton_lab.agents import ZeroAgent

    path = tmp_path / f"eq{suffix}"
    agent = Capture(ZeroAgent())
    ref = cam_env.collect(agent=agent, episodes=2, path=path, max_steps=5, progress=False, writer=writer)
    assert ref.metadata["writer"] == {"thread": "BackgroundWriter", "process": "ProcessWriter"}[writer]
    assert ref["episodes"] == 2 and ref["diverged"] == 0  # depth's inf (sky) is not taken for a divergence
    for demo in read_dataset_info(path)["demo_ids"]:
        ep = read_episode(path, demo)
        row = ep["attrs"]["env_index"]
        assert ep["obs"]["front_head_rgb"].dtype == np.uint8
        assert ep["obs"]["front_head_depth"].dtype == np.float32 and ep["obs"]["front_head_depth"].shape == (5, 72, 96)
        assert ep["obs"]["front_head_segmentation"].dtype == np.int32
        for t in range(5):
            for name in cam_env.sensors.image_terms:
                np.testing.assert_array_equal(ep["obs"][name][t], agent.frames[t][name][row].numpy())
            np.testing.assert_allclose(ep["datagen"]["camera_poses"]["front_head"][t], agent.frames[t]["pose"][row])
        depth = ep["obs"]["front_head_depth"]
        assert (depth[np.isfinite(depth)] > 0.05).all() and np.isfinite(depth).any()  # [m], past the near plane
        assert len(np.unique(ep["obs"]["front_head_segmentation"])) >= 3
    for key in ("obs/front_head_depth", "obs/front_head_segmentation"):
        expected = ((1, 72, 96), "gzip") if suffix == ".hdf5" else ((5, 72, 96), "zstd")  # zarr: ~1 MB time chunks
        assert image_chunks(path, key) == expected


def test_state_only_env_records_and_renders_nothing(pick_env, tmp_path):
    from newton_lab.agents import ZeroAgent

    path = tmp_path / "state.zarr"
    pick_env.collect(agent=ZeroAgent(), episodes=2, path=path, max_steps=3, progress=False)
    ep = read_episode(path, 0)
    assert not [k for k in ep["obs"] if k.startswith("front_head")] and "camera_poses" not in ep["datagen"]
    assert read_dataset_info(path)["env_args"]["newton_lab"]["cameras"] == {}
    assert not pick_env.sensors.cameras.built  # no camera was ever built


def test_bad_cameras_option_is_one_line(capsys):
    from newton_lab.cli import main

    assert main(["collect", "--cameras", "front_head=96", "--dataset-path", "x.zarr"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--cameras 'front_head=96'" in err[0] and "front_head=96x72" in err[0]


def test_cameras_option_takes_a_data_list():
    from newton_lab.commands import camera_option

    assert camera_option("front_head=96x72") == {"front_head": (96, 72)}
    assert camera_option("front_head=96x72:rgb,left_wrist=64x48:rgb+depth") == {
        "front_head": {"resolution": (96, 72), "data": ("rgb",)},
        "left_wrist": {"resolution": (64, 48), "data": ("rgb", "depth")},
    }
    for bad in ("front_head=96x72:", "front_head=96x72:rgb+", "front_head=96:rgb"):
        with pytest.raises(ValueError, match="front_head=96x72:rgb"):
            camera_option(bad)


@pytest.mark.slow
def test_sigkill_mid_image_collection_keeps_finished_episodes(tmp_path):
    path = tmp_path / "killed.zarr"
    proc = subprocess.Popen(
        cli(
            "collect",
            "--task",
            TASK,
            "--episodes",
            "200",
            "--num-envs",
            "1",
            "--max-steps",
            "12",
            "--device",
            "cpu",
            "--no-progress",
            "--cameras",
            "front_head=96x72",
            "--dataset-path",
            str(path),
        ),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    seen = 0
    try:
        deadline = time.time() + 600
        while time.time() < deadline and proc.poll() is None and seen < 3:
            time.sleep(0.3)
            if path.exists():
                try:
                    seen = read_dataset_info(path)["num_demos"]
                except Exception:  # noqa: BLE001 - mid-creation
                    continue
        assert seen >= 3, "collection did not write three episodes in time"
        time.sleep(0.2)  # land inside a later episode or write
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    ids, problems = read_all(path)
    assert len(ids) >= seen and not problems, problems
    for demo in ids:
        assert read_episode(path, demo)["obs"]["front_head_rgb"].shape == (12, 72, 96, 3)
    assert json.dumps(read_dataset_info(path)["env_args"]["newton_lab"]["cameras"])


@pytest.mark.slow
def test_mimic_of_an_image_source_writes_images(tmp_path):
    from newton_lab.agents import PlannerAgent
    from newton_lab.envs import make_env
    from newton_lab.mimic import mimic

    env = make_env(TASK, num_envs=1, device="cpu", seed=0, randomize=True, cameras={"front_head": SMALL})
    src = env.collect(
        agent=PlannerAgent.from_task(TASK), episodes=1, path=tmp_path / "src.zarr", max_steps=400, progress=False
    )
    assert src["successes"] == 1
    ref = mimic(
        src, episodes=1, num_envs=2, output_path=tmp_path / "gen.hdf5", device="cpu", progress=False, max_attempts=6
    )
    assert ref.metadata["successes"] == 1
    info = read_dataset_info(ref.path)
    assert info["env_args"]["newton_lab"]["cameras"]["front_head"]["width"] == SMALL[0]
    ep = read_episode(ref.path, info["demo_ids"][0])
    assert ep["obs"]["front_head_rgb"].shape == (len(ep["actions"]), SMALL[1], SMALL[0], 3)
    assert ep["datagen"]["camera_poses"]["front_head"].shape == (len(ep["actions"]), 7)


def test_image_buffers_too_large_for_the_device_end_in_one_line():
    """Growing the per-row image buffers past the device's memory (e.g. 298x224 frames at thousands of rows) is
    a one-line MemoryError naming the fixes, not an allocator traceback."""
    import torch

    from newton_lab.envs.frame_chunks import FrameChunks

    frames = FrameChunks("front_head_rgb", 10**9, (224, 298, 3), torch.uint8, "cpu")  # no env needed
    with pytest.raises(
        MemoryError,
        match=r"front_head_rgb of 1000000000 rows for 64 steps needs 11936187\.7 GiB "
        r"on cpu, .*--cameras none",
    ):
        frames.grow(0)
