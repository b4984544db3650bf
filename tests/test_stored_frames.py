"""Image frames copied between HDF5 datasets as their compressed chunks (``datasets.hdf5.frames``, what the split by
phase does): the copy reads back frame for frame, holds the source's chunk bytes, and a dataset whose frames are not
stored one deflated frame a chunk is read the ordinary way."""

from __future__ import annotations

from contextlib import closing

import h5py
import numpy as np

from newton_lab.datasets import open_writer, read_episode
from newton_lab.datasets.hdf5 import store
from newton_lab.datasets.hdf5.frames import StoredFrames


def _episode(steps: int = 6) -> dict:
    rng = np.random.default_rng(0)
    frames = np.zeros((steps, 72, 96, 3), np.uint8)
    frames[:, 20:50, 30:70] = rng.integers(0, 255, (steps, 1, 1, 3), dtype=np.uint8)  # a block of a colour a frame
    return {"actions": rng.normal(size=(steps, 4)).astype(np.float32), "obs": {"front_head_rgb": frames}}


def _chunk(path, key: str, frame: int) -> tuple[int, bytes]:
    with h5py.File(path, "r") as f:
        return f[f"data/demo_0/{key}"].id.read_direct_chunk((frame, 0, 0, 0))


def test_frames_copied_as_stored_read_back_frame_for_frame(tmp_path):
    source, copy = tmp_path / "a.hdf5", tmp_path / "b.hdf5"
    ep = _episode()
    with open_writer(source, task_id="GalbotG1-PickCube-v0", env_args={}) as w:
        w.append_episode(ep, success=True)
    with closing(store.read_many(source, [0], None, stored_frames=True)) as items:
        (tree,) = list(items)
    frames = tree["obs"]["front_head_rgb"]
    assert isinstance(frames, StoredFrames) and frames.shape == (6, 72, 96, 3)
    np.testing.assert_array_equal(np.asarray(frames), ep["obs"]["front_head_rgb"])  # inflated on demand
    rows = np.array([1, 3, 4])
    segment = {"actions": tree["actions"][rows], "obs": {"front_head_rgb": frames.select(rows)}}
    with open_writer(copy, task_id="GalbotG1-PickCube-v0", env_args={}) as w:
        w.append_episodes([(segment, True, {})])
    back = read_episode(copy, 0)
    np.testing.assert_array_equal(back["obs"]["front_head_rgb"], ep["obs"]["front_head_rgb"][rows])
    for i, r in enumerate(rows):  # the very chunk bytes: nothing was deflated again
        assert _chunk(copy, "obs/front_head_rgb", i) == _chunk(source, "obs/front_head_rgb", int(r))


def test_frames_stored_otherwise_are_read_as_arrays(tmp_path):
    path = tmp_path / "a.hdf5"
    with open_writer(path, task_id="GalbotG1-PickCube-v0", env_args={}) as w:
        w.append_episode(_episode(), success=True)
    with h5py.File(path, "r+") as f:  # the same frames two a chunk: not one frame a chunk
        g = f["data/demo_0/obs"]
        frames = g["front_head_rgb"][()]
        del g["front_head_rgb"]
        g.create_dataset("front_head_rgb", data=frames, chunks=(2, 72, 96, 3), compression="gzip")
    with closing(store.read_many(path, [0], None, stored_frames=True)) as items:
        (tree,) = list(items)
    assert isinstance(tree["obs"]["front_head_rgb"], np.ndarray)
    np.testing.assert_array_equal(tree["obs"]["front_head_rgb"], frames)


def test_new_frames_are_deflated_on_threads_as_hdf5_would(tmp_path):
    """A written episode's frames are one zlib stream a chunk at ``FRAME_DEFLATE_LEVEL`` (the bytes HDF5's deflate
    filter writes), and a frame deflate cannot shrink (noise) is stored raw with the filter skipped: h5py reads
    both back as they were."""
    import zlib

    from newton_lab.datasets.hdf5.frames import FRAME_DEFLATE_LEVEL

    path = tmp_path / "a.hdf5"
    ep = _episode(steps=70)  # more frames than one deflate task holds
    noise = np.random.default_rng(1).integers(0, 255, (72, 96, 3), dtype=np.uint8)
    ep["obs"]["front_head_rgb"][5] = noise
    with open_writer(path, task_id="GalbotG1-PickCube-v0", env_args={}) as w:
        w.append_episode(ep, success=True)
    frames = ep["obs"]["front_head_rgb"]
    for i in (0, 69):
        mask, data = _chunk(path, "obs/front_head_rgb", i)
        assert mask == 0 and data == zlib.compress(frames[i].tobytes(), FRAME_DEFLATE_LEVEL)
    assert _chunk(path, "obs/front_head_rgb", 5) == (1, noise.tobytes())
    with h5py.File(path, "r") as f:
        dset = f["data/demo_0/obs/front_head_rgb"]
        assert dset.chunks == (1, 72, 96, 3) and dset.compression == "gzip"
        assert dset.compression_opts == FRAME_DEFLATE_LEVEL
        np.testing.assert_array_equal(dset[()], frames)
    np.testing.assert_array_equal(read_episode(path, 0)["actions"], ep["actions"])
