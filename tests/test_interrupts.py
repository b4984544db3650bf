"""Interrupts and kills are ends, not crashes: Ctrl-C (SIGINT) during collect, train and split exits 130 with one
line saying what was kept and where, every finished item kept; a SIGKILLed split leaves no phase writer running and
no partial output that looks finished (the next split runs)."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from test_lerobot_export import make_dataset

from newton_lab.cli.watchdog import children, descendants  # the /proc walk the watchdog itself uses

pytestmark = pytest.mark.slow  # each test starts and stops CLI processes (torch, Warp): in CI, not in a plain make test

TASK = "GalbotG1-PickToShelf-v0"
RUN = "import sys; from newton_lab.cli import main; sys.exit(main(sys.argv[1:]))"


def newton_lab(*argv: str, cwd: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-c", RUN, *argv], cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )


def wait_for(condition, what: str, limit_s: float = 900.0) -> None:
    """Poll ``condition`` until it holds (a generous limit: 2 cores under a load of 6 are slow; not a timing
    check)."""
    end = time.monotonic() + limit_s
    while not condition():
        if time.monotonic() > end:
            raise AssertionError(f"never saw {what}")
        time.sleep(0.05)


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def make_splittable(path: Path, demos: int, steps: int) -> None:
    """A dataset recorded on the coherent PickToShelf (action columns of all its components, ``datagen/phase`` a
    third of each episode per phase), made without an env."""
    import newton_lab.tasks  # noqa: F401

    from newton_lab.datasets import open_writer
    from newton_lab.robots.registry import robot_binding
    from newton_lab.task_api.registry import lookup

    names: list[str] = []
    cfg = lookup(TASK).make_cfg({})
    for ph in cfg.phases:
        comp = lookup(ph.task_id)
        comp = comp.cfg(**comp.accepted({}))
        groups = robot_binding(comp.robot).joint_groups
        names += [j for t in comp.actions for j in groups[t.group] if j not in names]
    args = {
        "newton_lab": {"action_joint_names": names, "phases": [p.name for p in cfg.phases], "obs_terms": {"q": [0, 40]}}
    }
    rng = np.random.default_rng(0)
    with open_writer(path, task_id=TASK, env_args=args, fsync=False) as w:
        w.append_episodes(
            [
                (
                    {
                        "actions": rng.standard_normal((steps, len(names))).astype(np.float32),
                        "obs": {"q": rng.standard_normal((steps, 40)).astype(np.float32)},
                        "dones": np.zeros(steps, dtype=np.int64),
                        "datagen": {"phase": np.repeat(np.arange(3, dtype=np.int32), -(-steps // 3))[:steps]},
                    },
                    True,
                    None,
                )
                for _ in range(demos)
            ]
        )


def split_caught_writing(tmp_path: Path, data: str):
    """``split`` of ``data`` into ``parts``, once its first phase writers are writing (one per core, up to the three
    phases: on 2 cores the third phase starts only after one of the first two ended, near the split's end, and a
    signal sent then landed after the split had finished under load): (the process, its stage folder, its writer
    pids)."""
    split = newton_lab("split", "--dataset-path", data, "--out", "parts", cwd=tmp_path)
    stage = tmp_path / f".parts.{split.pid}.partial"
    writers = min(3, os.cpu_count() or 1)
    wait_for(
        lambda: len(list(stage.glob("*.hdf5"))) >= writers or split.poll() is not None, "the phase writers writing"
    )
    assert split.poll() is None, split.communicate()
    return split, stage, children(split.pid)


def test_a_killed_split_leaves_no_writer_and_nothing_that_looks_finished(tmp_path):
    """SIGKILL while the phase writers write: they end with it (a parent-death signal), the output folder does not
    appear (the phases are written in a stage beside it, renamed into place when all are done), and the next split
    removes the stage and writes every demo."""
    from newton_lab.datasets import read_dataset_info

    make_splittable(tmp_path / "c.hdf5", demos=400, steps=60)
    split, stage, writers = split_caught_writing(tmp_path, "c.hdf5")
    assert writers
    split.kill()
    split.communicate()
    wait_for(lambda: not any(alive(w) for w in writers), "the phase writers ending", limit_s=120)
    assert not (tmp_path / "parts").exists() and stage.exists()
    again = newton_lab("split", "--dataset-path", "c.hdf5", "--out", "parts", cwd=tmp_path)
    out, err = again.communicate(timeout=900)
    assert again.returncode == 0, err
    assert sorted(p.name for p in (tmp_path / "parts").iterdir()) == ["nav.hdf5", "pick.hdf5", "place.hdf5"]
    assert all(read_dataset_info(tmp_path / "parts" / f"{p}.hdf5")["num_demos"] == 400 for p in ("pick", "nav"))
    assert not stage.exists() and not list(tmp_path.glob(".parts.*"))


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_ctrl_c_during_collect_keeps_every_finished_episode_in_one_line(tmp_path, signum):
    """Ctrl-C (SIGINT) or SIGTERM: exit status 130 / 143, one line, every finished episode kept."""
    from newton_lab.datasets import read_dataset_info

    path = tmp_path / "r.hdf5"

    def demos() -> int:
        try:
            return read_dataset_info(path)["num_demos"]
        except (OSError, ValueError):  # not there yet, or being written
            return 0

    run = newton_lab(
        "collect",
        "--task",
        "GalbotG1-Reach-v0",
        "--episodes",
        "100000",
        "--num-envs",
        "2",
        "--max-steps",
        "5",
        "--cameras",
        "none",
        "--no-progress",
        "--dataset-path",
        str(path),
        cwd=tmp_path,
    )
    wait_for(lambda: demos() >= 2 or run.poll() is not None, "two episodes written")
    run.send_signal(signum)
    out, err = run.communicate(timeout=900)
    lines = [line for line in err.splitlines() if "CUDA driver" not in line]
    assert run.returncode == 128 + signum and len(lines) == 1, err
    kept = read_dataset_info(path)["num_demos"]
    assert f"newton-lab collect: interrupted: {kept} finished episodes of this run kept in {path}" in lines[0]
    assert kept >= 2


def test_ctrl_c_during_train_saves_the_resume_point(tmp_path):
    """The run stops after the step in flight, writes resume.pt and says so; --resume continues from it."""
    make_dataset(tmp_path / "d.hdf5")
    argv = (
        "train",
        "--dataset-path",
        "d.hdf5",
        "--preset",
        "cpu",
        "--output-dir",
        "pol",
        "--checkpoint-every-steps",
        "100000",
        "--checkpoint-every-s",
        "100000",
        "--max-steps",
        "300",
    )
    run = newton_lab(*argv, cwd=tmp_path)
    read = []

    def training() -> bool:  # the first line on stderr: the data is read, the loop starts
        read.append(run.stderr.readline())
        return "windows read" in read[-1] or run.poll() is not None

    wait_for(training, "training to start")
    run.send_signal(signal.SIGINT)  # while the model is built, or in the first steps: stops after the next step
    _, err = run.communicate(timeout=900)
    lines = [line for line in err.splitlines() if line.strip()]
    assert run.returncode == 130 and len(lines) == 1, err
    assert "newton-lab train: interrupted at step " in lines[0] and "pol/resume.pt; continue with --resume" in lines[0]
    step = int(lines[0].split("interrupted at step ")[1].split()[0])
    assert 1 <= step < 300
    assert (tmp_path / "pol" / "resume.pt").is_file() and not (tmp_path / "pol" / "checkpoint.pt").exists()
    again = newton_lab(*argv, "--resume", cwd=tmp_path)
    out, err = again.communicate(timeout=900)
    assert again.returncode == 0, err
    log = json.loads((tmp_path / "pol" / "train_log.json").read_text())
    assert log["resumed_at_steps"] == [step] and log["steps"] == 300
    assert (tmp_path / "pol" / "checkpoint.pt").is_file() and not (tmp_path / "pol" / "resume.pt").exists()


@pytest.fixture(autouse=True)
def _no_stray_children():
    """Nothing this module starts outlives its test (a test that failed midway leaves none running either). Children
    the worker had before the test are another module's (a test server of the same pytest worker) and not counted."""
    before = set(children(os.getpid()))
    yield
    stray = [c for c in children(os.getpid()) if alive(c) and c not in before]
    for pid in stray:
        os.kill(pid, signal.SIGKILL)
    assert not stray


