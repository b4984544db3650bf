"""``newton-lab yolo-export``: a YOLO-seg dataset rendered on CPU Warp (96x72 here), checked the way Ultralytics
reads it (Ultralytics itself needs torchvision, which has no usable CPU build beside torch 2.13), and the polygon
tracer on masks of known shape."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image, ImageDraw

from newton_lab.datasets.yolo import SPLITS, assign_splits, color_segmentation, mask_polygon

NAMES = ["red_cube", "blue_cuboid", "yellow_cylinder", "green_cylinder"]


def cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "newton_lab.cli", "yolo-export", *args],
        capture_output=True,
        text=True,
        timeout=900,
        check=False,
    )


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("yolo") / "ds"
    proc = cli(
        "--num-images",
        "50",
        "--num-envs",
        "2",
        "--resolution",
        "96",
        "72",
        "--randomize",
        "--device",
        "cpu",
        "--preview",
        "2",
        "--output-dir",
        str(out),
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    return out


def polygon_area(p: np.ndarray) -> float:
    return 0.5 * abs(float(np.dot(p[:, 0], np.roll(p[:, 1], -1)) - np.dot(p[:, 1], np.roll(p[:, 0], -1))))


@pytest.mark.slow
def test_fifty_images_load_as_ultralytics_reads_them(exported):
    spec = yaml.safe_load((exported / "data.yaml").read_text())
    assert spec["names"] == dict(enumerate(NAMES)) and spec["path"] == str(exported.resolve())
    seen = set()
    stems = {s: sorted(p.stem for p in (exported / "images" / s).glob("*.png")) for s in SPLITS}
    assert {s: len(v) for s, v in stems.items()} == {"train": 35, "val": 10, "test": 5}
    for split in SPLITS:
        assert stems[split] == sorted(p.stem for p in (exported / "labels" / split).glob("*.txt"))
        for stem in stems[split]:
            w, h = Image.open(exported / "images" / split / f"{stem}.png").size
            assert (w, h) == (96, 72)
            for line in (exported / "labels" / split / f"{stem}.txt").read_text().splitlines():
                cls, *xy = line.split()
                assert int(cls) in spec["names"] and len(xy) >= 6 and len(xy) % 2 == 0
                poly = np.array(xy, float).reshape(-1, 2)
                assert poly.min() >= 0 and poly.max() <= 1  # inside the image
                assert polygon_area(poly * [w, h]) > 1.0
                seen.add(int(cls))
    assert seen == set(range(4))  # every class of data.yaml occurs
    previews = sorted((exported / "preview").glob("*.png"))
    assert len(previews) == 2 and Image.open(previews[0]).size == (3 * 96, 3 * 72)


def polygon_iou(rgb: np.ndarray, cls: int, poly: np.ndarray, colors: np.ndarray) -> tuple[float, int]:
    """(IoU of a normalised label polygon, filled, with the pixels of class ``cls``'s colour in the frame, how many
    pixels have that colour)."""
    h, w = rgb.shape[:2]
    fill = Image.new("1", (w, h))
    ImageDraw.Draw(fill).polygon([(x * w - 0.5, y * h - 0.5) for x, y in poly], fill=1)  # pixel edges -> centres
    filled, seen = np.array(fill, bool), color_segmentation(rgb, colors) == cls
    return float((filled & seen).sum() / max(1, (filled | seen).sum())), int(seen.sum())


@pytest.mark.slow
def test_label_polygons_outline_their_objects_in_the_images(exported):
    """Each label's polygon lies on its object: filled, it overlaps the pixels of the object's colour in its image
    (found by hue, as ``--mask-source rgb-color`` finds them) with IoU 0.7 on average, 0.5 or more for nine in
    ten (mirrored polygons: 0.08 on average). Labels whose frame shows far more of the object's hue than the
    polygon covers (the randomised scene paints a large surface in it) are not judged; most are."""
    from newton_lab.tasks.sort_to_shelf.objects import OBJECTS

    colors = np.array([OBJECTS[n].color for n in NAMES]) * 255.0
    ious, labels = [], 0
    for label in sorted((exported / "labels").glob("*/*.txt")):
        rgb = np.array(Image.open(exported / "images" / label.parent.name / f"{label.stem}.png").convert("RGB"))
        h, w = rgb.shape[:2]
        for line in label.read_text().splitlines():
            cls, *xy = line.split()
            poly = np.array(xy, float).reshape(-1, 2)
            iou, seen = polygon_iou(rgb, int(cls), poly, colors)
            labels += 1
            if seen <= 2 * polygon_area(poly * [w, h]):
                ious.append(iou)
    assert len(ious) >= 0.75 * labels and labels >= 50, (len(ious), labels)
    assert np.mean(ious) >= 0.7 and np.mean(np.array(ious) >= 0.5) >= 0.9, (np.mean(ious), sorted(ious)[:10])


def test_polygons_trace_masks_of_known_shape():
    """A rectangle, a disc with a hole and a region touching the border: the polygon's area is the mask's within
    a few percent, its vertices lie on the image, and its centroid lies inside the mask."""
    h, w = 72, 96
    y, x = np.mgrid[0:h, 0:w]
    rect = (x >= 10) & (x < 40) & (y >= 20) & (y < 35)
    disc = ((x - 60) ** 2 + (y - 40) ** 2 <= 15**2) & ((x - 60) ** 2 + (y - 40) ** 2 > 4**2)
    edge = (x < 8) & (y < 30)
    for mask in (rect, disc, edge):
        poly = mask_polygon(mask)
        assert poly is not None and len(poly) >= 4
        assert poly.min() >= 0 and (poly <= [w, h]).all()
        hole = np.pi * 4**2 if mask is disc else 0.0
        assert abs(polygon_area(poly) - hole - mask.sum()) < 0.06 * mask.sum()
        cx, cy = poly.mean(axis=0)
        assert mask[int(cy), int(cx)] or mask is disc  # the disc's centroid is its hole
    assert mask_polygon(rect & (x < 12) & (y < 22)) is None  # 4 px: below MIN_AREA_PX
    assert assign_splits(10, [0.7, 0.2, 0.1], seed=0).count("train") == 7


@pytest.mark.parametrize(
    "args, words",
    [
        (["--split", "0.5", "0.2", "0.1"], "--split takes three fractions >= 0 summing to 1"),
        (["--task", "GalbotG1-PickCube-v0"], "use a SortToShelf task"),
        (["--resolution", "0", "72"], "--resolution takes width and height"),
        (["--num-images", "0"], "--num-images must be"),
        (["--mask-source", "depth"], "--mask-source 'depth' is unknown; use one of segmentation, rgb-color"),
    ],
)
def test_bad_input_is_one_line(tmp_path, args, words):
    proc = cli(*args, "--output-dir", str(tmp_path / "ds"))
    assert proc.returncode == 2 and words in proc.stderr and len(proc.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "ds").exists() or not any((tmp_path / "ds").iterdir())


def test_a_non_empty_output_dir_is_refused(tmp_path):
    (tmp_path / "ds").mkdir()
    (tmp_path / "ds" / "keep.txt").write_text("mine")
    proc = cli("--num-images", "1", "--output-dir", str(tmp_path / "ds"), "--device", "cpu")
    assert proc.returncode == 2 and "exists and is not empty" in proc.stderr
    assert [p.name for p in (tmp_path / "ds").iterdir()] == ["keep.txt"]


def test_rgb_color_masks_match_the_segmentation():
    """--mask-source rgb-color: with the task's own colours, the masks found from the RGB frame by hue are the
    segmentation's for every visible sorting object (a real render, 96x72)."""
    from newton_lab.envs import make_env

    env = make_env(
        "GalbotG1-SortToShelf-Pick-v0",
        num_envs=1,
        device="cpu",
        seed=1,
        cameras={"front_head": {"resolution": (96, 72), "data": ("rgb", "segmentation")}},
    )
    images = env.render()
    rgb, seg = images["front_head_rgb"][0].cpu().numpy(), images["front_head_segmentation"][0].cpu().numpy()
    names = env.sensors.cameras.segmentation_names
    ids = [names.index(n) for n in NAMES]
    colors = np.full_like(env.sensors.cameras.id_colors()[0], np.nan)
    colors[ids] = env.sensors.cameras.id_colors()[0][ids]
    found = color_segmentation(rgb, colors)
    visible = [i for i in ids if (seg == i).sum() >= 12]
    assert len(visible) >= 3
    for i in visible:
        iou = ((seg == i) & (found == i)).sum() / ((seg == i) | (found == i)).sum()
        assert iou > 0.9, (names[i], iou)
