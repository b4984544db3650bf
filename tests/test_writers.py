"""One writer protocol for HDF5 and zarr: concurrent writers, the bounded lock wait, refused writes. No physics."""

from __future__ import annotations

import errno
import os
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
import zarr

from newton_lab.datasets import delete_demos, list_demos, open_writer, read_dataset_info, read_episode
from newton_lab.datasets.files import locking
from newton_lab.datasets.storage import DatasetLockedError, DatasetWriteError, inject_write_fault
from newton_lab.datasets.writers.background_thread import BackgroundWriter

ROOT = Path(__file__).resolve().parents[1]
TASK = "pick_cube"
FORMATS = [".hdf5", ".zarr"]
STEPS = 40


def episode(seed: int, steps: int = STEPS) -> dict:
    rng = np.random.default_rng(seed)
    return {
        "actions": rng.standard_normal((steps, 7)).astype(np.float32),
        "obs": {
            "eef_pos": rng.standard_normal((steps, 3)),
            "rgb": rng.integers(0, 255, (steps, 8, 8, 3), dtype=np.uint8),
        },
        "states": {"robot": {"qpos": rng.standard_normal((steps, 9)).astype(np.float32)}},
    }


def assert_episode(path: Path, demo_id: int, seed: int) -> None:
    ep = read_episode(path, demo_id)
    assert ep.pop("attrs")["seed"] == seed
    expected = episode(seed)
    np.testing.assert_array_equal(ep["actions"], expected["actions"])
    np.testing.assert_array_equal(ep["obs"]["rgb"], expected["obs"]["rgb"])
    np.testing.assert_array_equal(ep["states"]["robot"]["qpos"], expected["states"]["robot"]["qpos"])


def child_env() -> dict:
    return dict(os.environ, PYTHONPATH=f"{ROOT}{os.pathsep}{Path(__file__).parent}")


@pytest.fixture(autouse=True)
def _no_fault_left():
    yield
    inject_write_fault(None)


# ----------------------------------------------------------------------------- two writers
APPENDER = """
import sys, time
from pathlib import Path
from test_writers import episode
from newton_lab.datasets import open_writer
path, first, go = sys.argv[1], int(sys.argv[2]), Path(sys.argv[3])
mine, peer = go.with_name(f"appended_{first}"), go.with_name(f"appended_{100 - first}")
print("READY", flush=True)
while not go.exists():
    time.sleep(0.005)
with open_writer(path, task_id="pick_cube", env_args={}) as w:
    for seed in range(first, first + 6):
        if seed == first + 3:  # half-way, with this writer open: the other process must get its appends in
            t0 = time.monotonic()
            while not peer.exists():
                if time.monotonic() - t0 > 60:
                    sys.exit("the other process appended nothing while this writer was open")
                time.sleep(0.005)
        print("APPENDED", w.append_episode(episode(seed), success=True, attrs={"seed": seed}), seed, flush=True)
        mine.touch()
"""


@pytest.mark.parametrize("suffix", FORMATS)
def test_two_processes_append_to_one_dataset(tmp_path, suffix):
    """Both create the dataset at once, then interleave appends: 12 episodes, unique ids, none lost. Each
    appender waits half-way, its writer open, until the other has appended (the lock is held per write, not per
    open writer), so the interleaving does not depend on how the OS schedules the two processes."""
    path, go = tmp_path / f"ds{suffix}", tmp_path / "go"
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", APPENDER, str(path), str(first), str(go)],
            env=child_env(),
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for first in (0, 100)
    ]
    for proc in procs:
        assert proc.stdout.readline().strip() == "READY", proc.stderr.read()
    go.touch()
    reported = []
    for proc in procs:
        out, err = proc.communicate(timeout=120)
        assert proc.returncode == 0, err
        reported += [(int(a), int(b)) for _, a, b in (line.split() for line in out.splitlines())]

    ids = sorted(i for i, _ in reported)
    assert len(reported) == 12 and ids == list(range(12))
    first, second = ([i for i, seed in reported if (seed >= 100) == k] for k in (False, True))
    assert min(first) < max(second) and min(second) < max(first)  # interleaved: neither waited for all of the other
    info = read_dataset_info(path)
    assert info["demo_ids"] == ids and info["num_demos"] == 12 and info["total"] == 12 * STEPS
    for demo_id, seed in reported:
        assert_episode(path, demo_id, seed)
    if suffix == ".zarr":
        assert sorted(os.listdir(path / "data")) == sorted([f"demo_{i}" for i in ids] + ["zarr.json"])


