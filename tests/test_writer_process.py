"""The writer process of ``collect`` (``datasets.writers.process``): the demos it writes are those the writer thread
writes, bit for bit (real physics, both formats); its shared ring reuses its room in order; a write error in the
process reaches the collector in one line; a killed collector leaves a process that writes what it was given and
exits."""

from __future__ import annotations

import os
import pstats
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from newton_lab.agents import PlannerAgent
from newton_lab.datasets import list_demos, open_writer, read_dataset_info, read_episode
from newton_lab.datasets.writers.columns import ColumnLayout, DemoBlock
from newton_lab.datasets.writers.process import ProcessWriter, _Ring
from newton_lab.datasets.zarr.packs import read_index
from newton_lab.datasets.zarr.settings import ZarrWriteSettings
from newton_lab.envs import make_env
from newton_lab.envs.rollout import WRITE_MIN_BATCH, _writer_kind

LAYOUT = ColumnLayout(
    {
        "obs/x": (0, 3),
        "states/joint_q": (3, 5),
        "states/joint_qd": (5, 7),
        "datagen/phase": (7, 8),
        "datagen/subtask_signals/grasp": (8, 9),
        "actions": (9, 11),
    },
    11,
    {"x": (0, 3)},
)


def _leaves(tree, prefix=""):
    for key, value in tree.items():
        yield from _leaves(value, f"{prefix}{key}/") if isinstance(value, dict) else [(prefix + key, value)]


@pytest.mark.parametrize("suffix", [".hdf5", ".zarr"])
def test_the_writer_process_writes_the_demos_the_writer_thread_writes(tmp_path, suffix):
    read = {}
    for writer in ("thread", "process"):
        env = make_env("GalbotG1-PickCube-v0", num_envs=2, device="cpu", seed=5, randomize=True, cameras=False)
        path = tmp_path / f"{writer}{suffix}"
        ref = env.collect(
            agent=PlannerAgent.from_task(env.task_id),
            episodes=3,
            path=path,
            max_steps=400,
            progress=False,
            writer=writer,
        )
        assert ref["saved_demo_ids"] == [0, 1, 2] and ref["successes"] == 3
        assert ref.metadata["writer"] == {"thread": "BackgroundWriter", "process": "ProcessWriter"}[writer]
        read[writer] = [dict(_leaves(read_episode(path, i))) for i in list_demos(path)]
    for by_thread, by_process in zip(read["thread"], read["process"], strict=True):
        assert by_thread.keys() == by_process.keys() and "next_obs/cube_pose" in by_thread
        for key, value in by_thread.items():
            assert (
                np.array_equal(value, by_process[key]) and np.asarray(value).dtype == np.asarray(by_process[key]).dtype
            ), key
        assert by_process["dones"][-1] == 1 and by_process["attrs/success"]
    assert _writer_kind("auto", WRITE_MIN_BATCH) == "process" and _writer_kind("auto", 2) == "thread"
    with pytest.raises(ValueError, match="writer 'disk' is not one of auto, thread, process"):
        _writer_kind("disk", 2)


def test_the_ring_hands_out_room_first_in_first_out():
    ring = _Ring(1024)
    a, b = ring.take(400), ring.take(400)
    assert (a, b) == (0, 448) and ring.take(400) is None  # 64-byte aligned; 848 + 448 > 1024
    ring.give_back()  # a's room is free again: the next range wraps to the start
    assert ring.take(300) == 0 and ring.take(200) is None  # 320 .. 448 is too small while b is held
    ring.give_back()
    assert ring.take(600) == 320  # after the wrapped range, up to the end
    assert _Ring(64).take(65) is None


def _block(rows: int, steps: int, seed: int) -> np.ndarray:
    """Random frames whose next observation is the next frame's observation (as a recorder's are)."""
    block = np.random.default_rng(seed).standard_normal((rows, steps, LAYOUT.width)).astype(np.float32)
    block[:, :-1, 12:15] = block[:, 1:, 0:3]
    return block


def test_a_write_error_in_the_process_reaches_the_collector_in_one_line(tmp_path):
    path = tmp_path / "d.zarr"
    open_writer(path, task_id="t", env_args={})
    writer = ProcessWriter(path, task_id="t", layout=LAYOUT)
    ok = writer.put_block(_block(2, 4, 0), {}, [(0, 4, True, {"seed": 1}), (1, 3, False, {"seed": 1})])
    assert [f.result(timeout=60) for f in ok] == [[0, 1]]
    writer.put_block(_block(1, 4, 1), {}, [(0, 4, True, {"success": 1})])  # a reserved attr: refused by the writer
    with pytest.raises(ValueError) as exc:
        writer.flush()
    assert "attr 'success' is set by the writer; pass success= instead" in str(exc.value)
    assert "\n" not in str(exc.value)
    writer.close()
    info = read_dataset_info(path)
    assert info["demo_ids"] == [0, 1] and info["total"] == 7
    ep = read_episode(path, 1)
    block = _block(2, 4, 0)
    np.testing.assert_array_equal(ep["obs"]["x"], block[1, :3, 0:3])
    np.testing.assert_array_equal(ep["next_obs"]["x"], block[1, :3, 12:15])
    np.testing.assert_array_equal(ep["rewards"], block[1, :3, 11])
    assert ep["dones"].tolist() == [0, 0, 0] and ep["attrs"]["seed"] == 1


