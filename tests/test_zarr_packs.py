"""Packed zarr demos (``datasets/zarr/packs``): a large batch lands as a few ``pack_<first id>`` groups and reads,
deletes, merges and recovers from a kill like ``demo_<i>`` groups. Fast, no physics; the pack threshold is lowered
so that small batches pack."""

from __future__ import annotations

import errno
import shutil
import subprocess
import sys

import numpy as np
import pytest
import zarr
from test_storage import ENV_ARGS, TASK, assert_tree_equal, make_episode

from newton_lab.datasets import (
    DatasetWriteError,
    EpisodeWriter,
    delete_demos,
    list_demos,
    read_dataset_info,
    read_episode,
    read_episodes,
    read_filter_keys,
    set_filter_keys,
)
from newton_lab.datasets.files.write_faults import inject_write_fault
from newton_lab.datasets.merge import merge_datasets
from newton_lab.datasets.zarr import packs as zarr_packs
from newton_lab.datasets.zarr.settings import ZarrWriteSettings

SMALL_PACKS = ZarrWriteSettings(pack_min_batch=4)
"""Batches of 4 demos or more pack."""


def episode(seed: int) -> dict:
    return make_episode(seed, steps=20 + seed)  # lengths differ: rows per demo follow each demo's steps


def append(path, seeds) -> list[int]:
    with EpisodeWriter.open(path, task_id=TASK, env_args=ENV_ARGS, zarr_settings=SMALL_PACKS) as w:
        return w.append_episodes([(episode(s), s % 2 == 0, {"seed": s}) for s in seeds])


def names(path) -> list[str]:
    return sorted(p.name for p in (path / "data").iterdir() if p.is_dir())


def without_attrs(ep: dict) -> dict:
    return {k: v for k, v in ep.items() if k != "attrs"}


def test_a_large_batch_is_packed_and_reads_back_as_written(tmp_path):
    path = tmp_path / "p.zarr"
    assert append(path, range(9)) == list(range(9))
    assert append(path, [9, 10]) == [9, 10]  # a small batch: one group per demo
    assert names(path) == ["demo_10", "demo_9", "pack_0"]
    info = read_dataset_info(path)
    assert info["demo_ids"] == list(range(11)) and info["total"] == sum(20 + s for s in range(11))
    for s, ep in zip(range(11), read_episodes(path, range(11), attrs=True)):
        attrs = ep["attrs"]
        assert attrs["seed"] == s and attrs["num_samples"] == 20 + s and attrs["success"] == (s % 2 == 0)
        assert_tree_equal(without_attrs(ep), episode(s), f"demo {s}")
    picked = list(read_episodes(path, [5, 2], keys=["actions", "obs/rgb", "datagen/scale", "missing"]))
    assert sorted(picked[0]) == ["actions", "datagen", "obs"] and picked[0]["datagen"]["scale"].shape == ()
    np.testing.assert_array_equal(picked[1]["obs"]["rgb"], episode(2)["obs"]["rgb"])
    # zarr-python reads a pack: the demos' rows one after another, initial_state one row each
    data = zarr.open_group(str(path), mode="r")["data/pack_0"]
    np.testing.assert_array_equal(data["actions"][...], np.concatenate([episode(s)["actions"] for s in range(9)]))
    assert data["initial_state/robot/qpos"].shape == (9, 9) and data["datagen/scale"].shape == (9,)
    files = sum(1 for _ in (path / "data" / "pack_0").rglob("*"))  # image frames stay one chunk each
    assert files < 9 * sum(1 for _ in (path / "data" / "demo_9").rglob("*"))


def test_the_room_check_counts_a_pack_as_written(tmp_path):
    path = tmp_path / "r.zarr"
    with EpisodeWriter.open(path, task_id=TASK, env_args=ENV_ARGS, zarr_settings=SMALL_PACKS) as w:
        w.append_episodes([(make_episode(s, steps=30), True, None) for s in range(5)])
    assert names(path) == ["pack_0"]
    files = sum(1 for _ in (path / "data" / "pack_0").rglob("*")) + 1  # and the pack's folder
    assert zarr_packs.inodes_of_pack(make_episode(0, steps=30), 5) == files


def test_demos_of_different_layouts_are_written_one_group_each(tmp_path):
    path = tmp_path / "mixed.zarr"
    odd = {**episode(4), "extra": np.zeros((24, 2), np.float32)}
    with EpisodeWriter.open(path, task_id=TASK, env_args=ENV_ARGS, zarr_settings=SMALL_PACKS) as w:
        w.append_episodes([(episode(s), True, None) for s in range(4)] + [(odd, True, None)])
    assert names(path) == [f"demo_{i}" for i in range(5)]
    assert_tree_equal(without_attrs(read_episode(path, 4)), odd)