def limited(limit_bytes: int):
    """A ``preexec_fn``: files of the child stop growing at ``limit_bytes`` and a write past it fails with EFBIG (a
    refused write, as on a full disk or a quota, without a small file system)."""
    import resource

    def apply() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))

    return apply


@pytest.mark.parametrize("command", ["train", "split", "export"])
def test_a_refused_write_ends_train_and_split_in_one_line_leaving_nothing_half_written(tmp_path, command):
    """A write the disk refuses (here: past a file-size limit, EFBIG) ends ``train`` (torch.save), ``split`` (a
    phase writer's HDF5 write) and ``export`` (a parquet file) with exit status 1 and one line; no temporary or
    partial file is left."""
    if command == "export":
        make_dataset(tmp_path / "d.hdf5", lengths=(300, 300, 300))
        argv = ["export", "--dataset-path", "d.hdf5", "--root", "lerobot"]
        limit, words = 20_000, "the disk refused a write (File too large): "
    elif command == "train":
        make_dataset(tmp_path / "d.hdf5")
        argv = ["train", "--dataset-path", "d.hdf5", "--preset", "cpu", "--max-steps", "2", "--output-dir", "pol"]
        limit, words = 100_000, "the disk refused a write (short write) while writing pol/checkpoint.pt; free space"
    else:
        make_splittable(tmp_path / "c.hdf5", demos=40, steps=60)
        argv = ["split", "--dataset-path", "c.hdf5", "--out", "parts"]
        limit, words = 300_000, "while splitting into parts: the split was dropped, nothing written there"
    before = {p.name for p in tmp_path.iterdir()}
    out = subprocess.run(
        [sys.executable, "-c", RUN, *argv], cwd=tmp_path, capture_output=True, text=True, preexec_fn=limited(limit)
    )
    errors = [line for line in out.stderr.splitlines() if "windows read" not in line]
    assert out.returncode == 1 and len(errors) == 1 and words in errors[0], out.stderr
    left = {str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*") if p.name not in before and p.is_file()}
    assert not left, left


def test_a_killed_data_parallel_train_leaves_no_process(tmp_path):
    """``train --gpus 2 --device cpu`` runs torchrun and two gloo ranks; SIGKILL of the command ends them all (torchrun
    gets SIGTERM from the kernel when its parent dies, and ends its ranks)."""
    make_dataset(tmp_path / "d.hdf5")
    run = newton_lab(
        "train",
        "--dataset-path",
        "d.hdf5",
        "--preset",
        "cpu",
        "--max-steps",
        "100000",
        "--gpus",
        "2",
        "--device",
        "cpu",
        "--output-dir",
        "pol",
        cwd=tmp_path,
    )
    wait_for(lambda: len(descendants(run.pid)) >= 3 or run.poll() is not None, "torchrun and its two ranks")
    assert run.poll() is None, run.communicate()
    started = descendants(run.pid)
    run.kill()
    run.wait(timeout=60)  # not communicate(): a rank left alive would hold the pipes open, and it would never return
    try:
        wait_for(lambda: not any(alive(p) for p in started), "torchrun and its ranks ending", limit_s=120)
    finally:
        for pid in started:
            if alive(pid):
                os.kill(pid, signal.SIGKILL)


def test_a_killed_collect_leaves_no_writer_process(tmp_path):
    """SIGKILL of ``collect --writer process``: the writer process reads the end of its pipe, writes what it was
    given and exits; the dataset stays readable."""
    from newton_lab.datasets import read_dataset_info

    path = tmp_path / "r.zarr"
    run = newton_lab(
        "collect",
        "--task",
        "GalbotG1-Reach-v0",
        "--episodes",
        "100000",
        "--num-envs",
        "2",
        "--max-steps",
        "5",
        "--cameras",
        "none",
        "--no-progress",
        "--writer",
        "process",
        "--dataset-path",
        str(path),
        cwd=tmp_path,
    )

    def demos() -> int:
        try:
            return read_dataset_info(path)["num_demos"]
        except (OSError, ValueError):
            return 0

    wait_for(lambda: demos() >= 2 or run.poll() is not None, "two episodes written")
    assert run.poll() is None, run.communicate()
    writers = descendants(run.pid)
    assert writers
    run.kill()
    run.communicate()
    wait_for(lambda: not any(alive(p) for p in writers), "the writer process ending", limit_s=120)
    assert read_dataset_info(path)["num_demos"] >= 2


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_ctrl_c_during_split_drops_it_in_one_line(tmp_path, signum):
    """Ctrl-C (or SIGTERM) while the phase writers write: the writers are stopped, the stage removed, no --out folder
    appears, and one line says so (exit status 130 / 143)."""
    # a split that ends before the signal lands is no interruption: a larger one then (a loaded CI machine once
    # finished 6,400 demos' split before the signal)
    for demos in (1600, 6400, 25600):
        data = tmp_path / f"c{demos}.hdf5"
        make_splittable(data, demos=demos, steps=60)
        split, stage, writers = split_caught_writing(tmp_path, data.name)
        split.send_signal(signum)
        _, err = split.communicate(timeout=900)
        if split.returncode != 0:
            break
        shutil.rmtree(tmp_path / "parts")  # it finished first: try again with more to write
    lines = [line for line in err.splitlines() if line.strip()]
    assert split.returncode == 128 + signum and len(lines) == 1, err
    assert "newton-lab split: interrupted: the split into parts was dropped, nothing written there" in lines[0]
    assert not (tmp_path / "parts").exists() and not stage.exists()
    wait_for(lambda: not any(alive(w) for w in writers), "the phase writers ending", limit_s=120)


def test_ctrl_c_during_mimic_keeps_every_generated_demo_in_one_line(tmp_path):
    """Mimic generates through collect: Ctrl-C keeps every finished demo in the output and says how many."""
    from newton_lab.datasets import read_dataset_info

    source = tmp_path / "src.hdf5"
    out = subprocess.run(
        [
            sys.executable,
            "-c",
            RUN,
            "collect",
            "--task",
            "GalbotG1-PickCube-v0",
            "--num-envs",
            "2",
            "--episodes",
            "2",
            "--max-steps",
            "300",
            "--randomize",
            "--no-progress",
            "--cameras",
            "none",
            "--dataset-path",
            str(source),
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert out.returncode == 0, out.stderr
    path = tmp_path / "mimic.hdf5"

    def demos() -> int:
        try:
            return read_dataset_info(path)["num_demos"]
        except (OSError, ValueError):
            return 0

    run = newton_lab(
        "mimic",
        "--dataset-path",
        str(source),
        "--output-path",
        str(path),
        "--episodes",
        "10000",
        "--num-envs",
        "2",
        "--no-progress",
        cwd=tmp_path,
    )
    wait_for(lambda: demos() >= 1 or run.poll() is not None, "a generated demo written", limit_s=900)
    run.send_signal(signal.SIGINT)
    _, err = run.communicate(timeout=900)
    lines = [line for line in err.splitlines() if line.strip()]
    assert run.returncode == 130 and len(lines) == 1, err
    kept = read_dataset_info(path)["num_demos"]
    assert f"newton-lab mimic: interrupted: {kept} finished episode" in lines[0] and str(path) in lines[0]


def test_the_process_walk_survives_processes_that_end_while_it_reads_them():
    """The watchdog's /proc walk on a pid that is gone, and on a tree whose members keep ending while it is walked,
    gives what it could read rather than an error (a child ending between two reads once failed the walk)."""
    assert children(2**22 + 7) == [] and descendants(2**22 + 7) == []
    shell = subprocess.Popen(["sh", "-c", "for i in $(seq 200); do (sleep 0.01 &) ; done; wait"])
    try:
        while shell.poll() is None:
            assert all(isinstance(p, int) for p in descendants(os.getpid()))
    finally:
        shell.wait()
