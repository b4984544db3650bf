"""The collection writer's throughput choices: the background writer gathers ``min_batch`` episodes per batch (or
writes sooner when waited on), a packed batch is written by chunk threads in this process (strided arrays too) and
reads back as written, and ``bench-collect``'s summary words the three stages. Fast, no physics."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
import zarr
from test_storage import ENV_ARGS, TASK, assert_tree_equal, make_episode

from newton_lab.datasets import EpisodeWriter, list_demos, read_episodes
from newton_lab.datasets.writers.background_thread import BackgroundWriter
from newton_lab.datasets.zarr import packs as zarr_packs
from newton_lab.datasets.zarr.settings import ZarrWriteSettings


def _writer(path, **kw) -> BackgroundWriter:
    return BackgroundWriter(EpisodeWriter.open(path, task_id=TASK, env_args=ENV_ARGS, fsync=False), **kw)


def test_the_background_writer_gathers_min_batch_episodes(tmp_path):
    bg = _writer(tmp_path / "g.zarr", max_queued=64, min_batch=5, max_wait_s=60.0)
    try:
        futures = [bg.put(make_episode(s, steps=5), success=True) for s in range(4)]
        time.sleep(0.3)  # time for the writer thread to (wrongly) write
        assert bg.batches == 0 and not any(f.done() for f in futures)  # 4 < min_batch: still gathering
        futures += bg.put_many([(make_episode(4, steps=5), True, None)])
        assert [f.result(timeout=30) for f in futures] == list(range(5)) and bg.batches == 1  # one batch of 5
        more = bg.put_many([(make_episode(s, steps=5), True, None) for s in (5, 6)])
        bg.flush()  # a flush does not wait for min_batch
        assert [f.result() for f in more] == [5, 6] and bg.batches == 2
    finally:
        bg.close()
    lone = _writer(tmp_path / "t.zarr", min_batch=100, max_wait_s=0.05)
    try:
        f = lone.put(make_episode(0, steps=5), success=True)
        assert f.result(timeout=30) == 0 and lone.batches == 1  # the oldest waited max_wait_s: written alone
    finally:
        lone.close()


def test_a_put_that_waits_for_room_has_the_queue_written_below_min_batch(tmp_path):
    ep = make_episode(0, steps=5)
    size = sum(np.asarray(v).nbytes for v in _leaves(ep))
    bg = _writer(tmp_path / "b.zarr", max_queued=10, min_batch=10, max_wait_s=60.0, max_queued_bytes=2 * size + 1)
    try:
        first = bg.put_many([(make_episode(s, steps=5), True, None) for s in range(2)])
        done: list = []
        third = threading.Thread(
            target=lambda: done.append(bg.put(make_episode(2, steps=5), success=True)), daemon=True
        )
        third.start()  # no room for its bytes: the two queued go now, although fewer than min_batch
        third.join(30)
        assert not third.is_alive() and [f.result(timeout=30) for f in first] == [0, 1]
        bg.flush()
        assert done[0].result() == 2
    finally:
        bg.close()
    assert list_demos(tmp_path / "b.zarr") == [0, 1, 2]


def _leaves(tree: dict):
    for v in tree.values():
        yield from (_leaves(v) if isinstance(v, dict) else [v])


@pytest.mark.parametrize("threads", [1, 3])
def test_a_packed_batch_on_chunk_threads_reads_back_as_written(tmp_path, threads):
    """Arrays of several ~1 MB chunks and an edge chunk, strided views among them: one pack for the batch, the
    demos read back as given, and zarr-python reads the pack's rows one demo after another."""
    rng = np.random.default_rng(0)
    episodes = []
    for s in range(6):
        ep = make_episode(s, steps=30 + s)
        wide = rng.standard_normal((30 + s, 4096 + 8)).astype(np.float32)
        ep["obs"]["wide"] = wide[:, 8:]  # a strided view: 16 KB a row, 64 rows a chunk, 195 rows in all
        episodes.append(ep)
    path = tmp_path / "p.zarr"
    settings = ZarrWriteSettings(pack_min_batch=4, pack_threads=threads)
    with EpisodeWriter.open(path, task_id=TASK, env_args=ENV_ARGS, zarr_settings=settings) as w:
        assert w.append_episodes([(ep, True, {"seed": s}) for s, ep in enumerate(episodes)]) == list(range(6))
    assert sorted(p.name for p in (path / "data").iterdir() if p.is_dir()) == ["pack_0"]
    for s, got in enumerate(read_episodes(path, range(6))):
        assert_tree_equal({k: v for k, v in got.items() if k != "attrs"}, episodes[s], f"demo {s}")
    wide = zarr.open_group(str(path), mode="r")["data/pack_0/obs/wide"]
    assert wide.shape[0] == 195 and wide.chunks[0] == 64  # four chunks, the last an edge one of 3 rows
    np.testing.assert_array_equal(wide[...], np.concatenate([ep["obs"]["wide"] for ep in episodes]))