def test_a_block_is_packed_as_its_demos_trees_would_be(tmp_path):
    """zarr packs a batch of joined demos (``EpisodeWriter.append_block``) byte for byte as it packs their trees."""
    frames = np.random.default_rng(4).integers(0, 255, (40, 9, 2, 2, 3), dtype=np.uint8)
    block = DemoBlock.from_rows(
        LAYOUT, _block(40, 9, 3), {"cam": frames}, [(k, 3 + k % 7, k % 3 == 0, {"seed": k}) for k in range(39, -1, -1)]
    )
    joined, trees = tmp_path / "joined.zarr", tmp_path / "trees.zarr"
    for path in (joined, trees):
        open_writer(path, task_id="t", env_args={})
    assert open_writer(joined, task_id="t", env_args={}).append_block(block) == list(range(40))
    items = list(zip(block.trees(), block.successes, block.attrs))
    assert open_writer(trees, task_id="t", env_args={}).append_episodes(items) == list(range(40))
    index = read_index(joined / "data" / "pack_0")
    assert index == read_index(trees / "data" / "pack_0") and index["arrays"]["next_obs/x"].startswith("next:")
    for demo in range(40):
        a, b = dict(_leaves(read_episode(joined, demo))), dict(_leaves(read_episode(trees, demo)))
        assert a.keys() == b.keys() and "obs/cam" in a and "datagen/subtask_signals/grasp" in a
        for key, value in a.items():
            assert np.array_equal(value, b[key]) and np.asarray(value).dtype == np.asarray(b[key]).dtype, key
    first = read_episode(joined, 0)  # row 39: 3 + 39 % 7 = 7 steps, a success
    np.testing.assert_array_equal(first["obs"]["cam"], frames[39, :7])
    assert first["dones"].tolist() == [0] * 6 + [1] and first["attrs"]["seed"] == 39


def test_the_writer_process_writes_as_its_settings_say(tmp_path):
    """``ProcessWriter``'s ``zarr_settings`` and ``profile_to`` reach the process: a block of 3 demos lands as one
    pack with ``pack_min_batch=3`` and as 3 demo groups by default; the profile of its writes is saved at the end."""
    profile = tmp_path / "writes.prof"
    for settings, names in ((None, ["demo_0", "demo_1", "demo_2"]), (ZarrWriteSettings(pack_min_batch=3), ["pack_0"])):
        path = tmp_path / f"{names[0]}.zarr"
        open_writer(path, task_id="t", env_args={})
        with ProcessWriter(
            path, task_id="t", layout=LAYOUT, zarr_settings=settings, profile_to=profile if settings else None
        ) as writer:
            done = writer.put_block(_block(3, 4, 0), {}, [(k, 4, True, {}) for k in range(3)])
            assert [f.result(timeout=60) for f in done] == [[0, 1, 2]]
        assert sorted(p.name for p in (path / "data").iterdir() if p.is_dir()) == names
        np.testing.assert_array_equal(read_episode(path, 2)["obs"]["x"], _block(3, 4, 0)[2, :, 0:3])
    assert pstats.Stats(str(profile)).total_calls > 0


def test_a_block_larger_than_a_quarter_of_the_ring_goes_in_parts_of_whole_rows(tmp_path):
    """Thousands of long episodes with images can end together: their block crosses in parts, none refused."""
    path = tmp_path / "big.zarr"
    open_writer(path, task_id="t", env_args={})
    block, frames = _block(8, 6, 2), np.arange(8 * 6 * 4, dtype=np.uint8).reshape(8, 6, 2, 2)
    row = block[0].nbytes + frames[0].nbytes
    with ProcessWriter(path, task_id="t", layout=LAYOUT, ring_bytes=4 * 3 * row) as writer:  # 3 rows a part
        parts = writer.put_block(block, {"cam": frames}, [(k, 6 - k % 2, True, {}) for k in range(7, -1, -1)])
        assert [f.result(timeout=60) for f in parts] == [[0, 1, 2], [3, 4, 5], [6, 7]]
        assert writer.hand_over["copy"] > 0 and writer.hand_over["ring_wait"] >= 0  # the collector's own seconds
        assert writer.seconds["copy_out"] > 0 and writer.seconds["queue_wait"] >= 0  # the process's, reported back
    for demo, k in enumerate(range(7, -1, -1)):
        ep = read_episode(path, demo)
        np.testing.assert_array_equal(ep["obs"]["x"], block[k, : 6 - k % 2, 0:3])
        np.testing.assert_array_equal(ep["obs"]["cam"], frames[k, : 6 - k % 2])


