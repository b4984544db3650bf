"""Tests for newton_lab.datasets storage (HDF5 + zarr v3). Fast, no physics."""

from __future__ import annotations

import hashlib
import json
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
import zarr

from newton_lab.datasets import (
    FORMAT_VERSION,
    EpisodeWriter,
    delete_demos,
    list_demos,
    open_writer,
    read_dataset_info,
    read_episode,
    read_episodes,
    read_filter_keys,
    set_filter_keys,
    split_train_val,
    state_tree,
)
from newton_lab.datasets.files.write_faults import inject_write_fault

ROOT = Path(__file__).resolve().parents[1]
TASK = "pick_cube"
ENV_ARGS = {"env_kwargs": {"robot": "g1", "control_freq": 20}}
FORMATS = [".hdf5", ".zarr"]


def make_episode(seed: int, steps: int = 200) -> dict:
    """Deterministic episode with nested groups (also used by the SIGKILL child process)."""
    rng = np.random.default_rng(seed)
    return {
        "actions": rng.standard_normal((steps, 7)).astype(np.float32),
        "obs": {
            "eef_pos": rng.standard_normal((steps, 3)),
            "rgb": rng.integers(0, 255, (steps, 8, 8, 3), dtype=np.uint8),
        },
        "states": {
            "robot": {"qpos": rng.standard_normal((steps, 9)).astype(np.float32)},
            "objects": {"cube": {"pose": rng.standard_normal((steps, 7))}},
        },
        "initial_state": {"robot": {"qpos": rng.standard_normal((1, 9)).astype(np.float32)}},
        "datagen": {
            "subtask_term_signals": {"grasp": rng.random(steps) > 0.5},
            "tcp_pose": rng.standard_normal((steps, 4, 4)).astype(np.float32),
            "scale": np.float64(seed),
        },
    }


def assert_tree_equal(actual: dict, expected: dict, where: str = "") -> None:
    assert sorted(actual) == sorted(expected), where
    for key, exp in expected.items():
        if isinstance(exp, dict):
            assert_tree_equal(actual[key], exp, f"{where}/{key}")
        else:
            exp = np.asarray(exp)
            got = actual[key]
            assert isinstance(got, np.ndarray), f"{where}/{key}"
            assert got.dtype == exp.dtype and got.shape == exp.shape, f"{where}/{key}"
            np.testing.assert_array_equal(got, exp, err_msg=f"{where}/{key}")


def fingerprint(path: Path) -> str:
    """Hash of a file or of a directory tree (names + bytes)."""
    h = hashlib.sha256()
    files = [path] if path.is_file() else sorted(p for p in path.rglob("*") if p.is_file())
    for f in files:
        h.update(str(f.relative_to(path.parent)).encode())
        h.update(f.read_bytes())
    return h.hexdigest()


def stored_root_attrs(path: Path) -> dict:
    """`data` attrs read with h5py/zarr directly (not through newton_lab)."""
    if path.suffix == ".zarr":
        return dict(zarr.open_group(str(path), mode="r", zarr_format=3)["data"].attrs.asdict())
    with h5py.File(path, "r") as f:
        return {k: (v.item() if hasattr(v, "item") else v) for k, v in f["data"].attrs.items()}


def write_demos(path: Path, seeds, task: str = TASK) -> list[int]:
    with EpisodeWriter.open(path, task_id=task, env_args=ENV_ARGS) as w:
        return [
            w.append_episode(
                make_episode(s),
                success=s % 2 == 0,
                attrs={"seed": s, "termination_reason": "success" if s % 2 == 0 else "timeout", "episode_length": 200},
            )
            for s in seeds
        ]


@pytest.mark.parametrize("suffix", [".hdf5", ".h5", ".zarr"])
def test_round_trip(tmp_path, suffix):
    path = tmp_path / f"ds{suffix}"
    assert write_demos(path, [0, 1, 2]) == [0, 1, 2]

    info = read_dataset_info(path)
    assert info["task_id"] == TASK and info["format_version"] == FORMAT_VERSION == 2
    assert info["env_args"] == {"env_name": TASK, "type": 2, "env_kwargs": ENV_ARGS["env_kwargs"]}
    assert info["num_demos"] == 3 and info["total"] == 600 and info["demo_ids"] == [0, 1, 2]
    assert info["demos"][1] == {"num_samples": 200, "success": False}
    assert list_demos(path) == [0, 1, 2]

    for seed in (0, 1, 2):
        ep = read_episode(path, seed)
        attrs = ep.pop("attrs")
        assert_tree_equal(ep, make_episode(seed))
        assert attrs == {
            "num_samples": 200,
            "success": seed % 2 == 0,
            "seed": seed,
            "episode_length": 200,
            "termination_reason": "success" if seed % 2 == 0 else "timeout",
        }
    assert_tree_equal({k: v for k, v in read_episode(path, "demo_2").items() if k != "attrs"}, make_episode(2))

    raw = stored_root_attrs(path)
    assert raw["total"] == 600 and raw["num_demos"] == 3 and raw["task_id"] == TASK and raw["format_version"] == 2
    assert json.loads(raw["env_args"])["env_name"] == TASK