def test_the_bench_collect_summary_names_the_stages_and_the_bound():
    from newton_lab.bench_collect import summary

    out = {
        "task": "T",
        "device_name": "NVIDIA H100 80GB HBM3",
        "num_envs": 4096,
        "format": ".zarr",
        "successful_demos": 16384,
        "wall_s": 10.0,
        "demos_per_s": 1638.4,
        "demos_per_hour": 5_898_240.0,
        "physics_s": 5.0,
        "agent_s": 2.0,
        "writer_s": 2.5,
        "writer_files_s": 1.5,
        "writer_sync_s": 0.5,
        "loop_s": 3.0,
        "hand_over_s": 1.0,
        "drain_s": 0.2,
        "vector_steps": 1000,
        "bytes_per_demo": 118_000.0,
        "inodes_per_demo": 0.45,
        "writer_batches": 64,
        "physics_bound": True,
        "physics_share": 0.5,
    }
    text = summary(out)
    assert "1638 demos/s = 5.90 M demos per GPU-hour" in text and "physics 5.00 s (5.00 ms/step)" in text
    assert (
        "physics-bound (agent + writer <= physics per step): yes (4.50 vs 5.00 ms/step; the step is 50 % of the "
        "wall)" in text
    )
    assert "largest stage: physics 5.00 s (writer 2.50 s, agent 2.00 s, hand-over 1.00 s)" in text
    cameras = {**out, "cameras": {"front_head": [96, 72, ["rgb"]]}, "record_s": 1.5, "writer_s": 6.0}
    assert "largest stage: physics + render 6.50 s (writer 6.00 s, agent 2.00 s, hand-over 1.00 s)" in summary(cameras)
    split = summary({**out, "hand_over_copy_s": 0.7, "hand_over_ring_wait_s": 0.25})
    assert "hand-over 1.00 s (into the writer's ring 0.70 s, waiting for its room 0.25 s), drain" in split
    process = summary(
        {
            **out,
            "hand_over_copy_s": 0.7,
            "hand_over_ring_wait_s": 0.25,
            "writer_copy_out_s": 0.5,
            "writer_queue_wait_s": 0.1,
        }
    )
    assert (
        "the writer process copied the bursts' low-dim arrays out of its ring 0.50 s and was blocked on its full "
        "write queue 0.10 s" in process
    )


def _with_repeats(seed: int, steps: int) -> dict:
    """An episode whose ``next_obs`` is its ``obs`` one step on and whose ``datagen/pose`` repeats ``obs/pose``."""
    rng = np.random.default_rng(seed)
    obs = {
        "pose": rng.standard_normal((steps + 1, 7)).astype(np.float32),
        "q": rng.standard_normal((steps + 1, 5)).astype(np.float32),
    }
    return {
        "actions": rng.standard_normal((steps, 3)).astype(np.float32),
        "obs": {k: v[:-1].copy() for k, v in obs.items()},
        "next_obs": {k: v[1:].copy() for k, v in obs.items()},
        "datagen": {"pose": obs["pose"][:-1].copy(), "zero": np.zeros((steps, 2), np.float32)},
        "other": np.zeros((steps, 2), np.float32),
    }


def test_arrays_that_repeat_others_are_stored_once_and_read_back_byte_identical(tmp_path):
    episodes = [_with_repeats(s, 10 + s) for s in range(5)]
    episodes[3]["datagen"]["zero"][2, 1] = -0.0  # equal to 0.0 as a value, not as bytes: stored apart
    episodes[4]["next_obs"]["q"][3, 0] += 1  # one interior row off: next_obs/q stored in full
    path, packed = tmp_path / "d.zarr", ZarrWriteSettings(pack_min_batch=4)
    with EpisodeWriter.open(path, task_id=TASK, env_args=ENV_ARGS, zarr_settings=packed) as w:
        w.append_episodes([(ep, True, None) for ep in episodes])
    arrays = zarr_packs.read_index(path / "data" / "pack_0")["arrays"]
    assert {k: v for k, v in arrays.items() if isinstance(v, str)} == {
        "datagen/pose": "same:obs/pose",
        "next_obs/pose": "next:obs/pose",
    }
    for s, got in enumerate(read_episodes(path, range(5))):
        _assert_bytes_equal(got, episodes[s], f"demo {s}")
    picked = next(read_episodes(path, [2], keys=["next_obs/pose", "datagen/pose"]))  # without their source asked
    np.testing.assert_array_equal(picked["next_obs"]["pose"], episodes[2]["next_obs"]["pose"])
    np.testing.assert_array_equal(picked["datagen"]["pose"], episodes[2]["datagen"]["pose"])
    assert not (path / "data" / "pack_0" / "datagen" / "pose").exists()  # stored once
    assert zarr.open_group(str(path), mode="r")["data/pack_0/next_obs/pose"].shape == (5, 7)  # last rows only


def _assert_bytes_equal(actual: dict, expected: dict, where: str) -> None:
    assert sorted(k for k in actual if k != "attrs") == sorted(expected), where
    for key, exp in expected.items():
        if isinstance(exp, dict):
            _assert_bytes_equal(actual[key], exp, f"{where}/{key}")
        else:
            got = actual[key]
            assert got.dtype == exp.dtype and got.shape == exp.shape and got.tobytes() == exp.tobytes(), where + key
