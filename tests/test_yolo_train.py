"""``newton-lab yolo-train`` / ``yolo-predict``: the parts that need no Ultralytics (it needs torchvision, which has no
usable CPU build beside torch 2.13): the data specs written for a run, the overlay drawing, the polars-free
results reader, and the refusals (one line, exit 2, before Warp is imported, nothing written). The training and
inference themselves run on a GPU host with Ultralytics installed: docs/data.md#yolo-seg."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import yaml

from newton_lab.commands.perception import YoloPredictArgs, YoloTrainArgs, check_yolo_predict, check_yolo_train
from newton_lab.datasets.yolo import (
    OVERLAY_COLORS,
    YoloWriter,
    default_imgsz,
    mask_iou,
    montage,
    overlay,
    read_export,
    training_specs,
)
from newton_lab.perception.train import results_csv, seg_metrics

NAMES = ["red_cube", "blue_cuboid", "yellow_cylinder", "green_cylinder"]
SQUARE = np.array([[0.1, 0.1], [0.4, 0.1], [0.4, 0.5], [0.1, 0.5]])


def export(root: Path, splits: list[str], names=NAMES, size=(96, 72)) -> Path:
    """A small yolo-export folder written by the exporter's own writer (blank frames, one square label each)."""
    writer = YoloWriter(root, names, splits)
    for k in range(len(splits)):
        writer.add(np.zeros((size[1], size[0], 3), np.uint8), [(k % len(names), SQUARE)])
    writer.close()
    return root


def test_training_specs_train_on_the_export_and_score_on_every_heldout_image(tmp_path):
    ds = read_export(export(tmp_path / "ds", ["train"] * 5 + ["val"] * 2 + ["test"]))
    held = read_export(export(tmp_path / "held", ["val"] * 3 + ["test"] * 2))
    assert ds["images"] == {"train": 5, "val": 2, "test": 1} and ds["size"] == (96, 72)
    assert ds["names"] == dict(enumerate(NAMES))
    train, evaluate = training_specs(ds, held, tmp_path / "run")
    root, hroot = (tmp_path / "ds").resolve(), (tmp_path / "held").resolve()
    assert train == {
        "path": str((tmp_path / "run").resolve()),
        "train": [str(root / "images/train")],
        "val": [str(root / "images/val")],
        "names": dict(enumerate(NAMES)),
    }
    assert evaluate["val"] == [str(hroot / "images/val"), str(hroot / "images/test")]  # empty train split left out
    assert evaluate["train"] == train["train"] and evaluate["names"] == train["names"]
    for spec in (train, evaluate):  # Ultralytics finds each image's labels by replacing /images/ with /labels/
        for folder in spec["train"] + spec["val"]:
            for png in Path(folder).glob("*.png"):
                assert Path(str(png).replace("/images/", "/labels/")).with_suffix(".txt").is_file()
    _, own = training_specs(ds, None, tmp_path / "run")
    assert own["val"] == [str(root / "images/val")]  # no held-out export: the val split is scored
    assert yaml.safe_load(yaml.safe_dump(train)) == train
    assert default_imgsz((298, 224)) == 320 and default_imgsz((96, 72)) == 96 and default_imgsz((97, 72)) == 128


def test_read_export_refuses_folders_that_are_not_exports(tmp_path):
    with pytest.raises(FileNotFoundError, match="--heldout .*: no data.yaml there"):
        read_export(tmp_path, "--heldout")
    (tmp_path / "data.yaml").write_text("names: {0: a}\n")
    with pytest.raises(ValueError, match="no images under"):
        read_export(tmp_path)
    (tmp_path / "data.yaml").write_text("just text\n")
    with pytest.raises(ValueError, match="data.yaml has no names list"):
        read_export(tmp_path)


def test_overlay_tints_outlines_and_keeps_the_rest():
    h, w = 24, 32
    rgb = np.full((h, w, 3), 100, np.uint8)
    a = np.zeros((h, w), bool)
    a[4:12, 5:15] = True
    b = np.zeros((h, w), bool)
    b[14:20, 20:30] = True
    image = overlay(rgb, np.stack([a, b]), [0, 2], [0.9, 0.5], NAMES, scale=2, alpha=0.5)
    assert image.size == (2 * w, 2 * h)
    px = np.array(image)[::2, ::2]  # back to one sample per frame pixel
    assert (px[8, 10] == (0.5 * 100 + 0.5 * np.array(OVERLAY_COLORS[0])).round()).all()  # tinted inside
    assert (px[4, 10] == OVERLAY_COLORS[0]).all() and (px[17, 20] == OVERLAY_COLORS[2]).all()  # outlined
    assert (px[22:, :18] == 100).all()  # far from both masks and their labels
    empty = overlay(rgb, np.zeros((0, h, w), bool), [], [], NAMES)
    assert (np.array(empty)[::3, ::3] == rgb).all()
    sheet = montage([image] * 5, cols=4)
    assert sheet.size == (4 * 2 * w, 2 * 2 * h)
    assert mask_iou(a, a) == 1.0 and mask_iou(a, b) == 0.0 and mask_iou(a & False, b & False) == 0.0
    assert mask_iou(a, a[:, ::-1] | a) == pytest.approx(a.sum() / (a | a[:, ::-1]).sum())


