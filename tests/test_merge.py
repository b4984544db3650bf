"""Copying stored demos between datasets (``EpisodeWriter.append_copies``) and merging shards. Fast, no physics."""

from __future__ import annotations

import pytest
from test_storage import ENV_ARGS, FORMATS, TASK, assert_tree_equal, fingerprint, make_episode, write_demos

from newton_lab.datasets import EpisodeWriter, list_demos, merge as merge_module, read_dataset_info, read_episode
from newton_lab.datasets.files.write_faults import inject_write_fault
from newton_lab.datasets.merge import merge_datasets


def _arrays(path, demo_id) -> dict:
    return {k: v for k, v in read_episode(path, demo_id).items() if k != "attrs"}


@pytest.mark.parametrize("suffix", FORMATS)
def test_append_copies_keeps_arrays_and_attrs(tmp_path, suffix):
    src, dst = tmp_path / f"src{suffix}", tmp_path / f"dst{suffix}"
    write_demos(src, [0, 1, 2])
    write_demos(dst, [5])
    with EpisodeWriter.open(dst, task_id=TASK, env_args=ENV_ARGS) as w:
        assert w.append_copies(src, [2, "demo_0"], attrs={2: {"source": "src:2"}}) == [1, 2]
    assert list_demos(dst) == [0, 1, 2] and read_dataset_info(dst)["total"] == 3 * 200
    assert_tree_equal(_arrays(dst, 1), make_episode(2))  # 0-d and nested arrays too
    assert_tree_equal(_arrays(dst, 2), make_episode(0))
    attrs = read_episode(dst, 1)["attrs"]
    assert attrs == {**read_episode(src, 2)["attrs"], "source": "src:2"} and attrs["num_samples"] == 200
    assert read_dataset_info(dst)["demos"][2]["success"] is True and read_dataset_info(dst)["demos"][1]["success"]


@pytest.mark.parametrize("suffix", FORMATS)
def test_append_copies_refuses_bad_input_in_one_line(tmp_path, suffix):
    other = ".zarr" if suffix == ".hdf5" else ".hdf5"
    src, dst = tmp_path / f"src{suffix}", tmp_path / f"dst{suffix}"
    write_demos(src, [0, 1])
    write_demos(tmp_path / f"conv{other}", [0])
    write_demos(tmp_path / f"task{suffix}", [0], task="stack_cube")
    with EpisodeWriter.open(dst, task_id=TASK, env_args=ENV_ARGS) as w:
        for source, ids, attrs, error, words in (
            (tmp_path / f"conv{other}", [0], None, ValueError, "copies need one format"),
            (src, [0, 7], None, KeyError, "demo 7 not in"),
            (tmp_path / f"task{suffix}", [0], None, ValueError, "holds task 'stack_cube'"),
            (dst, [0], None, ValueError, "into itself"),
            (src, [0], {0: {"num_samples": 3}}, ValueError, "set by the writer"),
        ):
            with pytest.raises(error, match=words):
                w.append_copies(source, ids, attrs=attrs)
    assert list_demos(dst) == []


@pytest.mark.parametrize("suffix", FORMATS)
def test_failed_copy_batch_leaves_dataset_unchanged(tmp_path, suffix):
    src, dst = tmp_path / f"src{suffix}", tmp_path / f"dst{suffix}"
    write_demos(src, [0, 1, 2])
    write_demos(dst, [3])
    before = fingerprint(dst)
    inject_write_fault(12)  # the disk fills part-way through the batch
    try:
        with EpisodeWriter.open(dst, task_id=TASK, env_args=ENV_ARGS) as w, pytest.raises(OSError, match="disk full"):
            w.append_copies(src, [0, 1, 2])
    finally:
        inject_write_fault(None)
    if suffix == ".hdf5":  # rolled back byte for byte
        assert fingerprint(dst) == before
    assert list_demos(dst) == [0] and read_dataset_info(dst)["total"] == 200
    with EpisodeWriter.open(dst, task_id=TASK, env_args=ENV_ARGS) as w:
        assert w.append_copies(src, [1]) == [1]
    assert_tree_equal(_arrays(dst, 1), make_episode(1))


@pytest.mark.parametrize("out_suffix", FORMATS)
def test_merge_copies_or_converts_in_batches(tmp_path, out_suffix, monkeypatch):
    monkeypatch.setattr(merge_module, "MERGE_BATCH", 2)
    a, b = tmp_path / "a.hdf5", tmp_path / "b.zarr"
    write_demos(a, [0, 1, 2])
    write_demos(b, [3, 4])
    seen = []
    ref = merge_datasets([a, b], tmp_path / f"out{out_suffix}", progress=lambda done, total: seen.append((done, total)))
    out = ref.path
    assert ref.metadata["saved_demo_ids"] == [0, 1, 2, 3, 4] and seen == [(2, 5), (3, 5), (5, 5)]
    for new, (path, old, seed) in enumerate([(a, 0, 0), (a, 1, 1), (a, 2, 2), (b, 0, 3), (b, 1, 4)]):
        assert_tree_equal(_arrays(out, new), make_episode(seed))
        attrs = read_episode(out, new)["attrs"]
        assert attrs["source"] == f"{path.name}:{old}" and attrs["seed"] == seed and attrs["success"] == (seed % 2 == 0)
    assert read_dataset_info(out)["total"] == 5 * 200
    with pytest.raises(FileExistsError, match="merge into a new path"):
        merge_datasets([a], out)
