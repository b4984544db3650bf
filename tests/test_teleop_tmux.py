"""``newton-lab teleop --device keyboard`` as an operator meets it: in a terminal (tmux), keys sent with
``send-keys``. A scripted key sequence picks the cube and releases it on the block, ``done`` ends the episode,
``keep`` keeps it; a second session answers ``drop`` and a third ends the input (Ctrl-D): the dataset still
holds the one successful demo."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import missing_tool

pytestmark = pytest.mark.slow
if shutil.which("tmux") is None:
    missing_tool("tmux is not installed (apt-get install tmux)", module=True)

STATUS = re.compile(r"step +(\d+) \| tcp ([+-]\d+\.\d+) ([+-]\d+\.\d+) ([+-]\d+\.\d+) m")
CLI = str(Path(sys.executable).with_name("newton-lab"))
CUBE_GRASP = (0.20, -0.07, -0.19)
"""Jog from the PickCube start TCP (-0.50, 0.25, 0.35) to the grasp pose above the cube's centre [m]."""


class Tmux:
    """One detached tmux session on a private server socket."""

    def __init__(self, name: str, command: list[str], cwd: Path):
        self.base = ["tmux", "-L", f"newton_lab_{name}"]
        subprocess.run(
            self.base
            + [
                "new-session",
                "-d",
                "-s",
                name,
                "-x",
                "200",
                "-y",
                "50",
                "-c",
                str(cwd),
                " ".join(command) + "; sleep 600",
            ],
            check=True,
        )
        self.target = name

    def keys(self, *keys: str, literal: bool = True) -> None:
        for k in keys:
            subprocess.run(self.base + ["send-keys", "-t", self.target] + (["-l"] if literal else []) + [k], check=True)

    def screen(self) -> str:
        return subprocess.run(
            self.base + ["capture-pane", "-p", "-J", "-S", "-200", "-t", self.target],
            capture_output=True,
            text=True,
            check=True,
        ).stdout

    def wait_for(self, pred, what: str, timeout: float = 600.0):
        t0 = time.time()
        while time.time() - t0 < timeout:
            screen = self.screen()
            hit = pred(screen)
            if hit:
                return hit
            time.sleep(0.3)
        raise AssertionError(f"timed out waiting for {what}; screen:\n{self.screen()[-3000:]}")

    def kill(self) -> None:
        subprocess.run(self.base + ["kill-server"], capture_output=True)


def _status(screen: str):
    hits = STATUS.findall(screen)
    return (int(hits[-1][0]), [float(v) for v in hits[-1][1:]]) if hits else None


def _at(tmux: Tmux, target, what: str, tol: float = 0.012):
    def pred(screen):
        st = _status(screen)
        return st if st and max(abs(a - b) for a, b in zip(st[1], target)) < tol else None

    return tmux.wait_for(pred, what)


def _steps(tmux: Tmux, n: int) -> None:
    s0 = _status(tmux.screen())[0]
    tmux.wait_for(lambda s: (_status(s) or (0,))[0] >= s0 + n, f"{n} more steps")


def _session(tmp_path: Path, name: str, dataset: Path) -> Tmux:
    # paced at the control rate (20 Hz), as an operator meets it: unpaced, a slow machine could run the episode
    # into its step limit (6000 steps) between two of the script's keys
    return Tmux(
        name, [CLI, "teleop", "--device", "keyboard", "--cameras", "none", "--dataset-path", str(dataset)], tmp_path
    )


def test_keyboard_teleop_in_a_terminal_keep_drop_and_end_of_input(tmp_path):
    from newton_lab.datasets import DatasetRef
    from newton_lab.datasets.storage import list_demos, read_dataset_info, read_episode

    dataset = tmp_path / "teleop.hdf5"
    tmux = _session(tmp_path, f"keep{id(tmp_path)}", dataset)
    try:
        _, (x, y, z) = tmux.wait_for(_status, "the first status line")  # compile + env build
        assert "done  -> end the episode" in tmux.screen()  # the key map is shown
        dx, dy, dz = CUBE_GRASP
        tmux.keys("i" * round(dx / 0.01) + "l" * round(-dy / 0.01))
        _at(tmux, (x + dx, y + dy, z), "the TCP above the cube")
        tmux.keys("f" * round(-dz / 0.01))
        _at(tmux, (x + dx, y + dy, z + dz), "the TCP at the cube")
        tmux.keys(" ")  # close
        _steps(tmux, 40)
        tmux.keys("r" * 10)
        _at(tmux, (x + dx, y + dy, z + dz + 0.10), "the cube lifted")
        tmux.keys("l" * 26)  # to the block (y -0.08)
        _at(tmux, (x + dx, y + dy - 0.26, z + dz + 0.10), "the cube above the block")
        tmux.keys("f" * 8)
        _at(tmux, (x + dx, y + dy - 0.26, z + dz + 0.02), "the cube on the block")
        tmux.keys(" ")  # open
        tmux.wait_for(lambda s: "success yes" in s, "success")
        tmux.keys("done")
        tmux.keys("Enter", literal=False)
        tmux.wait_for(lambda s: "keep / drop / exit?" in s, "the review prompt")
        tmux.keys("keep")
        tmux.keys("Enter", literal=False)
        tmux.wait_for(lambda s: "kept demo [0]" in s, "kept")
        tmux.wait_for(lambda s: "kept demo" in s and _status(s.split("kept demo")[-1]), "the next episode")
        tmux.keys("done")
        tmux.keys("Enter", literal=False)
        tmux.wait_for(lambda s: s.count("keep / drop / exit?") >= 2, "the second review prompt")
        tmux.keys("exit")
        tmux.keys("Enter", literal=False)
        screen = tmux.wait_for(lambda s: "latency device frame -> action applied" in s and s, "the session's end")
    finally:
        tmux.kill()
    assert "episode 1:" in screen and "success yes, ended by user_exit" in screen
    assert list_demos(dataset) == [0]
    assert read_dataset_info(dataset)["num_demos"] == 1
    assert DatasetRef.open(dataset).provenance[-1].operation == "drop"  # exit drops the episode under review
    attrs = read_episode(dataset, 0)["attrs"]
    assert attrs["success"] is True and attrs["termination_reason"] == "user_exit"

    for answer, name in (("drop", "drop"), (None, "eof")):  # a dropped episode and an ended input add nothing
        tmux = _session(tmp_path, f"{name}{id(tmp_path)}", dataset)
        try:
            tmux.wait_for(_status, "the first status line")
            tmux.keys("iii")
            tmux.keys("done")
            tmux.keys("Enter", literal=False)
            tmux.wait_for(lambda s: "keep / drop / exit?" in s, "the review prompt")
            if answer is None:
                tmux.keys("C-d", literal=False)
            else:
                tmux.keys(answer)
                tmux.keys("Enter", literal=False)
                tmux.wait_for(
                    lambda s: "dropped demo" in s and _status(s.split("dropped demo")[-1]), "the next episode"
                )
                tmux.keys("done")  # then end the input at the next prompt
                tmux.keys("Enter", literal=False)
                tmux.wait_for(lambda s: s.count("keep / drop / exit?") >= 2, "the second review prompt")
                tmux.keys("C-d", literal=False)
            tmux.wait_for(lambda s: "latency device frame -> action applied" in s, "the session's end")
        finally:
            tmux.kill()
        assert list_demos(dataset) == [0], name
