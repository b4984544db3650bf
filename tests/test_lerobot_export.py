"""Tests for newton_lab.datasets.lerobot (LeRobot v3.0 export + structural validator). Fast, no physics."""

from __future__ import annotations

import hashlib
import json
import shutil
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa  # a dependency of the project (the export writes parquet): imported, never skipped
import pyarrow.parquet as pq
import pytest

from newton_lab.datasets import open_writer, read_episode
from newton_lab.datasets.lerobot import (
    export_lerobot,
    validate_lerobot_v3,
    writer as lr,  # the export reads episodes through it
)
from newton_lab.datasets.ref import DatasetRef
from newton_lab.datasets.zarr.settings import ZarrWriteSettings

TASK = "GalbotG1-PickCube-v0"
JOINTS = [f"joint_{i}" for i in range(7)] + ["gripper"]
OBS = {"robot_joint_pos": 34, "tcp_pose": 7, "gripper_pos": 1, "cube_pose": 7, "blue_block_pos": 3, "actions": 8}
LENGTHS = (12, 7, 9)  # demo 1 is the failed one
IMAGE = "front_head_rgb"


def _obs_terms() -> dict[str, list[int]]:
    out, col = {}, 0
    for name, width in OBS.items():
        out[name] = [col, col + width]
        col += width
    return out


ENV_ARGS = {
    "env_kwargs": {"num_envs": 2, "seed": 0},
    "newton_lab": {"sim_dt": 0.01, "decimation": 5, "action_joint_names": JOINTS, "obs_terms": _obs_terms()},
}
STATE_ORDER = [t for t in OBS if t != "actions"]  # env order (env_args JSON is stored with sorted keys)


@pytest.fixture(scope="session", autouse=True)
def _quiet_warp():
    """Overrides the conftest fixture of the same name: these tests never import warp."""
    yield


@dataclass(frozen=True)
class Ref:  # stands in for a DatasetRef
    path: Path


def make_episode(
    seed: int, steps: int, image: tuple[int, int] | None = None, noisy: bool = False, motion: int = 1
) -> dict:
    rng = np.random.default_rng(seed)
    actions = rng.standard_normal((steps, 8)).astype(np.float32)
    obs = {name: rng.standard_normal((steps, w)).astype(np.float32) for name, w in OBS.items() if name != "actions"}
    obs["cube_pose"] = rng.standard_normal((steps, 7))  # float64 on purpose: exported as float32
    obs["actions"] = actions.copy()
    if image is not None and noisy:  # incompressible frames
        obs[IMAGE] = rng.integers(0, 256, (steps, *image, 3), dtype=np.uint8)
    elif image is not None:  # a smooth moving gradient (video codecs are lossy on noise), per-episode offset
        t, y, x = np.meshgrid(np.arange(steps), np.arange(image[0]), np.arange(image[1]), indexing="ij")
        base = rng.integers(0, 100, 3)
        obs[IMAGE] = np.stack(
            [np.clip(base[c] + 3 * x + 2 * y + motion * t + 40 * c, 0, 255) for c in range(3)], axis=-1
        ).astype(np.uint8)
    return {
        "actions": actions,
        "obs": obs,
        "states": rng.standard_normal((steps, 81)).astype(np.float32),  # flat joint_q + joint_qd
        "rewards": rng.random(steps).astype(np.float32),
        "dones": np.zeros(steps, dtype=np.int64),
        "datagen": {
            "tcp_pose": rng.standard_normal((steps, 7)).astype(np.float32),
            "phase": np.arange(steps, dtype=np.int32),
        },
    }


def make_dataset(
    path: Path, lengths=LENGTHS, failed=(1,), image: tuple[int, int] | None = None, noisy: bool = False, motion: int = 1
) -> Path:
    with open_writer(path, task_id=TASK, env_args=ENV_ARGS, fsync=False) as w:
        for i, steps in enumerate(lengths):
            ok = i not in failed
            w.append_episode(
                make_episode(i, steps, image, noisy, motion),
                success=ok,
                attrs={"termination_reason": "success" if ok else "timeout"},
            )
    return path