def test_a_killed_collector_leaves_a_writer_process_that_writes_what_it_got_and_exits(tmp_path):
    path = tmp_path / "k.zarr"
    child = textwrap.dedent(f"""
        import sys, time, numpy as np
        sys.path.insert(0, {os.path.dirname(__file__)!r})
        from test_writer_process import LAYOUT, _block
        from newton_lab.datasets import open_writer
        from newton_lab.datasets.writers.process import ProcessWriter
        open_writer({str(path)!r}, task_id="t", env_args={{}})
        w = ProcessWriter({str(path)!r}, task_id="t", layout=LAYOUT)
        for i in range(3):
            w.put_block(_block(4, 6, i), {{}}, [(k, 6, True, {{}}) for k in range(4)])
        w.flush()
        print(w._proc.pid, flush=True)
        time.sleep(600)
    """)
    collector = subprocess.Popen([sys.executable, "-c", child], stdout=subprocess.PIPE, text=True)
    try:
        writer_pid = int(collector.stdout.readline())
    finally:
        collector.send_signal(signal.SIGKILL)
        collector.wait()
    deadline = time.time() + 30
    while time.time() < deadline and os.path.exists(f"/proc/{writer_pid}") and _state(writer_pid) != "Z":
        time.sleep(0.1)
    assert not os.path.exists(f"/proc/{writer_pid}") or _state(writer_pid) == "Z", "the writer process lives on"
    assert read_dataset_info(path)["demo_ids"] == list(range(12))


def _state(pid: int) -> str:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0]
    except FileNotFoundError:
        return "gone"


@pytest.mark.parametrize(("ring_mib", "packs"), [(256, 1), (8, 0)])
def test_frames_are_written_from_the_ring_frame_for_frame(tmp_path, ring_mib, packs):
    """The process writes image frames straight from its ring (``RowPieces``), and a burst's room comes back only
    once it is written: with room for all, one pack whose time chunks span demos and bursts; with a ring of ~13
    demos, that wraps many times, batches of a few demos written group by group. Every demo reads back frame for
    frame, as the writer thread writes them from copies."""
    frames = np.random.default_rng(3).integers(0, 255, (40, 30, 72, 96, 3), dtype=np.uint8)  # 50 frames a chunk
    block = _block(40, 30, 4)
    lengths = [17 + k % 13 for k in range(40)]
    path = tmp_path / "f.zarr"
    open_writer(path, task_id="t", env_args={})
    with ProcessWriter(path, task_id="t", layout=LAYOUT, min_batch=40, ring_bytes=ring_mib << 20) as writer:
        done = []
        for first in (0, 16, 32):  # three bursts
            rows = range(first, min(first + 16, 40))
            done += writer.put_block(
                block[first : first + 16],
                {"cam": frames[first : first + 16]},
                [(k - first, lengths[k], True, {}) for k in rows],
            )
        assert [i for f in done for i in f.result(timeout=60)] == list(range(40))
        assert (writer.batches == 1) == (packs == 1)
    found = [p for p in (path / "data").iterdir() if p.name.startswith("pack_")]
    assert len(found) == packs and all(read_index(p) is not None for p in found)
    for k in range(40):
        ep = read_episode(path, k)
        np.testing.assert_array_equal(ep["obs"]["cam"], frames[k, : lengths[k]])
        np.testing.assert_array_equal(ep["obs"]["x"], block[k, : lengths[k], 0:3])
    thread_path = tmp_path / "t.zarr"
    w = open_writer(thread_path, task_id="t", env_args={})
    w.append_block(DemoBlock.from_rows(LAYOUT, block, {"cam": frames}, [(k, lengths[k], True, {}) for k in range(40)]))
    w.close()
    for k in range(40):
        np.testing.assert_array_equal(read_episode(thread_path, k)["obs"]["cam"], read_episode(path, k)["obs"]["cam"])
    if packs:  # a damaged chunk of frames is refused in one line, as any damaged dataset is, and left as it is
        chunk = found[0] / "obs" / "cam" / "c.3.0.0.0"  # rows 150..199: demo 8's frames
        chunk.write_bytes(chunk.read_bytes()[:100])
        with pytest.raises(ValueError, match=r"is not a newton_lab dataset or is damaged \(pack_0 \(demo 8\)") as e:
            read_episode(path, 8)
        assert "\n" not in str(e.value) and len(chunk.read_bytes()) == 100
