"""One writer protocol for HDF5 and zarr: concurrent writers, the bounded lock wait, refused writes. No physics."""

from __future__ import annotations

import errno
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
import zarr

from newton_lab.datasets import _common, list_demos, open_writer, read_dataset_info, read_episode
from newton_lab.datasets.storage import DatasetLockedError, DatasetWriteError, inject_write_fault

ROOT = Path(__file__).resolve().parents[1]
TASK = "pick_cube"
FORMATS = [".hdf5", ".zarr"]
STEPS = 40


def episode(seed: int, steps: int = STEPS) -> dict:
    rng = np.random.default_rng(seed)
    return {"actions": rng.standard_normal((steps, 7)).astype(np.float32),
            "obs": {"eef_pos": rng.standard_normal((steps, 3)),
                    "rgb": rng.integers(0, 255, (steps, 8, 8, 3), dtype=np.uint8)},
            "states": {"robot": {"qpos": rng.standard_normal((steps, 9)).astype(np.float32)}}}


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
print("READY", flush=True)
while not go.exists():
    time.sleep(0.005)
with open_writer(path, task_id="pick_cube", env_args={}) as w:
    for seed in range(first, first + 6):
        print("APPENDED", w.append_episode(episode(seed), success=True, attrs={"seed": seed}), seed, flush=True)
"""


@pytest.mark.parametrize("suffix", FORMATS)
def test_two_processes_append_to_one_dataset(tmp_path, suffix):
    """Both create the dataset at once, then interleave appends: 12 episodes, unique ids, none lost."""
    path, go = tmp_path / f"ds{suffix}", tmp_path / "go"
    procs = [subprocess.Popen([sys.executable, "-c", APPENDER, str(path), str(first), str(go)], env=child_env(),
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for first in (0, 100)]
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
    assert min(first) < max(second) and min(second) < max(first)  # fair: neither waited for all of the other
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
        monkeypatch.setattr(_common, "LOCK_WAIT_S", 0.5)
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
    assert re.fullmatch(rf"disk full after (\d+) episodes?; {re.escape(str(path))} holds \1 finished episodes?",
                        str(exc.value)), str(exc.value)
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
        assert sorted(zarr.open_group(str(path), mode="r", zarr_format=3)["data"].group_keys()) == \
            sorted(f"demo_{i}" for i in range(held))
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
w = open_writer(sys.argv[1], task_id="pick_cube", env_args={})
for seed in range(100):
    w.append_episode(episode(seed), success=True, attrs={"seed": seed})
"""


@pytest.mark.parametrize("suffix", FORMATS)
def test_fault_seam_reaches_subprocesses(tmp_path, suffix):
    """``NEWTON_LAB_TEST_WRITE_FAULT`` (honoured under pytest only) lets CLI tests fill the disk."""
    path = tmp_path / f"ds{suffix}"
    proc = subprocess.run([sys.executable, "-c", FULL_CHILD, str(path)], check=False, capture_output=True, text=True,
                          env=dict(child_env(), NEWTON_LAB_TEST_WRITE_FAULT="200"), timeout=120)
    assert proc.returncode == 1 and "Segmentation" not in proc.stderr
    last = proc.stderr.strip().splitlines()[-1]
    held = len(list_demos(path))
    assert held >= 2 and list_demos(path) == list(range(held))
    assert last.endswith(f"DatasetWriteError: disk full after {held} episodes; {path} holds {held} finished episodes")