def test_deleting_packed_demos(tmp_path):
    path = tmp_path / "d.zarr"
    append(path, range(6))
    set_filter_keys(path, {"train": ["demo_0", "demo_1", "demo_4"], "valid": ["demo_5"]})
    assert delete_demos(path, [1, 4]) == [0, 2, 3, 5]
    assert read_filter_keys(path) == {"train": ["demo_0"], "valid": ["demo_5"]}
    info = read_dataset_info(path)
    assert info["demo_ids"] == [0, 2, 3, 5] and info["total"] == sum(20 + s for s in (0, 2, 3, 5))
    with pytest.raises(KeyError, match="demo 4 not in"):
        read_episode(path, 4)
    assert_tree_equal(without_attrs(read_episode(path, 5)), episode(5))
    delete_demos(path, [0, 2, 3, 5])  # the pack's last demos: the pack goes
    assert names(path) == [] and list_demos(path) == []
    assert append(path, range(4)) == [6, 7, 8, 9]  # ids are never reused


@pytest.mark.parametrize("readable", [True, False])
def test_a_pack_left_by_a_killed_append_is_skipped_then_removed(tmp_path, readable):
    """A pack renamed into place but never committed (killed before ``next_demo_id`` advanced): readers skip it and
    the next append removes it (also when its index cannot be read: then every name past the last id goes)."""
    path = tmp_path / "k.zarr"
    append(path, range(4))
    shutil.copytree(path / "data" / "pack_0", path / "data" / "pack_4")  # as a killed batch would leave it
    shutil.copytree(path / "data" / "pack_0", path / "data" / "pack_8")
    if not readable:
        (path / "data" / "pack_4" / "zarr.json").unlink()
    assert list_demos(path) == [0, 1, 2, 3] and read_dataset_info(path)["total"] == sum(range(20, 24))
    with pytest.raises(KeyError):
        read_episode(path, 5)
    assert append(path, range(10, 16)) == list(range(4, 10))
    assert names(path) == ["pack_0", "pack_4"]
    for s, ep in zip(range(10, 16), read_episodes(path, range(4, 10))):
        assert_tree_equal(ep, episode(s))


def test_a_failed_pack_write_leaves_the_dataset_as_it_was(tmp_path):
    path = tmp_path / "f.zarr"
    append(path, range(4))
    inject_write_fault(30, errno.ENOSPC)  # part way through the pack's arrays
    try:
        with pytest.raises(DatasetWriteError, match="holds 4 finished episodes"):
            append(path, range(4, 10))
    finally:
        inject_write_fault(None)
    assert names(path) == ["pack_0"] and list_demos(path) == [0, 1, 2, 3]
    assert append(path, range(4, 8)) == [4, 5, 6, 7]
    assert_tree_equal(without_attrs(read_episode(path, 7)), episode(7))


def test_merging_packed_shards_writes_packs(tmp_path):
    a, b = tmp_path / "a.zarr", tmp_path / "b.zarr"
    append(a, range(5))
    append(b, range(5, 9))
    merged = merge_datasets([a, b], tmp_path / "m.zarr", zarr_settings=SMALL_PACKS).path
    assert names(merged) == ["pack_0", "pack_5"]
    for s, ep in zip(range(9), read_episodes(merged, range(9), attrs=True)):
        assert ep["attrs"]["source"] == f"{'a' if s < 5 else 'b'}.zarr:{s if s < 5 else s - 5}"
        assert ep["attrs"]["seed"] == s
        assert_tree_equal(without_attrs(ep), episode(s))


KILL_CHILD = """
import os, signal, sys
from test_zarr_packs import append
from newton_lab.datasets.zarr import store as zarr_store
print("BATCH", *append(sys.argv[1], range(5)), flush=True)
zarr_store._commit = lambda *args: os.kill(os.getpid(), signal.SIGKILL)  # packs renamed into place, not committed
append(sys.argv[1], range(5, 11))
print("NOT KILLED", flush=True)
"""


def test_sigkill_before_a_pack_batch_commits(tmp_path):
    from test_writers import child_env

    path = tmp_path / "s.zarr"
    proc = subprocess.run(
        [sys.executable, "-c", KILL_CHILD, str(path)],
        check=False,
        capture_output=True,
        text=True,
        env=child_env(),
        timeout=120,
    )
    assert proc.returncode == -9 and proc.stdout.splitlines() == ["BATCH 0 1 2 3 4"], proc.stderr
    assert "pack_5" in names(path)  # really torn: the killed batch's pack is in place
    assert list_demos(path) == [0, 1, 2, 3, 4] and read_dataset_info(path)["total"] == sum(range(20, 25))
    assert append(path, range(20, 26)) == list(range(5, 11))
    assert names(path) == ["pack_0", "pack_5"]
    for s, ep in zip(list(range(5)) + list(range(20, 26)), read_episodes(path, range(11))):
        assert_tree_equal(ep, episode(s))


def test_zarr_write_settings_refuse_nonsense_in_one_line(tmp_path):
    with pytest.raises(ValueError, match=r"^ZarrWriteSettings.pack_threads must be an int >= 1, got 0$"):
        ZarrWriteSettings(pack_threads=0)
    with pytest.raises(ValueError, match="pack_min_batch must be an int >= 1, got 2.5"):
        ZarrWriteSettings(pack_min_batch=2.5)
    with pytest.raises(TypeError, match="zarr_settings must be a ZarrWriteSettings, got dict"):
        EpisodeWriter.open(tmp_path / "s.zarr", task_id=TASK, env_args=ENV_ARGS, zarr_settings={"pack_min_batch": 4})
