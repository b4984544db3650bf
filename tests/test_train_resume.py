"""Resumable training: an interrupted run continued from ``resume.pt`` ends bitwise where an uninterrupted run of
the same seed ends (CPU), a kill before the first checkpoint leaves nothing behind, bad resume files fail in one
line. Real training of a tiny policy on a tiny dataset; one torch thread (bitwise results need the same one)."""

from __future__ import annotations

import json
import os
import pty
import re
import signal
import subprocess
import sys
import termios
import time
from pathlib import Path

import pytest
import torch
from newton_lab.flows.stages import train_stage
from test_policy import TINY, write_dataset

from newton_lab.cli import main
from newton_lab.commands import TrainArgs
from newton_lab.policies import DiffusionPolicy, train
from newton_lab.policies.diffusion import PRESETS
from newton_lab.policies.train_loop import Checkpointer

ROOT = Path(__file__).resolve().parents[1]
CFG = dict(TINY, lr=1e-2, warmup_steps=3, batch_size=8, epochs=100, max_steps=14, seed=0)
"""40 windows, batch 8: 5 steps per epoch; 14 steps end mid-epoch 3."""
ONE_THREAD = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


class Killed(Exception):
    """Stands for a kill right after a resume file was written."""


@pytest.fixture(scope="session", autouse=True)
def _quiet_warp():
    """Overrides the conftest fixture: these tests train only."""
    yield


@pytest.fixture(scope="module", autouse=True)
def _one_thread():
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    return write_dataset(tmp_path_factory.mktemp("resume_data") / "demos.hdf5")


@pytest.fixture(scope="module")
def reference(dataset, tmp_path_factory) -> Path:
    """The uninterrupted run."""
    return train(dataset, {**CFG, "output_dir": str(tmp_path_factory.mktemp("uninterrupted"))})


def kill_after_saving_at(monkeypatch, steps: tuple[int, ...]) -> None:
    real = Checkpointer.save

    def save(self, run):
        real(self, run)
        if run.step in steps:
            raise Killed(run.step)

    monkeypatch.setattr(Checkpointer, "save", save)


def assert_same_run(path: Path, reference: Path) -> None:
    got, want = torch.load(path, weights_only=True), torch.load(reference, weights_only=True)
    assert got["info"]["training"]["steps"] == want["info"]["training"]["steps"]
    assert got["weights"].keys() == want["weights"].keys()
    unequal = [k for k in want["weights"] if not torch.equal(got["weights"][k], want["weights"][k])]
    assert not unequal, f"{len(unequal)} of {len(want['weights'])} tensors differ, e.g. {unequal[:3]}"
    logs = [json.loads((p.parent / "train_log.json").read_text())["epoch_log"] for p in (path, reference)]
    assert [e["loss"] for e in logs[0]] == [e["loss"] for e in logs[1]]


def test_interrupted_three_times_ends_bitwise_where_the_uninterrupted_run_ends(
    dataset, reference, tmp_path, monkeypatch
):
    # killed mid-epoch 1 (step 4), mid-epoch 2 (step 8) and at the end of epoch 2 (step 10); the checkpoint
    # interval may change between sessions
    kill_after_saving_at(monkeypatch, (4, 8, 10))
    out = tmp_path / "run"
    for every, resume, killed_at in ((4, False, 4), (4, True, 8), (5, True, 10)):
        with pytest.raises(Killed, match=str(killed_at)):
            train(dataset, {**CFG, "output_dir": str(out), "checkpoint_every_steps": every}, resume=resume)
        assert sorted(p.name for p in out.iterdir()) == ["resume.pt"]  # no temporary file, no checkpoint yet
    path = train(dataset, {**CFG, "output_dir": str(out), "checkpoint_every_steps": 5}, resume=True)
    assert_same_run(path, reference)
    assert sorted(p.name for p in out.iterdir()) == ["checkpoint.pt", "train_log.json"]  # resume.pt served
    policy = DiffusionPolicy.load(path)  # the final checkpoint is the usual one
    assert policy.info["training"]["resumed_at_steps"] == [4, 8, 10]