def test_results_csv_without_polars(tmp_path):
    (tmp_path / "results.csv").write_text("epoch,train/box_loss,metrics/mAP50(M)\n1,2.5,0.1\n2,1.5,0.4\n")
    got = results_csv(SimpleNamespace(csv=tmp_path / "results.csv"))
    assert got == {"epoch": [1.0, 2.0], "train/box_loss": [2.5, 1.5], "metrics/mAP50(M)": [0.1, 0.4]}
    assert results_csv(SimpleNamespace(csv=tmp_path / "missing.csv")) == {}


def test_seg_metrics_reads_mask_and_box_map():
    m = SimpleNamespace(
        seg=SimpleNamespace(map50=0.95, map=0.71, ap50=np.array([0.9, 1.0])),
        box=SimpleNamespace(map50=0.97, map=0.8),
        ap_class_index=np.array([1, 3]),
    )
    assert seg_metrics(m, dict(enumerate(NAMES))) == {
        "mask_map50": 0.95,
        "mask_map50_95": 0.71,
        "box_map50": 0.97,
        "box_map50_95": 0.8,
        "mask_ap50_per_class": {"blue_cuboid": 0.9, "green_cylinder": 1.0},
    }


def test_missing_ultralytics_is_refused_after_the_arguments(tmp_path, monkeypatch):
    ds = export(tmp_path / "ds", ["train", "val"])
    monkeypatch.setattr(importlib.util, "find_spec", lambda name: None)
    with pytest.raises(ValueError, match=r"ultralytics is not installed here; pip install ultralytics==8\.4\.190"):
        check_yolo_train(YoloTrainArgs(dataset=str(ds), device="cpu", output_dir=str(tmp_path / "run")))
    with pytest.raises(ValueError, match="ultralytics is not installed here"):
        check_yolo_predict(YoloPredictArgs(weights=str(ds / "data.yaml"), output_dir=str(tmp_path / "p")))
    assert not (tmp_path / "run").exists() and not (tmp_path / "p").exists()


CHECK = """
import sys
from newton_lab.cli import main
code = main(sys.argv[1:])
assert "warp" not in sys.modules and "torch" not in sys.modules and "ultralytics" not in sys.modules
sys.exit(code)
"""


def cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", CHECK, *args], capture_output=True, text=True, timeout=60, check=False)


@pytest.fixture(scope="module")
def exports(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("exports")
    export(root / "ds", ["train"] * 3 + ["val"])
    export(root / "only_val", ["val"] * 2)
    export(root / "other_names", ["val"], names=["a", "b"])
    (root / "full").mkdir()
    (root / "full" / "keep.txt").write_text("mine")
    (root / "best.pt").write_bytes(b"")
    return root


@pytest.mark.parametrize(
    "args, words",
    [
        (["yolo-train", "--dataset", "{r}/nope"], "--dataset {r}/nope: no data.yaml there"),
        (["yolo-train", "--dataset", "{r}/only_val"], "no training images (images/train is empty)"),
        (["yolo-train", "--dataset", "{r}/ds", "--heldout", "{r}/other_names"], "are not the dataset's"),
        (["yolo-train", "--dataset", "{r}/ds", "--model", "yolo11n.yaml"], "use a segmentation config (*-seg.yaml"),
        (["yolo-train", "--dataset", "{r}/ds", "--model", "{r}/missing.pt"], "no such checkpoint file"),
        (["yolo-train", "--dataset", "{r}/ds", "--imgsz", "300"], "--imgsz must be a multiple of 32"),
        (["yolo-train", "--dataset", "{r}/ds", "--time-budget-s", "0"], "--time-budget-s must be > 0"),
        (["yolo-train", "--dataset", "{r}/ds", "--epochs", "0"], "--epochs must be an integer >= 1"),
        (["yolo-train", "--dataset", "{r}/ds", "--output-dir", "{r}/full"], "exists and is not empty"),
        (["yolo-predict", "--weights", "{r}/nope.pt"], "--weights {r}/nope.pt: no such file"),
        (["yolo-predict", "--weights", "{r}/best.pt", "--conf", "1.5"], "--conf must be in [0, 1)"),
        (["yolo-predict", "--weights", "{r}/best.pt", "--task", "GalbotG1-PickCube-v0"], "use a SortToShelf task"),
        (["yolo-predict", "--weights", "{r}/best.pt", "--resolution", "0", "72"], "--resolution takes width and"),
        (["yolo-predict", "--weights", "{r}/best.pt", "--capture-every", "0"], "--capture-every must be >= 1"),
        (["yolo-predict", "--weights", "{r}/best.pt", "--output-dir", "{r}/full"], "exists and is not empty"),
    ],
)
def test_bad_input_is_one_line_before_warp(exports, tmp_path, args, words):
    args = [a.format(r=exports) for a in args]
    if "--output-dir" not in args:
        args += ["--output-dir", str(tmp_path / "out")]
    proc = cli(*args, "--device", "cpu")
    assert proc.returncode == 2, proc.stderr[-1500:]
    assert words.format(r=exports) in proc.stderr and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert not (tmp_path / "out").exists()
    assert [p.name for p in (exports / "full").iterdir()] == ["keep.txt"]