@pytest.fixture(params=[".hdf5", ".zarr", "zarr packs"])
def dataset(request, tmp_path, monkeypatch) -> Path:
    if request.param != "zarr packs":
        return make_dataset(tmp_path / f"src{request.param}")
    path = tmp_path / "src.zarr"
    packed = ZarrWriteSettings(pack_min_batch=2)  # the demos as one batch, packed
    with open_writer(path, task_id=TASK, env_args=ENV_ARGS, fsync=False, zarr_settings=packed) as w:
        w.append_episodes(
            [
                (
                    make_episode(i, steps, None, False),
                    i != 1,
                    {"termination_reason": "success" if i != 1 else "timeout"},
                )
                for i, steps in enumerate(LENGTHS)
            ]
        )
    assert (path / "data" / "pack_0").is_dir()
    return path


def fingerprint(path: Path) -> str:
    h = hashlib.sha256()
    for f in sorted(p for p in path.rglob("*")):
        h.update(str(f.relative_to(path)).encode())
        if f.is_file():
            h.update(f.read_bytes())
    return h.hexdigest()


def read_data(root: Path) -> pa.Table:
    return pa.concat_tables([pq.read_table(p) for p in sorted((root / "data").glob("*/*.parquet"))])


def read_episodes(root: Path) -> pa.Table:
    return pa.concat_tables([pq.read_table(p) for p in sorted((root / "meta/episodes").glob("*/*.parquet"))])


def column(table: pa.Table, key: str) -> np.ndarray:
    col = table.column(key).combine_chunks()
    if pa.types.is_fixed_size_list(col.type):
        return col.values.to_numpy(zero_copy_only=False).reshape(len(col), col.type.list_size)
    return col.to_numpy(zero_copy_only=False)