HOLDER = """
import fcntl, sys, time
fd = open(sys.argv[1], "rb")
fcntl.flock(fd, fcntl.LOCK_EX)
print("LOCKED", flush=True)
time.sleep(60)
"""


@pytest.mark.parametrize("suffix", FORMATS)
def test_locked_dataset_ends_in_one_line_naming_the_holder(tmp_path, suffix, monkeypatch):
    path = tmp_path / f"ds{suffix}"
    with open_writer(path, task_id=TASK, env_args={}) as w:
        w.append_episode(episode(0), success=True, attrs={"seed": 0})
    lock_file = path / "zarr.json" if suffix == ".zarr" else path
    holder = subprocess.Popen([sys.executable, "-c", HOLDER, str(lock_file)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "LOCKED"
        monkeypatch.setattr(locking, "LOCK_WAIT_S", 0.5)
        start = time.monotonic()
        with pytest.raises(DatasetLockedError) as exc, open_writer(path, task_id=TASK, env_args={}) as w:
            w.append_episode(episode(1), success=True)
        assert time.monotonic() - start < 5
    finally:
        holder.kill()
        holder.wait()
    msg = str(exc.value)
    assert msg == f"{path} is locked by process {holder.pid}; wait for it or write to another path"
    assert isinstance(exc.value, ValueError)  # the CLI's one-line errors
    with open_writer(path, task_id=TASK, env_args={}) as w:  # the holder is gone: appends go on
        assert w.append_episode(episode(1), success=True, attrs={"seed": 1}) == 1
    assert_episode(path, 0, 0)
    assert_episode(path, 1, 1)


# ----------------------------------------------------------------------------- refused writes
@pytest.mark.parametrize("suffix", FORMATS)
@pytest.mark.parametrize("fail_at", [1, 2, 7, 30])
def test_disk_full_ends_in_one_line_and_keeps_the_episodes(tmp_path, suffix, fail_at, capfd):
    path = tmp_path / f"ds{suffix}"
    with open_writer(path, task_id=TASK, env_args={}) as w:
        for seed in range(3):
            w.append_episode(episode(seed), success=True, attrs={"seed": seed})
        capfd.readouterr()
        inject_write_fault(fail_at)  # the fail_at-th write from now raises ENOSPC, and every later one
        with pytest.raises(DatasetWriteError) as exc:
            for seed in range(3, 50):
                w.append_episode(episode(seed), success=True, attrs={"seed": seed})
        inject_write_fault(None)
    assert isinstance(exc.value, OSError) and exc.value.errno == errno.ENOSPC
    assert re.fullmatch(
        rf"disk full after (\d+) episodes?; {re.escape(str(path))} holds \1 finished episodes?", str(exc.value)
    ), str(exc.value)
    held = int(str(exc.value).split()[3])
    assert held >= 3 and capfd.readouterr().err == ""  # no traceback flood
    assert list_demos(path) == list(range(held)) and read_dataset_info(path)["total"] == held * STEPS
    for seed in range(held):
        assert_episode(path, seed, seed)
    if suffix == ".hdf5":  # no journal left, and h5py itself opens it
        assert not Path(f"{path}-journal").exists()
        with h5py.File(path, "r") as f:
            assert sorted(f["data"]) == [f"demo_{i}" for i in range(held)]
    else:  # the failed demo was taken out again
        assert sorted(os.listdir(path / "data")) == sorted([f"demo_{i}" for i in range(held)] + ["zarr.json"])
        assert sorted(zarr.open_group(str(path), mode="r", zarr_format=3)["data"].group_keys()) == sorted(
            f"demo_{i}" for i in range(held)
        )
    with open_writer(path, task_id=TASK, env_args={}) as w:  # space again: appending goes on
        assert w.append_episode(episode(99), success=True, attrs={"seed": 99}) == held
    assert_episode(path, held, 99)


@pytest.mark.parametrize("suffix", FORMATS)
def test_io_error_uses_the_os_words(tmp_path, suffix):
    path = tmp_path / f"ds{suffix}"
    with open_writer(path, task_id=TASK, env_args={}) as w:
        w.append_episode(episode(0), success=True, attrs={"seed": 0})
        inject_write_fault(3, errno.EIO)
        with pytest.raises(DatasetWriteError) as exc:
            w.append_episode(episode(1), success=True)
    assert str(exc.value) == f"input/output error after 1 episode; {path} holds 1 finished episode"
    assert exc.value.errno == errno.EIO
    inject_write_fault(None)
    assert list_demos(path) == [0]
    assert_episode(path, 0, 0)


FULL_CHILD = """
import sys
from test_writers import episode
from newton_lab.datasets import open_writer
from newton_lab.datasets.files.write_faults import inject_write_fault
inject_write_fault(int(sys.argv[2]))  # the disk fills at this write
w = open_writer(sys.argv[1], task_id="pick_cube", env_args={})
for seed in range(100):
    w.append_episode(episode(seed), success=True, attrs={"seed": seed})
"""


@pytest.mark.parametrize("suffix", FORMATS)
def test_a_full_disk_ends_a_writing_process_in_one_line(tmp_path, suffix):
    """The write-fault seam, armed by the test's own child process (never by the environment), fills its disk: the
    process exits 1 with one line saying what the dataset holds."""
    path = tmp_path / f"ds{suffix}"
    # 400 writes: a zarr episode takes ~105 (its rgb frames are one chunk each)
    proc = subprocess.run(
        [sys.executable, "-c", FULL_CHILD, str(path), "400"],
        check=False,
        capture_output=True,
        text=True,
        env=child_env(),
        timeout=120,
    )
    assert proc.returncode == 1 and "Segmentation" not in proc.stderr
    last = proc.stderr.strip().splitlines()[-1]
    held = len(list_demos(path))
    assert held >= 2 and list_demos(path) == list(range(held))
    assert last.endswith(f"DatasetWriteError: disk full after {held} episodes; {path} holds {held} finished episodes")


# ----------------------------------------------------------------------------- batches (issue 14)
BATCH_CHILD = """
import os, signal, sys
from test_writers import episode
from newton_lab.datasets.hdf5 import journal as _journal, store as hdf5_store
from newton_lab.datasets import open_writer
from newton_lab.datasets.zarr import packs as zarr_packs, store as zarr_store
path, point = sys.argv[1], sys.argv[2]
store = zarr_store if path.endswith(".zarr") else hdf5_store
w = open_writer(path, task_id="pick_cube", env_args={})
for b in range(2):
    batch = [(episode(10 * b + k), True, {"seed": 10 * b + k}) for k in range(3)]
    print("BATCH", *w.append_episodes(batch), flush=True)
def die(*args, **kwargs):
    os.kill(os.getpid(), signal.SIGKILL)
if point == "mid_write" and path.endswith(".zarr"):  # the 4th of 6 episodes: its first arrays written, then killed
    real, calls = zarr_packs.write_demo, [0]  # the per-demo writer, as zarr_packs.write_job calls it
    def write_demo(node, attrs, tree, fallback):
        calls[0] += 1
        if calls[0] == 4:
            real(node, attrs, {"actions": tree["actions"]}, fallback)
            die()
        real(node, attrs, tree, fallback)
    zarr_packs.write_demo = write_demo
elif point == "mid_write":  # inside the 4th of 6 episodes (each tree: 4 nested _write_tree calls)
    real, calls = store._write_tree, [0]
    def write_tree(g, tree):
        calls[0] += 1
        if calls[0] == 14:
            die()
        real(g, tree)
    store._write_tree = write_tree
elif path.endswith(".zarr"):  # every demo renamed into place, the commit (next_demo_id) not written
    store._commit = die
else:  # every byte written, the journal closed: killed just before the commit (journal deletion)
    real_close = _journal.JournaledFile.close_journal
    _journal.JournaledFile.close_journal = lambda self: (real_close(self), die())
w.append_episodes([(episode(100 + k), True, {"seed": 100 + k}) for k in range(6)])
print("NOT KILLED", flush=True)
"""


@pytest.mark.parametrize("point", ["mid_write", "before_commit"])
@pytest.mark.parametrize("suffix", FORMATS)
def test_sigkill_mid_batch_keeps_earlier_batches_and_none_of_the_killed_one(tmp_path, suffix, point):
    path = tmp_path / f"ds{suffix}"
    proc = subprocess.run(
        [sys.executable, "-c", BATCH_CHILD, str(path), point],
        check=False,
        env=child_env(),
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == -9, proc.stderr
    assert proc.stdout.split("\n")[:2] == ["BATCH 0 1 2", "BATCH 3 4 5"], proc.stdout
    seeds = [0, 1, 2, 10, 11, 12]
    if suffix == ".hdf5":  # really torn: the killed session left its journal
        assert Path(f"{path}-journal").exists()
    elif point == "before_commit":  # really torn: the killed batch's demos are in place, uncommitted
        assert all((path / "data" / f"demo_{i}" / "zarr.json").exists() for i in range(6, 12))
    info = read_dataset_info(path)  # HDF5: rolls the killed session back first
    assert info["demo_ids"] == list(range(6)) and info["num_demos"] == 6 and info["total"] == 6 * STEPS
    for demo_id, seed in enumerate(seeds):
        assert_episode(path, demo_id, seed)
    with open_writer(path, task_id=TASK, env_args={}) as w:  # the killed batch's ids are given again
        assert w.append_episodes([(episode(s), True, {"seed": s}) for s in (7, 8)]) == [6, 7]
    assert list_demos(path) == list(range(8)) and read_dataset_info(path)["total"] == 8 * STEPS
    assert_episode(path, 6, 7)
    assert_episode(path, 7, 8)
    if suffix == ".zarr":  # the killed batch's staged and renamed demos were removed
        assert sorted(os.listdir(path / "data")) == sorted([f"demo_{i}" for i in range(8)] + ["zarr.json"])
    else:
        assert not Path(f"{path}-journal").exists()
        with h5py.File(path, "r") as f:
            assert sorted(f["data"]) == sorted(f"demo_{i}" for i in range(8))
            assert f["data"].attrs["next_demo_id"] == 8


def _forbid_walks(monkeypatch) -> None:
    """Fail the test if an append walks the demos already stored (HDF5 ``_committed``, zarr ``_scan``)."""
    from newton_lab.datasets.hdf5 import store as hdf5_store
    from newton_lab.datasets.zarr import store as zarr_store

    def walk(*args, **kwargs):
        raise AssertionError("append walked the existing demos")

    monkeypatch.setattr(hdf5_store, "_committed", walk)
    monkeypatch.setattr(zarr_store, "_scan", walk)


def _drop_next_id(path: Path) -> None:
    """Make ``path`` look written by a version without ``next_demo_id`` (totals present)."""
    if path.suffix == ".zarr":
        zarr.open_group(str(path), mode="r+", zarr_format=3)["data"].attrs.__delitem__("next_demo_id")
    else:
        with h5py.File(path, "r+") as f:
            del f["data"].attrs["next_demo_id"]


@pytest.mark.parametrize("suffix", FORMATS)
def test_append_reads_only_the_root_attrs(tmp_path, suffix, monkeypatch):
    """No walk over existing demos on append, so its cost does not grow with the dataset; a dataset of the
    older layout (no next_demo_id) is walked once, on its first append, and then keeps the attr."""
    path = tmp_path / f"ds{suffix}"
    with open_writer(path, task_id=TASK, env_args={}, fsync=False) as w:
        w.append_episodes([(episode(s), True, {"seed": s}) for s in range(3)])
    _drop_next_id(path)
    with open_writer(path, task_id=TASK, env_args={}, fsync=False) as w:
        assert w.append_episode(episode(3), success=True, attrs={"seed": 3}) == 3  # derived once, stored
    with monkeypatch.context() as m:
        _forbid_walks(m)
        with open_writer(path, task_id=TASK, env_args={}, fsync=False) as w:
            assert w.append_episodes([(episode(s), s % 2 == 0, {"seed": s}) for s in range(4, 9)]) == [4, 5, 6, 7, 8]
            assert w.append_episode(episode(9), success=True, attrs={"seed": 9}) == 9
            assert w.append_episodes([]) == []
    info = read_dataset_info(path)
    assert info["demo_ids"] == list(range(10)) and info["total"] == 10 * STEPS and info["num_demos"] == 10
    assert info["demos"][5] == {"num_samples": STEPS, "success": False}
    for seed in (0, 3, 4, 9):
        assert_episode(path, seed, seed)
    delete_demos(path, [9])  # ids are never reused, also after deleting the last one
    with open_writer(path, task_id=TASK, env_args={}, fsync=False) as w:
        assert w.append_episode(episode(10), success=True, attrs={"seed": 10}) == 10


@pytest.mark.parametrize("suffix", FORMATS)
def test_bad_episode_in_a_batch_writes_none(tmp_path, suffix):
    path = tmp_path / f"ds{suffix}"
    with open_writer(path, task_id=TASK, env_args={}) as w, pytest.raises(ValueError, match="actions"):
        w.append_episodes([(episode(0), True, None), ({"obs": {"x": np.zeros((3, 1))}}, True, None)])
    assert list_demos(path) == []


# ----------------------------------------------------------------------------- background writer
@pytest.mark.parametrize("suffix", FORMATS)
def test_background_writer_round_trip(tmp_path, suffix):
    path = tmp_path / f"ds{suffix}"
    with BackgroundWriter(open_writer(path, task_id=TASK, env_args={}), max_queued=8) as bg:
        futures = bg.put_many([(episode(s), True, {"seed": s}) for s in range(3)])
        futures += [bg.put(episode(s), success=True, attrs={"seed": s}) for s in range(3, 12)]
        with pytest.raises(ValueError, match="actions"):  # checked in the caller, nothing queued
            bg.put({"obs": {"x": np.zeros((3, 1))}}, success=True)
        bg.flush()
        assert all(f.done() for f in futures)
    assert [f.result() for f in futures] == list(range(12)) and 1 <= bg.batches <= 12
    assert list_demos(path) == list(range(12))
    for seed in range(12):
        assert_episode(path, seed, seed)
    with pytest.raises(RuntimeError, match="closed"):
        bg.put(episode(0), success=True)


def test_background_writer_blocks_when_the_queue_is_full(tmp_path, monkeypatch):
    path = tmp_path / "ds.hdf5"
    writer = open_writer(path, task_id=TASK, env_args={}, fsync=False)
    release, real = threading.Event(), writer.append_prepared

    def slow(batch):
        release.wait(60)
        return real(batch)

    monkeypatch.setattr(writer, "append_prepared", slow)
    bg = BackgroundWriter(writer, max_queued=2)
    waiting, real_wait = threading.Event(), bg._wait

    def recording_wait(ready):  # the blocked put's thread found no room: it waits on the condition
        if threading.current_thread().name == "blocked put" and not ready():
            waiting.set()
        return real_wait(ready)

    bg._wait = recording_wait
    first = bg.put(episode(0), success=True, attrs={"seed": 0})  # taken by the thread: it waits on `release`
    deadline = time.monotonic() + 30
    while not bg._busy:
        assert time.monotonic() < deadline, "the writer thread never took the first episode"
        time.sleep(0.001)
    queued = bg.put_many([(episode(s), True, {"seed": s}) for s in (1, 2)])  # fills the queue
    blocked = threading.Thread(
        target=lambda: queued.append(bg.put(episode(3), success=True, attrs={"seed": 3})),
        name="blocked put",
        daemon=True,
    )
    blocked.start()
    while not waiting.is_set() and blocked.is_alive():  # one or the other happens: no sleep decides it
        assert time.monotonic() < deadline, "the put neither waited nor returned"
        time.sleep(0.001)
    # back-pressure: the put waits for room; the writer is held on `release`, so it cannot get any
    assert waiting.is_set() and blocked.is_alive() and len(queued) == 2
    release.set()
    blocked.join(60)
    assert not blocked.is_alive()
    bg.close()
    assert [f.result() for f in [first, *queued]] == [0, 1, 2, 3] and bg.batches == 3
    assert list_demos(path) == [0, 1, 2, 3]


@pytest.mark.parametrize("suffix", FORMATS)
def test_background_disk_full_raises_in_the_caller_with_the_one_line(tmp_path, suffix, capfd):
    path = tmp_path / f"ds{suffix}"
    bg = BackgroundWriter(open_writer(path, task_id=TASK, env_args={}))
    bg.put_many([(episode(s), True, {"seed": s}) for s in range(3)])
    bg.flush()
    capfd.readouterr()
    inject_write_fault(5)
    futures = []
    with pytest.raises(DatasetWriteError) as exc:
        for seed in range(3, 200):
            futures.append(bg.put(episode(seed), success=True, attrs={"seed": seed}))
        bg.flush()
    bg.close()  # the error was raised once: close does not raise it again
    inject_write_fault(None)
    assert re.fullmatch(
        rf"disk full after (\d+) episodes?; {re.escape(str(path))} holds \1 finished episodes?", str(exc.value)
    ), str(exc.value)
    held = int(str(exc.value).split()[3])
    assert held >= 3 and list_demos(path) == list(range(held)) and capfd.readouterr().err == ""
    written = [f for f in futures if f.exception() is None]
    assert [f.result() for f in written] == list(range(3, held)) and all(f.done() for f in futures)
    with open_writer(path, task_id=TASK, env_args={}) as w:  # space again: appending goes on
        assert w.append_episode(episode(99), success=True, attrs={"seed": 99}) == held
