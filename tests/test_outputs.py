"""One rule for every output path (``newton_lab.datasets.files.output_paths``): missing parent folders are created, a
file where one of them should be is refused in one line (the problem and the fix), and nothing on disk is lost. Checked
on the helper itself and through the writers of a dataset, a checkpoint and an export. Fast, no physics."""

from __future__ import annotations

import os
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from test_lerobot_export import make_dataset

from newton_lab.datasets import list_demos, open_writer
from newton_lab.datasets.files.output_paths import OutputPathError, output_path
from newton_lab.datasets.lerobot import export_lerobot
from newton_lab.datasets.yolo import YoloWriter
from newton_lab.datasets.zarr import inodes as room
from newton_lab.policies.resume import write_atomic

KINDS = {"dataset": "data/pick_cube.hdf5", "checkpoint": "outputs/policy/checkpoint.pt", "export": "exports/lerobot"}


def tree(top: Path) -> dict[str, bytes | None]:
    """Every path under ``top`` with a file's bytes (None for a folder)."""
    return {str(p.relative_to(top)): (p.read_bytes() if p.is_file() else None) for p in sorted(top.rglob("*"))}


@pytest.mark.parametrize("kind", KINDS)
def test_missing_parents_are_created(tmp_path, monkeypatch, kind):
    monkeypatch.chdir(tmp_path)
    rel = Path(KINDS[kind])
    assert output_path(rel) == rel and rel.parent.is_dir() and not rel.exists()
    assert output_path(rel) == rel  # again: nothing to do
    assert output_path(f"~/{rel}", create=False) == Path.home() / rel  # ~ expanded


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("depth", ["parent", "above"])
def test_a_file_parent_is_refused_in_one_line(tmp_path, monkeypatch, kind, depth):
    monkeypatch.chdir(tmp_path)
    rel = Path(KINDS[kind])
    blocker = rel.parent if depth == "parent" else Path(rel.parts[0])
    blocker.parent.mkdir(parents=True, exist_ok=True)
    blocker.write_bytes(b"keep me")
    before = tree(tmp_path)
    for create in (True, False):
        with pytest.raises(OutputPathError) as exc:
            output_path(rel, create=create)
        msg = str(exc.value)
        assert isinstance(exc.value, ValueError) and "\n" not in msg
        assert msg.startswith(f"cannot write {rel}: ") and msg.endswith("is a file; choose another path"), msg
        where = f"its parent {blocker}" if blocker == rel.parent else f"{blocker}, on its path,"
        assert f"{where} is a file" in msg, msg
    assert tree(tmp_path) == before


def test_the_writers_follow_the_rule(tmp_path):
    """A dataset, a checkpoint and an export into missing folders are written; under a file they are refused
    with the helper's line, and the file and everything else stay as they were."""
    dataset = make_dataset(tmp_path / "new" / "data" / "demos.hdf5")
    assert len(list_demos(dataset)) == 3
    write_atomic({"step": 1}, tmp_path / "new" / "runs" / "a" / "resume.pt")
    assert (tmp_path / "new" / "runs" / "a" / "resume.pt").is_file()
    summary = export_lerobot(dataset, tmp_path / "new" / "exports" / "lerobot", video=False)
    assert Path(summary["root"]).is_dir() and summary["episodes"] == 2

    (tmp_path / "afile").write_bytes(b"keep me")
    before = tree(tmp_path)
    writes = {
        "dataset": lambda p: open_writer(p / "demos.zarr", task_id="t", env_args={}),
        "checkpoint": lambda p: write_atomic({"step": 1}, p / "run" / "resume.pt"),
        "export": lambda p: export_lerobot(dataset, p / "lerobot", video=False),
        "yolo": lambda p: YoloWriter(p / "yolo", ["cube"], ["train"]),
    }
    for write in writes.values():
        with pytest.raises(OutputPathError, match=r"^cannot write .*afile.* is a file; choose another path$"):
            write(tmp_path / "afile")
    assert tree(tmp_path) == before
    assert not any(name.startswith(".") for name in os.listdir(tmp_path))  # no partial export left


def test_room_is_checked_for_a_zarr_in_a_missing_folder(tmp_path, monkeypatch):
    """``check_room`` looks at the filesystem the missing folders will be made on (it used to skip the check)."""
    monkeypatch.setattr(room.os, "statvfs", lambda p: SimpleNamespace(f_files=1000, f_favail=3))
    with pytest.raises(ValueError, match="inodes"):
        room.check_room(tmp_path / "new" / "sub" / "demos.zarr", 10, {"actions": np.zeros((1, 8), np.float32)})
    assert list(tmp_path.iterdir()) == []