def decode_png(data: bytes) -> np.ndarray:
    """Independent minimal PNG decoder (8-bit RGB, non-interlaced, all five filter types)."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, width = 8, b"", None
    while pos < len(data):
        n, tag = struct.unpack(">I4s", data[pos : pos + 8])
        body = data[pos + 8 : pos + 8 + n]
        assert struct.unpack(">I", data[pos + 8 + n : pos + 12 + n])[0] == zlib.crc32(tag + body) & 0xFFFFFFFF
        if tag == b"IHDR":
            width, height, depth, ctype, _, _, interlace = struct.unpack(">IIBBBBB", body)
            assert (depth, ctype, interlace) == (8, 2, 0)
        elif tag == b"IDAT":
            idat += body
        pos += 12 + n
    raw, stride, bpp = zlib.decompress(idat), width * 3, 3
    out = np.zeros((height, stride), np.int64)
    prev = [0] * stride
    for y in range(height):
        ftype, line = raw[y * (stride + 1)], raw[y * (stride + 1) + 1 : (y + 1) * (stride + 1)]
        cur = [0] * stride
        for i in range(stride):
            a = cur[i - bpp] if i >= bpp else 0
            b, c = prev[i], prev[i - bpp] if i >= bpp else 0
            if ftype == 0:
                pred = 0
            elif ftype == 1:
                pred = a
            elif ftype == 2:
                pred = b
            elif ftype == 3:
                pred = (a + b) // 2
            else:
                assert ftype == 4
                p = a + b - c
                pa_, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pred = a if pa_ <= pb and pa_ <= pc else (b if pb <= pc else c)
            cur[i] = (line[i] + pred) % 256
        out[y], prev = cur, cur
    return out.astype(np.uint8).reshape(height, width, 3)


def no_partials(parent: Path) -> bool:
    return not [p for p in parent.iterdir() if ".partial-" in p.name]


# ----------------------------------------------------------------------------- export
def test_export_validates_and_round_trips(dataset, tmp_path):
    root = tmp_path / "lerobot" / "pick"
    if dataset.suffix == ".zarr":  # a DatasetRef (anything with .path) is accepted as well as a path
        source = DatasetRef.open(dataset)
    else:
        source = dataset
    summary = export_lerobot(source, root)
    assert {k: summary[k] for k in ("root", "repo_id", "episodes", "frames", "skipped_failed", "fps")} == {
        "root": str(root),
        "repo_id": "newton_lab/galbotg1-pickcube-v0",
        "episodes": 2,
        "frames": LENGTHS[0] + LENGTHS[2],
        "skipped_failed": 1,
        "fps": 20,
    }
    assert summary["demo_ids"] == [0, 2] and summary["state_keys"] == STATE_ORDER and summary["image_keys"] == []

    report = validate_lerobot_v3(root)
    assert report["episodes"] == 2 and report["frames"] == summary["frames"] and report["fps"] == 20
    assert report["data_files"] == ["data/chunk-000/file-000.parquet"]
    assert no_partials(root.parent)
    (tmp_path / "probe").mkdir()
    assert root.stat().st_mode & 0o777 == (tmp_path / "probe").stat().st_mode & 0o777

    info = json.loads((root / "meta/info.json").read_text())
    assert info["codebase_version"] == "v3.0" and info["robot_type"] == "galbot_g1" and info["fps"] == 20
    assert (info["total_episodes"], info["total_frames"], info["total_tasks"]) == (2, summary["frames"], 1)
    assert (info["chunks_size"], info["data_files_size_in_mb"], info["video_files_size_in_mb"]) == (1000, 100, 200)
    assert info["splits"] == {"train": "0:2"} and info["video_path"] is None
    assert info["data_path"] == "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
    feats = info["features"]
    width = sum(OBS[t] for t in STATE_ORDER)
    assert feats["observation.state"]["dtype"] == "float32" and feats["observation.state"]["shape"] == [width]
    assert feats["observation.state"]["names"][:2] == ["robot_joint_pos.0", "robot_joint_pos.1"]
    assert feats["observation.state"]["names"][-1] == "blue_block_pos.2"
    assert feats["action"] == {"dtype": "float32", "shape": [8], "names": JOINTS}
    for key, dtype in (
        ("timestamp", "float32"),
        ("frame_index", "int64"),
        ("episode_index", "int64"),
        ("index", "int64"),
        ("task_index", "int64"),
    ):
        assert feats[key]["dtype"] == dtype and feats[key]["shape"] == [1]

    data, eps = read_data(root), read_episodes(root)
    schema = data.schema
    assert schema.field("action").type == pa.list_(pa.float32(), 8)
    assert schema.field("observation.state").type == pa.list_(pa.float32(), width)
    actions, state = column(data, "action"), column(data, "observation.state")
    assert column(data, "index").tolist() == list(range(summary["frames"]))
    assert eps.column("episode_index").to_pylist() == [0, 1]
    assert eps.column("tasks").to_pylist() == [[TASK], [TASK]]
    for e, demo in enumerate([0, 2]):
        lo, hi = eps.column("dataset_from_index")[e].as_py(), eps.column("dataset_to_index")[e].as_py()
        src = read_episode(dataset, demo)
        assert hi - lo == LENGTHS[demo] == eps.column("length")[e].as_py()
        got = actions[lo:hi]
        assert got.dtype == np.float32 and np.array_equal(got, src["actions"])  # exact, bit for bit
        want_state = np.concatenate([src["obs"][t].astype(np.float32) for t in STATE_ORDER], axis=1)
        assert np.array_equal(state[lo:hi], want_state)
        assert column(data, "frame_index")[lo:hi].tolist() == list(range(hi - lo))
        assert set(column(data, "episode_index")[lo:hi].tolist()) == {e}
        np.testing.assert_array_equal(column(data, "timestamp")[lo:hi], (np.arange(hi - lo) / 20).astype(np.float32))
    assert set(column(data, "task_index").tolist()) == {0}

    tasks = pq.read_table(root / "meta/tasks.parquet")
    assert tasks.column_names == ["task_index", "task"] and tasks.to_pylist() == [{"task_index": 0, "task": TASK}]
    assert json.loads(tasks.schema.metadata[b"pandas"])["index_columns"] == ["task"]  # LeRobot: tasks.loc[task]

    stats = json.loads((root / "meta/stats.json").read_text())
    np.testing.assert_allclose(stats["action"]["mean"], actions.astype(np.float64).mean(0), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(stats["action"]["std"], actions.astype(np.float64).std(0), rtol=1e-9, atol=1e-12)
    assert stats["action"]["min"] == actions.min(0).tolist() and stats["action"]["max"] == actions.max(0).tolist()
    assert stats["action"]["count"] == [summary["frames"]] and stats["index"]["max"] == [summary["frames"] - 1]
    np.testing.assert_allclose(stats["observation.state"]["mean"], state.astype(np.float64).mean(0), atol=1e-12)
    assert eps.column("stats/action/count").to_pylist() == [[LENGTHS[0]], [LENGTHS[2]]]

    source = json.loads((root / "meta/newton_lab_source.json").read_text())
    assert source["demo_ids"] == [0, 2] and source["skipped_failed_demo_ids"] == [1]


def test_failed_episode_included_on_request(tmp_path):
    src = make_dataset(tmp_path / "src.hdf5")
    root = tmp_path / "all"
    summary = export_lerobot(src, root, include_failed=True)
    assert summary["episodes"] == 3 and summary["skipped_failed"] == 0 and summary["frames"] == sum(LENGTHS)
    assert summary["demo_ids"] == [0, 1, 2]
    validate_lerobot_v3(root)
    data, eps = read_data(root), read_episodes(root)
    lo, hi = eps.column("dataset_from_index")[1].as_py(), eps.column("dataset_to_index")[1].as_py()
    assert np.array_equal(column(data, "action")[lo:hi], read_episode(src, 1)["actions"])


def test_options_state_keys_repo_task_fps(tmp_path):
    src = make_dataset(tmp_path / "src.zarr")
    root = tmp_path / "custom"
    summary = export_lerobot(
        Ref(src),
        root,
        repo_id="me/pick",
        fps=10,
        state_keys=["tcp_pose", "gripper_pos"],
        task_description="pick up the cube",
    )
    assert summary["repo_id"] == "me/pick" and summary["fps"] == 10
    assert summary["state_keys"] == ["tcp_pose", "gripper_pos"]
    validate_lerobot_v3(root)
    info = json.loads((root / "meta/info.json").read_text())
    assert info["fps"] == 10
    assert info["features"]["observation.state"]["shape"] == [8]
    assert info["features"]["observation.state"]["names"] == [f"tcp_pose.{i}" for i in range(7)] + ["gripper_pos.0"]
    data = read_data(root)
    src0 = read_episode(src, 0)
    np.testing.assert_array_equal(
        column(data, "observation.state")[: LENGTHS[0]],
        np.concatenate([src0["obs"]["tcp_pose"], src0["obs"]["gripper_pos"]], axis=1),
    )
    assert column(data, "timestamp")[1] == np.float32(0.1)
    assert pq.read_table(root / "meta/tasks.parquet").column("task").to_pylist() == ["pick up the cube"]
    assert read_episodes(root).column("tasks").to_pylist() == [["pick up the cube"]] * 2


@pytest.mark.parametrize(
    "kwargs, words",
    [
        ({"state_keys": ["nope"]}, ["nope", "available", "tcp_pose"]),
        ({"state_keys": "tcp_pose"}, ["list"]),
        ({"state_keys": []}, ["empty"]),
        ({"fps": 12.5}, ["whole", "fps"]),
        ({"repo_id": ""}, ["repo_id"]),
    ],
)
def test_bad_arguments_write_nothing(tmp_path, kwargs, words):
    src = make_dataset(tmp_path / "src.hdf5")
    root = tmp_path / "out"
    with pytest.raises((ValueError, TypeError)) as exc:
        export_lerobot(src, root, **kwargs)
    msg = str(exc.value)
    assert "\n" not in msg and all(w in msg for w in words), msg
    assert not root.exists() and no_partials(tmp_path)


def test_existing_root_refused_and_untouched(tmp_path):
    src = make_dataset(tmp_path / "src.hdf5")
    root = tmp_path / "taken"
    root.mkdir()
    (root / "keep.txt").write_text("mine")
    before = fingerprint(root)
    with pytest.raises(FileExistsError) as exc:
        export_lerobot(src, root)
    msg = str(exc.value)
    assert str(root) in msg and "choose a new root or delete it" in msg and "\n" not in msg
    assert fingerprint(root) == before and no_partials(tmp_path)
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(FileExistsError):
        export_lerobot(src, empty)
    assert list(empty.iterdir()) == []


def test_no_exportable_episodes(tmp_path):
    src = make_dataset(tmp_path / "src.hdf5", lengths=(5, 6), failed=(0, 1))
    root = tmp_path / "none"
    with pytest.raises(ValueError) as exc:
        export_lerobot(src, root)
    msg = str(exc.value)
    assert "no episodes to export" in msg and "include_failed=True" in msg and "\n" not in msg
    assert not root.exists() and no_partials(tmp_path)
    assert export_lerobot(src, root, include_failed=True)["episodes"] == 2


def test_crash_mid_export_leaves_no_root(tmp_path, monkeypatch):
    src = make_dataset(tmp_path / "src.hdf5", failed=())
    root = tmp_path / "crash"

    real = lr.read_episodes

    def flaky(path, demo_ids, **kwargs):  # the demos after the first: the third read fails
        for k, ep in enumerate(real(path, demo_ids, **kwargs)):
            if k == 1:
                raise RuntimeError("disk on fire")
            yield ep

    monkeypatch.setattr(lr, "read_episodes", flaky)
    with pytest.raises(RuntimeError, match="disk on fire"):
        export_lerobot(src, root)
    assert not root.exists() and no_partials(tmp_path)


def test_image_obs_become_image_features_without_video(tmp_path):
    src = make_dataset(tmp_path / "src.zarr", image=(6, 10))
    root = tmp_path / "img"
    summary = export_lerobot(src, root, video=False)
    key = f"observation.images.{IMAGE}"
    assert summary["image_keys"] == [key] and IMAGE not in summary["state_keys"]
    validate_lerobot_v3(root)
    info = json.loads((root / "meta/info.json").read_text())
    assert info["features"][key] == {"dtype": "image", "shape": [6, 10, 3], "names": ["height", "width", "channels"]}
    assert info["video_path"] is None and not (root / "videos").exists()
    assert info["features"]["observation.state"]["shape"] == [sum(OBS[t] for t in STATE_ORDER)]
    data = read_data(root)
    assert data.schema.field(key).type == pa.struct([("bytes", pa.binary()), ("path", pa.string())])
    images = data.column(key).to_pylist()
    eps = read_episodes(root)
    for e, demo in enumerate(summary["demo_ids"]):
        lo, hi = eps.column("dataset_from_index")[e].as_py(), eps.column("dataset_to_index")[e].as_py()
        frames = read_episode(src, demo)["obs"][IMAGE]
        for f in range(hi - lo):
            assert images[lo + f]["path"] == f"frame-{f:06d}.png"
            np.testing.assert_array_equal(decode_png(images[lo + f]["bytes"]), frames[f])
    stats = json.loads((root / "meta/stats.json").read_text())[key]
    assert np.asarray(stats["mean"]).shape == (3, 1, 1) and stats["count"] == [summary["frames"]]
    allframes = np.concatenate([read_episode(src, d)["obs"][IMAGE] for d in summary["demo_ids"]]).reshape(-1, 3)
    np.testing.assert_allclose(np.asarray(stats["mean"]).ravel(), allframes.mean(0) / 255, rtol=1e-9)
    np.testing.assert_allclose(np.asarray(stats["max"]).ravel(), allframes.max(0) / 255)


def test_image_obs_become_video_features(tmp_path):
    """Camera terms become mp4 video features: LeRobot's feature and episode columns, each episode's
    [from_timestamp, to_timestamp) span of the file decodes to its frames (lossy: small mean error), the
    validator decodes the files, and a truncated mp4 is a one-line error."""
    from newton_lab.datasets.lerobot.video import decode_frames, video_codec

    src = make_dataset(tmp_path / "src.hdf5", image=(72, 96))
    root = tmp_path / "vid"
    summary = export_lerobot(src, root)
    key = f"observation.images.{IMAGE}"
    report = validate_lerobot_v3(root)
    assert report["video_keys"] == [key] and summary["video_files"] == [f"videos/{key}/chunk-000/file-000.mp4"]
    info = json.loads((root / "meta/info.json").read_text())
    feature = info["features"][key]
    assert feature["dtype"] == "video" and feature["shape"] == [72, 96, 3]
    assert feature["info"]["video.codec"] == video_codec()[0].removeprefix("lib") and feature["info"]["video.fps"] == 20
    assert info["video_path"] == "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
    assert key not in read_data(root).schema.names  # frames live in the mp4, not the parquet
    frames, meta = decode_frames(root / summary["video_files"][0])
    assert (meta["width"], meta["height"], meta["fps"]) == (96, 72, 20.0) and len(frames) == summary["frames"]
    eps = read_episodes(root)
    for e, demo in enumerate(summary["demo_ids"]):
        lo = round(eps.column(f"videos/{key}/from_timestamp")[e].as_py() * 20)
        hi = round(eps.column(f"videos/{key}/to_timestamp")[e].as_py() * 20)
        source = read_episode(src, demo)["obs"][IMAGE]
        assert hi - lo == len(source)
        error = np.abs(frames[lo:hi].astype(np.int16) - source).mean()
        print(f"episode {e}: mean abs error {error:.2f} / 255")
        assert error < 6
    video = root / summary["video_files"][0]
    video.write_bytes(video.read_bytes()[: video.stat().st_size // 2])
    with pytest.raises(ValueError, match="video .*file-000.mp4 .*export the dataset again") as err:
        validate_lerobot_v3(root)
    assert "\n" not in str(err.value)


def test_data_files_roll_over(tmp_path):
    src = make_dataset(tmp_path / "src.hdf5", lengths=(40, 40, 40, 40), failed=(), image=(48, 64), noisy=True)
    root = tmp_path / "rolled"
    summary = export_lerobot(src, root, data_files_size_in_mb=1, video=False)  # PNG columns fill the files
    assert len(summary["data_files"]) > 1
    report = validate_lerobot_v3(root)
    assert report["data_files"] == summary["data_files"] and report["frames"] == 160
    eps = read_episodes(root)
    files = eps.column("data/file_index").to_pylist()
    assert files == sorted(files) and files[-1] == len(summary["data_files"]) - 1
    for e in range(4):
        path = root / f"data/chunk-000/file-{files[e]:03d}.parquet"
        rows = pq.read_table(path, columns=["episode_index", "action"])
        mask = column(rows, "episode_index") == e
        assert np.array_equal(column(rows, "action")[mask], read_episode(src, e)["actions"])


# ----------------------------------------------------------------------------- validator
def _rewrite_data(root: Path, fn) -> None:
    path = root / "data/chunk-000/file-000.parquet"
    table = pq.read_table(path)
    pq.write_table(fn(table), path)


def _set_column(name, values_fn):
    def fn(table):
        i = table.schema.get_field_index(name)
        old = column(table, name)
        return table.set_column(i, table.schema.field(i), pa.array(values_fn(old), table.schema.field(i).type))

    return fn


def _edit_json(rel, fn):
    def edit(root):
        p = root / rel
        obj = json.loads(p.read_text())
        fn(obj)
        p.write_text(json.dumps(obj))

    return edit


def _edit_episodes(name, values_fn):
    def edit(root):
        p = root / "meta/episodes/chunk-000/file-000.parquet"
        t = pq.read_table(p)
        i = t.schema.get_field_index(name)
        pq.write_table(
            t.set_column(i, t.schema.field(i), pa.array(values_fn(t.column(name).to_pylist()), t.schema.field(i).type)),
            p,
        )

    return edit


CORRUPTIONS = {
    "fps type": (_edit_json("meta/info.json", lambda o: o.update(fps="20")), "fps"),
    "codebase": (_edit_json("meta/info.json", lambda o: o.update(codebase_version="v2.1")), "codebase_version"),
    "total frames": (_edit_json("meta/info.json", lambda o: o.update(total_frames=5)), "total_frames"),
    "state shape": (
        _edit_json(
            "meta/info.json", lambda o: o["features"]["observation.state"].update(shape=[3], names=["a", "b", "c"])
        ),
        "observation.state",
    ),
    "index gap": (lambda r: _rewrite_data(r, _set_column("index", lambda v: v + (v >= 5))), "index"),
    "frame restart": (
        lambda r: _rewrite_data(r, _set_column("frame_index", lambda v: np.arange(len(v)))),
        "frame_index",
    ),
    "timestamps": (lambda r: _rewrite_data(r, _set_column("timestamp", lambda v: v * 2)), "timestamp"),
    "offsets": (_edit_episodes("dataset_from_index", lambda v: [v[0], v[1] + 1]), "episode 1"),
    "missing stats": (lambda r: (r / "meta/stats.json").unlink(), "stats.json"),
    "extra column": (
        lambda r: _rewrite_data(r, lambda t: t.append_column("junk", pa.array([0] * t.num_rows))),
        "unexpected",
    ),
}


@pytest.mark.parametrize("name", list(CORRUPTIONS))
def test_validator_names_first_problem(tmp_path, name):
    src = make_dataset(tmp_path / "src.hdf5")
    good = tmp_path / "good"
    export_lerobot(src, good)
    bad = tmp_path / "bad"
    shutil.copytree(good, bad)
    corrupt, word = CORRUPTIONS[name]
    corrupt(bad)
    with pytest.raises(ValueError) as exc:
        validate_lerobot_v3(bad)
    msg = str(exc.value)
    assert "\n" not in msg and str(bad) in msg and word in msg, msg
    with pytest.raises(ValueError, match="does not exist"):
        validate_lerobot_v3(tmp_path / "absent")