@pytest.mark.parametrize("suffix", FORMATS)
def test_append_to_existing_continues_ids(tmp_path, suffix):
    path = tmp_path / f"ds{suffix}"
    assert write_demos(path, [0, 1]) == [0, 1]
    assert write_demos(path, [2, 3]) == [2, 3]
    info = read_dataset_info(path)
    assert info["num_demos"] == 4 and info["total"] == 800
    assert_tree_equal({k: v for k, v in read_episode(path, 3).items() if k != "attrs"}, make_episode(3))
    assert stored_root_attrs(path)["num_demos"] == 4


@pytest.mark.parametrize("suffix", FORMATS)
def test_refuses_dataset_of_another_task(tmp_path, suffix):
    path = tmp_path / f"ds{suffix}"
    write_demos(path, [0])
    before = fingerprint(path)
    with pytest.raises(ValueError) as exc:
        open_writer(path, task_id="stack_cubes", env_args={})
    msg = str(exc.value)
    assert TASK in msg and "stack_cubes" in msg and "another path" in msg and "\n" not in msg
    assert fingerprint(path) == before


@pytest.mark.parametrize("suffix", FORMATS)
def test_creates_missing_parents_refuses_a_file_parent(tmp_path, suffix):
    """The rule of every output (``datasets.files.output_paths``): missing folders are created, a file where one
    should be is refused in one line and left as it was."""
    path = tmp_path / "no" / "such" / f"ds{suffix}"
    with open_writer(path, task_id=TASK, env_args={}) as w:
        w.append_episode(make_episode(0, steps=3), success=True)
    assert list_demos(path) == [0]
    (tmp_path / "afile").write_bytes(b"mine")
    for bad in (tmp_path / "afile" / f"ds{suffix}", tmp_path / "afile" / "sub" / f"ds{suffix}"):
        with pytest.raises(ValueError) as exc:
            open_writer(bad, task_id=TASK, env_args={})
        msg = str(exc.value)
        assert f"cannot write {bad}: " in msg and f"{tmp_path / 'afile'}" in msg and "is a file" in msg, msg
        assert "choose another path" in msg and "\n" not in msg
    assert (tmp_path / "afile").read_bytes() == b"mine"


def test_refuses_bad_suffix(tmp_path):
    for call in (lambda p: open_writer(p, task_id=TASK, env_args={}), read_dataset_info, list_demos):
        with pytest.raises(ValueError) as exc:
            call(tmp_path / "ds.npz")
        assert all(s in str(exc.value) for s in (".hdf5", ".h5", ".zarr"))
    assert list(tmp_path.iterdir()) == []


def test_missing_dataset_for_readers(tmp_path):
    for call in (read_dataset_info, list_demos, lambda p: read_episode(p, 0), lambda p: delete_demos(p, [0])):
        with pytest.raises(FileNotFoundError) as exc:
            call(tmp_path / "nope.hdf5")
        assert "nope.hdf5" in str(exc.value) and "\n" not in str(exc.value)