def test_sigkill_after_a_checkpoint_then_cli_resume(dataset, tmp_path, capsys):
    out = tmp_path / "cli"
    flags = [
        "train",
        "--dataset-path",
        str(dataset),
        "--output-dir",
        str(out),
        "--preset",
        "cpu",
        "--max-steps",
        "20",
        "--batch-size",
        "8",
        "--checkpoint-every-steps",
        "5",
        "--time-budget-s",
        "600",
    ]
    proc = subprocess.Popen(
        [sys.executable, "-m", "newton_lab.cli", *flags],
        cwd=ROOT,
        env=ONE_THREAD,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + 600  # a safety stop only: a loaded 2-core CI machine once took over 60 s
    while not (out / "resume.pt").exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert proc.returncode == -signal.SIGKILL, "the run ended before it could be killed"
    assert not (out / "checkpoint.pt").exists()
    step = torch.load(out / "resume.pt", weights_only=True)["progress"]["step"]
    assert 5 <= step < 20

    assert main([*flags, "--resume"]) == 0
    path = Path(json.loads(capsys.readouterr().out.strip().splitlines()[-1])["checkpoint"])
    assert path == out / "checkpoint.pt" and not (out / "resume.pt").exists()
    ref_args = TrainArgs(
        dataset_path=[str(dataset)],
        output_dir=str(tmp_path / "ref"),
        preset="cpu",
        max_steps=20,
        batch_size=8,
        checkpoint_every_steps=5,
        time_budget_s=600,
    )
    assert_same_run(path, train(ref_args.datasets(), {**ref_args.train_cfg(PRESETS), "progress": False}))
    assert DiffusionPolicy.load(path).info["training"]["resumed_at_steps"] == [step]


def test_kill_before_the_first_checkpoint_leaves_nothing(dataset, tmp_path):
    out = tmp_path / "early"
    script = (
        f"from newton_lab.policies import train; train({str(dataset)!r}, "
        f"{{**{dict(CFG, progress=True)!r}, 'max_steps': 10**6, 'checkpoint_every_steps': 10**6, "
        f"'checkpoint_every_s': None, 'output_dir': {str(out)!r}}})"
    )
    tty, term = pty.openpty()  # the progress bar shows on a terminal only (one 120 columns wide)
    termios.tcsetwinsize(term, (24, 120))
    proc = subprocess.Popen(
        [sys.executable, "-c", script], cwd=ROOT, env=ONE_THREAD, stdout=subprocess.DEVNULL, stderr=term
    )
    os.close(term)
    seen, deadline = b"", time.monotonic() + 60
    while proc.poll() is None and time.monotonic() < deadline:  # until the progress bar shows 5 steps done
        try:
            seen += os.read(tty, 4096)
        except OSError:  # the child closed the terminal
            break
        if any(int(n) >= 5 for n in re.findall(rb"\| *(\d+)/\d+ \[", seen)):
            break
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    os.close(tty)
    assert proc.returncode == -signal.SIGKILL, seen.decode(errors="replace")[-300:]
    assert not out.exists() or not any(out.iterdir())  # the folder is made by the first checkpoint
    with pytest.raises(FileNotFoundError, match="no resume file .*without --resume") as err:
        train(dataset, {**CFG, "output_dir": str(out)}, resume=True)
    assert "\n" not in str(err.value)


def test_bad_resume_files_fail_in_one_line(dataset, tmp_path, monkeypatch, capsys):
    kill_after_saving_at(monkeypatch, (4,))
    out = tmp_path / "bad"
    with pytest.raises(Killed):
        train(dataset, {**CFG, "output_dir": str(out), "checkpoint_every_steps": 4})
    resume = out / "resume.pt"
    with pytest.raises(FileExistsError, match="holds an interrupted run; continue it with --resume"):
        train(dataset, {**CFG, "output_dir": str(out)})  # a fresh run would overwrite it
    with pytest.raises(ValueError, match=r"other settings: lr=0.01 \(now 0.02\); resume with the same"):
        train(dataset, {**CFG, "output_dir": str(out), "lr": 2e-2}, resume=True)

    resume.write_bytes(resume.read_bytes()[: resume.stat().st_size // 2])  # torn, as no atomic write leaves it
    with pytest.raises(ValueError, match="resume.pt is damaged .*delete it and train without --resume") as err:
        train(dataset, {**CFG, "output_dir": str(out)}, resume=True)
    assert "\n" not in str(err.value)
    code = main(["train", "--dataset-path", str(dataset), "--output-dir", str(out), "--resume"])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "is damaged" in lines[0]
    code = main(["train", "--dataset-path", str(dataset), "--output-dir", str(tmp_path / "none"), "--resume"])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "no resume file" in lines[0]


def test_pipeline_train_stage_resumes_on_a_rerun(dataset, reference, tmp_path, monkeypatch):
    art = {"sha256": "0" * 64, "path": str(dataset)}
    cfg = {**CFG, "checkpoint_every_steps": 6}
    kill_after_saving_at(monkeypatch, (6,))
    with pytest.raises(Killed):
        train_stage(dataset=art, train_cfg=cfg, out_dir=str(tmp_path))
    (tmp_path / "policy" / "stray.tmp").write_text("leftover")  # other leftovers of the run are removed
    monkeypatch.undo()
    done = train_stage(dataset=art, train_cfg=cfg, out_dir=str(tmp_path))
    assert sorted(p.name for p in (tmp_path / "policy").iterdir()) == ["checkpoint.pt", "train_log.json"]
    assert_same_run(Path(done["path"]), reference)
    assert DiffusionPolicy.load(done["path"]).info["training"]["resumed_at_steps"] == [6]