def _corrupt(tmp_path: Path, kind: str) -> Path:
    if kind == "garbage_hdf5":
        path = tmp_path / "x.hdf5"
        path.write_bytes(os.urandom(4096))
    elif kind == "truncated_hdf5":
        path = tmp_path / "x.hdf5"
        write_demos(path, [0, 1])
        path.write_bytes(path.read_bytes()[: path.stat().st_size // 3])
    elif kind == "hdf5_without_data":
        path = tmp_path / "x.hdf5"
        with h5py.File(path, "w") as f:
            f.create_group("something_else")
    elif kind == "garbage_zarr":
        path = tmp_path / "x.zarr"
        path.mkdir()
        (path / "zarr.json").write_bytes(b"\x00not json{")
    elif kind == "empty_zarr_dir":
        path = tmp_path / "x.zarr"
        path.mkdir()
    else:  # a plain file named .zarr
        path = tmp_path / "x.zarr"
        path.write_bytes(b"garbage")
    return path


@pytest.mark.parametrize(
    "kind", ["garbage_hdf5", "truncated_hdf5", "hdf5_without_data", "garbage_zarr", "empty_zarr_dir", "file_named_zarr"]
)
def test_refuses_corrupt_dataset_and_leaves_it_untouched(tmp_path, kind):
    path = _corrupt(tmp_path, kind)
    before = fingerprint(path) if path.is_file() or any(path.iterdir()) else "empty"
    calls = (
        lambda p: open_writer(p, task_id=TASK, env_args={}),
        read_dataset_info,
        list_demos,
        lambda p: read_episode(p, 0),
        lambda p: delete_demos(p, [0]),
    )
    for call in calls:
        with pytest.raises(ValueError) as exc:
            call(path)
        msg = str(exc.value)
        assert "not a newton_lab dataset or is damaged" in msg and "re-collect" in msg and "\n" not in msg
    assert (fingerprint(path) if path.is_file() or any(path.iterdir()) else "empty") == before


@pytest.mark.parametrize("suffix", FORMATS)
def test_delete_demos_keeps_counts_consistent(tmp_path, suffix):
    path = tmp_path / f"ds{suffix}"
    write_demos(path, range(5))
    assert delete_demos(path, [1, "demo_3"]) == [0, 2, 4]
    info = read_dataset_info(path)
    assert info["demo_ids"] == [0, 2, 4] and info["num_demos"] == 3 and info["total"] == 600
    raw = stored_root_attrs(path)
    assert raw["num_demos"] == 3 and raw["total"] == 600

    with pytest.raises(KeyError) as exc:  # unknown id: nothing deleted, message lists what exists
        delete_demos(path, [0, 7])
    assert "0, 2, 4" in str(exc.value)
    assert list_demos(path) == [0, 2, 4]
    with pytest.raises(KeyError, match="0, 2, 4"):
        read_episode(path, 1)

    assert write_demos(path, [5]) == [5]  # ids continue after the highest, never reuse
    assert read_dataset_info(path)["total"] == 800


@pytest.mark.parametrize("suffix", FORMATS)
def test_unknown_demo_id_lists_range(tmp_path, suffix):
    path = tmp_path / f"ds{suffix}"
    write_demos(path, range(3))
    with pytest.raises(KeyError, match=r"0\.\.2"):
        read_episode(path, 9)


@pytest.mark.parametrize("suffix", FORMATS)
def test_read_episodes_reads_many_and_only_the_keys_asked(tmp_path, suffix):
    path = tmp_path / f"ds{suffix}"
    write_demos(path, range(4))
    for seed, ep in zip((2, 0, 3), read_episodes(path, [2, "demo_0", 3])):
        assert_tree_equal(ep, make_episode(seed))
    keys = ["actions", "obs/rgb", "states/robot/qpos", "obs/absent"]
    for seed, ep in zip((1, 2), read_episodes(path, [1, 2], keys=keys)):
        full = make_episode(seed)
        assert_tree_equal(
            ep,
            {
                "actions": full["actions"],
                "obs": {"rgb": full["obs"]["rgb"]},
                "states": {"robot": {"qpos": full["states"]["robot"]["qpos"]}},
            },
        )
    with pytest.raises(KeyError, match=r"0\.\.3"):
        list(read_episodes(path, [0, 9]))


@pytest.mark.parametrize("suffix", FORMATS)
def test_rejects_bad_episodes(tmp_path, suffix):
    path = tmp_path / f"ds{suffix}"
    with open_writer(path, task_id=TASK, env_args={}) as w:
        with pytest.raises(ValueError, match="actions"):
            w.append_episode({"obs": {"x": np.zeros((3, 1))}}, success=True)
        with pytest.raises(ValueError, match="obs/x"):
            w.append_episode({"actions": np.zeros((3, 2)), "obs": {"x": np.zeros((4, 1))}}, success=True)
        with pytest.raises(ValueError, match="num_samples"):
            w.append_episode({"actions": np.zeros((3, 2))}, success=True, attrs={"num_samples": 1})
        with pytest.raises(TypeError):
            w.append_episode({"actions": np.zeros((3, 2)), "names": np.array(["a", "b", "c"])}, success=True)
    assert read_dataset_info(path)["num_demos"] == 0
    with pytest.raises(RuntimeError, match="closed"):
        w.append_episode({"actions": np.zeros((3, 2))}, success=True)


@pytest.mark.parametrize("suffix", FORMATS)
def test_readers_ignore_and_writer_cleans_partial_demos(tmp_path, suffix):
    path = tmp_path / f"ds{suffix}"
    write_demos(path, [0])
    if suffix == ".zarr":  # demo group without the num_samples commit marker
        g = zarr.open_group(str(path), mode="r+", zarr_format=3)["data"].create_group("demo_1")
        g.create_array("actions", data=np.zeros((5, 7), np.float32))
        leftover = path / "data" / "demo_1"
    else:
        with h5py.File(path, "r+") as f:
            f["data"].create_group("_partial_demo_1").create_dataset("actions", data=np.zeros((5, 7)))
        leftover = None
    assert list_demos(path) == [0] and read_dataset_info(path)["total"] == 200
    assert write_demos(path, [1]) == [1]
    assert_tree_equal({k: v for k, v in read_episode(path, 1).items() if k != "attrs"}, make_episode(1))
    if leftover is None:
        with h5py.File(path, "r") as f:
            assert sorted(f["data"]) == ["demo_0", "demo_1"]


# ----------------------------------------------------------------------------- robomimic layout
def stored_masks(path: Path) -> dict:
    """``mask/<key>`` read with h5py / zarr directly: HDF5 holds robomimic's byte strings."""
    if path.suffix == ".zarr":
        root = zarr.open_group(str(path), mode="r", zarr_format=3)
        return {k: [str(n) for n in v[...]] for k, v in root["mask"].arrays()} if "mask" in root else {}
    with h5py.File(path, "r") as f:
        if "mask" not in f:
            return {}
        assert all(v.dtype.kind == "S" for v in f["mask"].values())
        return {k: [n.decode() for n in v[()]] for k, v in f["mask"].items()}


def robomimic_split(names: list[str], val_ratio: float) -> tuple[list[str], list[str]]:
    """robomimic 0.3.0 scripts/split_train_val.py, step by step (np.random.seed(0) in its __main__)."""
    demos = sorted(names)
    num_val = int(val_ratio * len(demos))
    mask = np.zeros(len(demos))
    mask[:num_val] = 1.0
    np.random.seed(0)
    np.random.shuffle(mask)
    mask = mask.astype(int)
    return [demos[i] for i in (1 - mask).nonzero()[0]], [demos[i] for i in mask.nonzero()[0]]


def write_small(path: Path, n: int) -> None:
    """n short demos (even ones successful), no fsync: the filter-key tests need demos, not data."""
    with open_writer(path, task_id=TASK, env_args=ENV_ARGS, fsync=False) as w:
        for i in range(n):
            w.append_episode({"actions": np.full((3, 2), i, np.float32)}, success=i % 2 == 0)


@pytest.mark.parametrize("suffix", FORMATS)
def test_filter_keys_round_trip_and_follow_deletes(tmp_path, suffix):
    path = tmp_path / f"ds{suffix}"
    write_small(path, 4)
    assert read_filter_keys(path) == {} and stored_masks(path) == {}
    assert set_filter_keys(path, {"train": [0, "demo_2", 3], "valid": [1], "none": []}) == {
        "train": ["demo_0", "demo_2", "demo_3"],
        "valid": ["demo_1"],
        "none": [],
    }
    assert set_filter_keys(path, {"valid": ["demo_1", 2]})["valid"] == ["demo_1", "demo_2"]  # replaced, others kept
    want = {"train": ["demo_0", "demo_2", "demo_3"], "valid": ["demo_1", "demo_2"], "none": []}
    assert read_filter_keys(path) == stored_masks(path) == want
    assert read_dataset_info(path)["demo_ids"] == [0, 1, 2, 3]  # masks are not demos
    before = fingerprint(path)
    for keys, words in (({"train": [9]}, ["demo 9", "0..3"]), ({"a/b": [0]}, ["'a/b'"]), ({"_x": [0]}, ["'_x'"])):
        with pytest.raises((KeyError, ValueError)) as exc:
            set_filter_keys(path, keys)
        assert all(w in str(exc.value) for w in words) and "\n" not in str(exc.value)
    assert fingerprint(path) == before
    delete_demos(path, [2])  # robomimic would fail on a mask naming a missing demo: deletes prune them
    assert read_filter_keys(path) == {"train": ["demo_0", "demo_3"], "valid": ["demo_1"], "none": []}


@pytest.mark.parametrize("suffix", FORMATS)
def test_failed_filter_key_write_keeps_the_old_keys(tmp_path, suffix):
    path = tmp_path / f"ds{suffix}"
    write_small(path, 3)
    set_filter_keys(path, {"train": [0, 1], "valid": [2]})
    inject_write_fault(1)
    try:
        with pytest.raises(OSError, match="disk full"):
            set_filter_keys(path, {"train": [0], "valid": [1, 2]})
    finally:
        inject_write_fault(None)
    assert read_filter_keys(path) == {"train": ["demo_0", "demo_1"], "valid": ["demo_2"]}
    assert list_demos(path) == [0, 1, 2]


def test_out_of_inodes_is_told_apart_from_a_full_disk(tmp_path, monkeypatch):
    """ENOSPC with bytes left but no free inode (a zarr dataset of many demos on ext4): the one line says so,
    how much space is still free, and what to do; the dataset keeps what it held."""
    import newton_lab.datasets.zarr.inodes as room

    path = tmp_path / "ds.zarr"
    write_small(path, 2)
    real = os.statvfs(tmp_path)
    stats = dict(
        zip(("f_bsize", "f_frsize", "f_blocks", "f_bfree", "f_bavail", "f_files", "f_ffree", "f_favail"), real[:8])
    )
    monkeypatch.setattr(room.os, "statvfs", lambda p: type("Stat", (), {**stats, "f_favail": 0, "f_ffree": 0}))
    inject_write_fault(1)
    try:
        with EpisodeWriter.open(path, task_id=TASK, env_args=ENV_ARGS) as w, pytest.raises(OSError) as exc:
            w.append_episode({"actions": np.zeros((3, 2), np.float32)}, success=True)
    finally:
        inject_write_fault(None)
    line = str(exc.value)
    assert line.startswith("out of inodes") and f"{path} holds 2 finished episodes" in line and "\n" not in line
    assert "GiB still free" in line and "write .hdf5" in line
    monkeypatch.undo()
    assert list_demos(path) == [0, 1]


@pytest.mark.parametrize("suffix", FORMATS)
def test_split_train_val_matches_robomimic(tmp_path, suffix):
    path = tmp_path / f"ds{suffix}"
    write_small(path, 12)  # names sort as strings: demo_0, demo_1, demo_10, demo_11, demo_2, ...
    keys = split_train_val(path, 0.25)
    train, valid = robomimic_split([f"demo_{i}" for i in range(12)], 0.25)
    assert keys["train"] == sorted(train, key=lambda n: int(n[5:])) and len(valid) == 3
    assert keys["valid"] == sorted(valid, key=lambda n: int(n[5:]))
    assert keys["successful"] == [f"demo_{i}" for i in range(0, 12, 2)]  # write_small: even demos succeed
    inner = split_train_val(path, 0.5, filter_key="successful")  # robomimic --filter_key successful
    s_train, s_valid = robomimic_split(keys["successful"], 0.5)
    assert sorted(inner["successful_train"]) == sorted(s_train) and sorted(inner["successful_valid"]) == sorted(s_valid)
    assert set(stored_masks(path)) == {"successful", "train", "valid", "successful_train", "successful_valid"}
    for bad, words in ((1.0, ["val_ratio", "[0, 1)"]), (-0.1, ["val_ratio"]), ("x", ["val_ratio"])):
        with pytest.raises(ValueError) as exc:
            split_train_val(path, bad)
        assert all(w in str(exc.value) for w in words)
    with pytest.raises(ValueError, match="no filter key 'better'.*available"):
        split_train_val(path, 0.1, filter_key="better")


@pytest.mark.parametrize("suffix", FORMATS)
def test_rewards_and_dones_are_time_aligned(tmp_path, suffix):
    path = tmp_path / f"ds{suffix}"
    with open_writer(path, task_id=TASK, env_args={}) as w:
        for key in ("rewards", "dones"):
            with pytest.raises(ValueError, match=f"'{key}'.*3 rows"):
                w.append_episode({"actions": np.zeros((3, 2)), key: np.zeros(4)}, success=True)
        w.append_episode(
            {"actions": np.zeros((3, 2)), "rewards": np.ones(3, np.float32), "dones": np.array([0, 0, 1])}, success=True
        )
    ep = read_episode(path, 0)
    assert ep["rewards"].tolist() == [1, 1, 1] and ep["dones"].tolist() == [0, 0, 1]


def test_state_tree_names_flat_states_and_passes_nested_ones():
    layout = {
        "joint_q": [0, 3],
        "joint_qd": [3, 5],
        "articulation/robot/joint_position": [0, 2],
        "articulation/robot/joint_velocity": [3, 4],
        "rigid_object/cube/root_pose": [1, 3],
    }
    flat = np.arange(10, dtype=np.float32).reshape(2, 5)
    tree = state_tree(flat, {"newton_lab": {"state_layout": layout}})
    np.testing.assert_array_equal(tree["articulation"]["robot"]["joint_position"], flat[:, :2])
    np.testing.assert_array_equal(tree["articulation"]["robot"]["joint_velocity"], flat[:, 3:4])
    np.testing.assert_array_equal(tree["rigid_object"]["cube"]["root_pose"], flat[:, 1:3])
    np.testing.assert_array_equal(tree["joint_qd"], flat[:, 3:])
    nested = make_episode(0, steps=4)["states"]  # a format 1 dataset's nested states
    assert state_tree(nested, {}) == nested
    with pytest.raises(ValueError, match="no newton_lab.state_layout"):
        state_tree(flat, {})
    with pytest.raises(ValueError, match="exceeds the 2 state columns"):
        state_tree(flat[:, :2], {"newton_lab": {"state_layout": layout}})


def test_hdf5_tree_writer_and_reader_match_h5py_high_level(tmp_path):
    """The HDF5 writer creates plain arrays through h5py's low-level API: the file is byte for byte the one that
    ``create_dataset`` writes (types incl. bool and non-contiguous input, layout, no filters, no times); the reader
    returns what h5py's ``Group.items`` / ``Dataset[()]`` return (gzip chunks, byte strings, 0-d, empty)."""
    from newton_lab.datasets.hdf5 import store as hdf5_store

    rng = np.random.default_rng(0)
    tree = {
        "f32": rng.random((17, 7), dtype=np.float32),
        "f64": rng.random(5),
        "i64": np.arange(9),
        "bool": np.array([True, False, True]),
        "u8": np.arange(12, dtype=np.uint8).reshape(3, 4),
        "fortran": np.asfortranarray(rng.random((4, 3))),
        "strided": np.arange(6, dtype=np.int32)[::2],
        "nested": {"x": np.ones((2, 2), np.float32), "empty": np.zeros((0, 3)), "scalar": np.array(2.5)},
    }

    def high_level(g, t):
        for k, v in t.items():
            if isinstance(v, dict):
                high_level(g.create_group(k), v)
            else:
                g.create_dataset(k, data=v)

    for name, write in (("ours.h5", hdf5_store._write_tree), ("h5py.h5", high_level)):
        with h5py.File(tmp_path / name, "w", libver=hdf5_store.LIBVER) as f:
            write(f.create_group("demo"), tree)
    assert (tmp_path / "ours.h5").read_bytes() == (tmp_path / "h5py.h5").read_bytes()

    def high_level_read(g):
        return {k: high_level_read(v) if isinstance(v, h5py.Group) else np.asarray(v[()]) for k, v in g.items()}

    with h5py.File(tmp_path / "ours.h5", "a") as f:  # the reader too: h5py's own reading, key order included
        f["demo"].create_dataset(
            "rgb",
            data=np.arange(2 * 4 * 4 * 3, dtype=np.uint8).reshape(2, 4, 4, 3),
            chunks=(1, 4, 4, 3),
            compression="gzip",
        )
        f["demo"]["nested"].create_dataset("names", data=np.array([b"a", b"bc"]))
        ours, theirs = hdf5_store._read_tree(f["demo"]), high_level_read(f["demo"])

    def same(a, b):
        assert list(a) == list(b)
        for k in a:
            if isinstance(a[k], dict):
                same(a[k], b[k])
            else:
                assert a[k].dtype == b[k].dtype and a[k].shape == b[k].shape and np.array_equal(a[k], b[k]), k

    same(ours, theirs)
    same({k: ours[k] for k in tree if k != "nested"}, {k: v for k, v in tree.items() if k != "nested"})


# ----------------------------------------------------------------------------- SIGKILL crash safety
CHILD = f"""
import sys
sys.path.insert(0, {str(Path(__file__).resolve().parent)!r})
from test_storage import make_episode
from newton_lab.datasets import EpisodeWriter
w = EpisodeWriter.open(sys.argv[1], task_id="kill_task", env_args={{}})
seed = int(sys.argv[2])
while True:
    demo_id = w.append_episode(make_episode(seed), success=seed % 2 == 0, attrs={{"seed": seed}})
    print("APPENDED", demo_id, seed, flush=True)
    seed += 1
"""


def _run_and_kill(path: Path, first_seed: int, min_reported: int, delay: float, log: Path) -> list[tuple[int, int]]:
    """Start an endless appender, SIGKILL it once it reported >= min_reported appends."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    with open(log, "w") as err:
        proc = subprocess.Popen(
            [sys.executable, "-c", CHILD, str(path), str(first_seed)],
            stdout=subprocess.PIPE,
            stderr=err,
            text=True,
            env=env,
        )
    lines: queue.Queue = queue.Queue()

    def pump() -> None:
        for line in proc.stdout:
            lines.put(line)
        lines.put(None)

    threading.Thread(target=pump, daemon=True).start()
    reported = []
    try:
        while len(reported) < min_reported:
            line = lines.get(timeout=120)
            if line is None:
                pytest.fail(f"appender exited early (rc={proc.wait()}): {log.read_text()[-2000:]}")
            reported.append(line)
        time.sleep(delay)
        os.kill(proc.pid, signal.SIGKILL)
        assert proc.wait(timeout=60) == -signal.SIGKILL
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    while (line := lines.get(timeout=60)) is not None:  # appends that returned before the kill
        reported.append(line)
    # a kill in the middle of a print leaves a partial last line: its append returned, but its
    # numbers may be cut, so only whole lines are checked
    return [(int(a), int(b)) for _, a, b in (line.split() for line in reported if line.endswith("\n"))]


@pytest.mark.parametrize("suffix", FORMATS)
def test_sigkill_during_appends_keeps_every_reported_episode(tmp_path, suffix):
    path = tmp_path / f"crash{suffix}"
    reported = _run_and_kill(path, 0, 3, 0.0, tmp_path / "log1.txt")
    # second writer on the crashed dataset: appends after the leftovers, then is killed again
    reported += _run_and_kill(path, 1000, 3, 0.013, tmp_path / "log2.txt")

    ids = [i for i, _ in reported]
    assert len(reported) >= 6 and len(set(ids)) == len(ids)
    info = read_dataset_info(path)
    assert set(ids) <= set(info["demo_ids"]) and info["task_id"] == "kill_task"
    assert info["num_demos"] == len(info["demo_ids"]) and info["total"] == 200 * info["num_demos"]
    for demo_id, seed in reported:
        ep = read_episode(path, demo_id)
        assert ep.pop("attrs") == {"num_samples": 200, "success": seed % 2 == 0, "seed": seed}
        assert_tree_equal(ep, make_episode(seed))
    # and the dataset stays appendable
    with open_writer(path, task_id="kill_task", env_args={}) as w:
        assert w.append_episode(make_episode(7), success=True) == max(info["demo_ids"]) + 1


# Kill the HDF5 writer at the worst moments: in the middle of HDF5's metadata flush (some
# metadata of the committed file already overwritten in place) and just before the commit.
KILL_POINT_CHILD = f"""
import os, signal, sys
sys.path.insert(0, {str(Path(__file__).resolve().parent)!r})
from test_storage import make_episode
from newton_lab.datasets import EpisodeWriter
from newton_lab.datasets.hdf5 import journal as _journal
point = sys.argv[2]
if point == "mid_flush":
    orig_save, count = _journal.JournaledFile._save, [0]
    def _save(self, start, end):
        orig_save(self, start, end)
        if start < self._size0:
            count[0] += 1
            if count[0] == 3:
                os.kill(os.getpid(), signal.SIGKILL)
    _journal.JournaledFile._save = _save
else:
    orig_close = _journal.JournaledFile.close_journal
    def close_journal(self):
        orig_close(self)
        os.kill(os.getpid(), signal.SIGKILL)
    _journal.JournaledFile.close_journal = close_journal
EpisodeWriter.open(sys.argv[1], task_id=TASK_ID, env_args={{}}).append_episode(make_episode(99), success=True)
""".replace("TASK_ID", repr(TASK))


@pytest.mark.parametrize("point", ["mid_flush", "before_commit"])
def test_hdf5_kill_inside_append_rolls_back(tmp_path, point):
    path = tmp_path / "ds.hdf5"
    write_demos(path, [0, 1])
    before = fingerprint(path)
    proc = subprocess.run(
        [sys.executable, "-c", KILL_POINT_CHILD, str(path), point],
        env=dict(os.environ, PYTHONPATH=str(ROOT)),
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    assert (tmp_path / "ds.hdf5-journal").exists() and fingerprint(path) != before  # really torn
    assert list_demos(path) == [0, 1]  # readers roll the torn append back first
    assert fingerprint(path) == before and not (tmp_path / "ds.hdf5-journal").exists()
    assert write_demos(path, [2]) == [2]
    for seed in (0, 1, 2):
        assert_tree_equal({k: v for k, v in read_episode(path, seed).items() if k != "attrs"}, make_episode(seed))


@pytest.mark.parametrize("point", ["mid_flush", "before_commit"])
def test_hdf5_writer_open_across_a_killed_append_rolls_it_back_itself(tmp_path, point):
    """A writer opened before another process was killed mid-append (its journal left, no reader in between)
    rolls the torn append back at its own next append, then appends: the killed demo (written in full before the
    commit, at ``before_commit``) does not come back, every other reads back as written."""
    path = tmp_path / "ds.hdf5"
    write_demos(path, [0, 1])
    before = fingerprint(path)
    with EpisodeWriter.open(path, task_id=TASK, env_args=ENV_ARGS) as w:
        proc = subprocess.run(
            [sys.executable, "-c", KILL_POINT_CHILD, str(path), point],
            env=dict(os.environ, PYTHONPATH=str(ROOT)),
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert proc.returncode == -signal.SIGKILL, proc.stderr
        assert (tmp_path / "ds.hdf5-journal").exists() and fingerprint(path) != before  # really torn
        assert w.append_episode(make_episode(2), success=True) == 2
    assert not (tmp_path / "ds.hdf5-journal").exists() and list_demos(path) == [0, 1, 2]
    for seed in (0, 1, 2):
        assert_tree_equal({k: v for k, v in read_episode(path, seed).items() if k != "attrs"}, make_episode(seed))


@pytest.mark.parametrize("suffix", FORMATS)
def test_failed_append_leaves_dataset_unchanged(tmp_path, suffix, monkeypatch):
    path = tmp_path / f"ds{suffix}"
    write_demos(path, [0])
    before = fingerprint(path)
    module = "zarr.packs" if suffix == ".zarr" else "hdf5.store"  # where each store calls its per-demo writer
    store = __import__(f"newton_lab.datasets.{module}", fromlist=["append"])
    name = "write_demo" if suffix == ".zarr" else "_write_tree"
    real = getattr(store, name)

    def failing(*args, **kwargs):  # the demo's first array lands, then the disk is full
        tree = args[-1] if name == "_write_tree" else args[2]
        args = (
            (*args[:-1], {"actions": tree["actions"]})
            if name == "_write_tree"
            else (*args[:2], {"actions": tree["actions"]})
        )
        real(*args, **kwargs)
        raise OSError("disk full")

    monkeypatch.setattr(store, name, failing)
    with pytest.raises(OSError, match="disk full"):
        write_demos(path, [1])
    monkeypatch.undo()
    if suffix == ".hdf5":  # rolled back byte for byte
        assert fingerprint(path) == before and not (tmp_path / "ds.hdf5-journal").exists()
    assert list_demos(path) == [0] and read_dataset_info(path)["total"] == 200
    assert write_demos(path, [1]) == [1]


def test_zarr_demo_nodes_match_what_zarr_python_writes(tmp_path):
    """The zarr append path writes nodes with plain file writes (``zarr.nodes``): every array's metadata equals
    zarr-python's for the same array, and zarr-python reads back the values (edge chunks, byte order, 0-d)."""
    from zarr.storage import LocalStore

    from newton_lab.datasets.zarr import nodes as zarr_nodes

    rng = np.random.default_rng(3)
    tree = {
        "long": rng.standard_normal((5000, 64)).astype(np.float32),  # 1.28 MB: two time chunks, the last padded
        "big_endian": rng.standard_normal((7, 3)).astype(">f8"),
        "ints": rng.integers(-9, 9, (11,), np.int16),
        "flags": rng.random(13) > 0.5,
        "frames": rng.integers(0, 255, (3, 6, 5, 3), np.uint8),
        "nested": {"scalar": np.float64(2.5), "empty": np.zeros((0, 4), np.float32)},
    }
    (tmp_path / "ours").mkdir()
    zarr.open_group(store=LocalStore(tmp_path / "ours"), mode="w", zarr_format=3)
    left = []
    zarr_nodes.write_demo(
        tmp_path / "ours" / "demo", {"num_samples": 5, "success": True}, tree, fallback=lambda rel, v: left.append(rel)
    )
    assert sorted(left) == ["nested/empty", "nested/scalar"]  # 0-d and empty arrays are zarr-python's
    ours = zarr.open_group(str(tmp_path / "ours"), mode="r", zarr_format=3)["demo"]
    assert ours.attrs.asdict() == {"num_samples": 5, "success": True}
    theirs = zarr.open_group(store=LocalStore(tmp_path / "theirs"), mode="w", zarr_format=3)
    for key in ("long", "big_endian", "ints", "flags", "frames"):
        value = tree[key]
        theirs.create_array(key, data=value, **zarr_nodes.array_kwargs(value))
        meta = json.loads((tmp_path / "ours" / "demo" / key / "zarr.json").read_text())
        assert meta == json.loads((tmp_path / "theirs" / key / "zarr.json").read_text()), key
        np.testing.assert_array_equal(ours[key][...], value, err_msg=key)
        assert ours[key].dtype == theirs[key].dtype
        for chunk in sorted(c for c in os.listdir(tmp_path / "theirs" / key) if c != "zarr.json"):  # same bytes
            assert (tmp_path / "ours" / "demo" / key / chunk).read_bytes() == (
                tmp_path / "theirs" / key / chunk
            ).read_bytes(), (key, chunk)
    assert sorted(os.listdir(tmp_path / "ours" / "demo" / "long")) == ["c.0.0", "c.1.0", "zarr.json"]


def test_zarr_plain_reader_matches_zarr_python(tmp_path):
    """``zarr.nodes.read_tree`` reads arrays of the plain layout from their files, chunks zarr left out as the fill
    value, and hands every other array (another codec, 0-d, empty, a NaN fill value) to zarr-python."""
    from zarr.codecs import BloscCodec
    from zarr.storage import LocalStore

    from newton_lab.datasets.zarr import nodes as zarr_nodes

    rng = np.random.default_rng(5)
    g = zarr.open_group(store=LocalStore(tmp_path / "z"), mode="w", zarr_format=3)
    flat = {"chunk_key_encoding": {"name": "default", "separator": "."}}
    sparse = np.zeros((9, 4), np.float32)
    sparse[6:] = rng.standard_normal((3, 4))  # rows 0..5 stay zero: zarr writes no file for chunks 0 and 1
    values = {
        "sparse": (sparse, {"chunks": (3, 4), "fill_value": 0.0, **flat}),
        "flags": (rng.random(7) > 0.5, {"chunks": (7,), **flat}),
        "ints": (rng.integers(-5, 5, (4, 3, 2), np.int64), {"chunks": (3, 3, 2), "fill_value": 7, **flat}),
        "blosc": (rng.standard_normal((5, 2)), {"chunks": (5, 2), "compressors": BloscCodec(), **flat}),
        "nan_fill": (rng.standard_normal(3).astype(np.float32), {"chunks": (3,), "fill_value": np.nan, **flat}),
        "scalar": (np.float64(1.5), {}),
        "empty": (np.zeros((0, 2), np.float32), {"chunks": (1, 2), **flat}),
    }
    sub = g.create_group("nested")
    for name, (value, kwargs) in values.items():
        (sub if name == "ints" else g).create_array(name, data=value, **kwargs)
    assert sorted(os.listdir(tmp_path / "z" / "sparse")) == ["c.2.0", "zarr.json"]
    handed = []

    def fallback(rel):
        handed.append(rel)
        return np.asarray(g[rel][...])

    tree = zarr_nodes.read_tree(tmp_path / "z", None, fallback)
    assert sorted(handed) == ["blosc", "empty", "nan_fill", "scalar"]
    assert sorted(tree) == sorted(set(values) - {"ints"} | {"nested"}) and sorted(tree["nested"]) == ["ints"]
    for name, (value, _) in values.items():
        got = tree["nested"][name] if name == "ints" else tree[name]
        assert got.dtype == np.asarray(value).dtype and got.shape == np.shape(value), name
        np.testing.assert_array_equal(got, value, err_msg=name)
    assert zarr_nodes.read_tree(tmp_path / "z", ("nested/ints", "nested", "missing"), fallback).keys() == {"nested"}
