"""rerun recordings, read back with rerun's own reader: one entity per model shape (every geometry type),
body transforms and per-row scalars every step, episode events, a default blueprint; replaying a dataset
episode reproduces its recorded states; each env camera is a pinhole whose frustum looks where its images do,
with RGB / depth / segmentation streams (live and replayed)."""

from __future__ import annotations

import newton
import numpy as np
import pytest
import rerun as rr
import warp as wp
from rerun.chunk import RrdReader

from newton_lab.agents import PlannerAgent
from newton_lab.datasets import read_dataset_info, read_episode, state_tree
from newton_lab.viz import RerunLogger, log_model_shapes, replay_episode
from newton_lab.viz.shapes import row_offsets

GEOMETRY = ("Boxes3D", "Ellipsoids3D", "Capsules3D", "Cylinders3D", "Mesh3D", "Points3D")


def _geometry(rrd) -> dict[str, str]:
    """Static geometry entities of a recording: path -> archetype name."""
    cols = RrdReader(str(rrd)).store().schema().component_columns()
    return {
        c.entity_path: c.archetype.rsplit(".", 1)[-1]
        for c in cols
        if c.is_static and c.archetype.rsplit(".", 1)[-1] in GEOMETRY
    }


def _rows(rrd) -> dict[str, int]:
    """Temporal rows logged per entity path."""
    rows: dict[str, int] = {}
    for chunk in RrdReader(str(rrd)).store().stream():
        if not chunk.is_static:
            rows[chunk.entity_path] = rows.get(chunk.entity_path, 0) + chunk.num_rows
    return rows


def _texts(rrd) -> list[str]:
    out = []
    for chunk in RrdReader(str(rrd)).store().stream():
        batch = chunk.to_record_batch()
        if "TextLog:text" in batch.schema.names:
            out += [t for cell in batch.column("TextLog:text").to_pylist() for t in cell]
    return out


def test_every_model_shape_is_one_entity(pick_env, tmp_path):
    """The G1 scene: every shape of the model (visual, collision-only, sites, static, ground) is logged once,
    at the path the logger reports, with body transforms and scalars every step."""
    model = pick_env.model
    shapes = model.shape_count
    per_world = int((model.shape_world.numpy() == 0).sum()) + int((model.shape_world.numpy() < 0).sum())
    rrd = tmp_path / "sub" / "run.rrd"  # the folder is created
    logger = RerunLogger(pick_env, save=rrd, max_worlds=2)
    agent = PlannerAgent.from_task(pick_env.task_id)
    pick_env.reset()
    agent.reset()
    for _ in range(3):
        _, reward, _, _, info = pick_env.step(agent.act(pick_env))
        logger.on_step(reward, info)
    logger.close()
    geo = _geometry(rrd)
    assert logger.path == rrd.resolve() and len(logger.shape_paths) == shapes
    assert len(geo) == shapes and set(geo) == {"/" + p for p in logger.shape_paths.values()}
    # the G1's collision-only shapes (arms, torso, chassis) are drawn too
    for part in (
        "leg_link5/collision/torso",
        "base_footprint/collision/chassis",
        "left_arm_link3/collision/",
        "right_arm_link7/collision/right_palm",
        "head_link2/visual/",
        "static/visual/table",
        "cube/visual/",
    ):
        assert sum(p.startswith(f"/world/0/{part}") for p in geo) == 1, part
    assert geo["/world/0/leg_link5/collision/torso"] == "Boxes3D"
    assert geo["/world/0/left_arm_link3/collision/left_arm_link3_geom_0"] == "Capsules3D"
    assert sum(p.startswith("/world/1/") for p in geo) == per_world - 1  # row 1 minus the shared ground
    rows = _rows(rrd)
    assert rows["/world/0/cube"] == 3 and rows["/world/1/left_arm_link7"] == 3 and rows["/world/0/tcp"] == 3
    assert rows["/metrics/0/reward"] == rows["/metrics/1/phase"] == rows["/metrics/0/success"] == 3
    assert [e.kind for e in RrdReader(str(rrd)).blueprints()] == ["blueprint"]
    assert "row 0 reset: episode 1 starts" in _texts(rrd)

    one = RerunLogger(pick_env, save=tmp_path / "one.rrd", max_worlds=1)  # only the first max_worlds rows
    one.close()
    assert len(_geometry(tmp_path / "one.rrd")) == len(one.shape_paths) == per_world
    assert not any(p.startswith("/world/1/") for p in _geometry(tmp_path / "one.rrd"))
    with pytest.raises(ValueError, match="needs a sink"):
        RerunLogger(pick_env)


def test_each_geometry_type_has_a_drawing(tmp_path):
    """Boxes, spheres, capsules, cylinders, cones, ellipsoids, meshes, convex hulls, sites, heightfields and
    planes of a small Newton model; a collision-only shape on a body with visual shapes is hidden by default."""
    b = newton.ModelBuilder()
    body = b.add_body(xform=wp.transform((0.0, 0.0, 1.0), wp.quat_identity()), mass=1.0, label="link")
    hidden_cfg = newton.ModelBuilder.ShapeConfig(is_visible=False)
    b.add_shape_box(body, hx=0.1, hy=0.2, hz=0.3, label="box")
    b.add_shape_sphere(body, radius=0.1, cfg=hidden_cfg, label="ball")
    b.add_shape_capsule(body, radius=0.05, half_height=0.2, label="capsule")
    b.add_shape_cylinder(body, radius=0.05, half_height=0.2, label="cylinder")
    b.add_shape_cone(body, radius=0.05, half_height=0.2, label="cone")
    b.add_shape_ellipsoid(body, rx=0.1, ry=0.2, rz=0.3, label="ellipsoid")
    b.add_shape_mesh(body, mesh=newton.Mesh.create_box(0.1), scale=(1.0, 2.0, 3.0), label="mesh")
    b.add_shape_convex_hull(body, mesh=newton.Mesh.create_sphere(0.1), label="hull")
    b.add_site(body, label="tcp")
    b.add_shape_heightfield(heightfield=newton.Heightfield(np.zeros((4, 4)), 4, 4, hx=0.5, hy=0.5), label="hf")
    b.add_ground_plane()
    model = b.finalize(device="cpu")
    rec = rr.RecordingStream("shape_test")
    rec.save(str(tmp_path / "shapes.rrd"))
    logged = log_model_shapes(rec, model, {body: "world/0/link"}, 1, row_offsets(1, 2.5))
    rec.flush()
    rec.disconnect()
    geo = _geometry(tmp_path / "shapes.rrd")
    assert len(geo) == len(logged.paths) == model.shape_count == 11
    assert {p.rsplit("/", 2)[-2] + "/" + p.rsplit("/", 1)[-1]: a for p, a in geo.items()} == {
        "visual/box": "Boxes3D",
        "collision/ball": "Ellipsoids3D",
        "visual/capsule": "Capsules3D",
        "visual/cylinder": "Cylinders3D",
        "visual/cone": "Mesh3D",
        "visual/ellipsoid": "Ellipsoids3D",
        "visual/mesh": "Mesh3D",
        "visual/hull": "Mesh3D",
        "site/tcp": "Ellipsoids3D",
        "visual/hf": "Mesh3D",
        "visual/ground_plane": "Mesh3D",
    }
    assert logged.hidden == ["world/0/link/collision/ball"]


def test_view_replays_recorded_states_and_logs_episode_events(pick_env, tmp_path):
    live = tmp_path / "collect.rrd"
    logger = RerunLogger(pick_env, save=live, max_worlds=2, images=False)  # (cameras: test_replay_shows_...)
    ref = pick_env.collect(
        agent=PlannerAgent.from_task(pick_env.task_id),
        episodes=1,
        path=tmp_path / "d.hdf5",
        max_steps=400,
        progress=False,
        on_step=logger.on_step,
    )
    logger.close()
    ep = read_episode(ref.path, 0)
    ended = [t for t in _texts(live) if " episode 1 succeeded (" in t or " episode 1 failed (" in t]
    assert len(ended) >= 1 and f"after {ep['attrs']['num_samples']} steps" in " ".join(ended)
    rrd = tmp_path / "replay.rrd"
    poses = replay_episode(ref.path, 0, save=rrd)
    cube = pick_env.task.entities["cube"].body
    states = state_tree(ep["states"], read_dataset_info(ref.path)["env_args"])
    np.testing.assert_allclose(poses[:, cube], states["rigid_object"]["cube"]["root_pose"], atol=1e-5)
    assert _rows(rrd)["/world/0/cube"] == ep["attrs"]["num_samples"]
    with pytest.raises(ValueError) as e:
        replay_episode(ref.path, 7)
    assert "no episode 7" in str(e.value)


def test_episodes_per_row_records_only_the_first_episodes(pick_env, tmp_path):
    """The pipeline's evaluation recording: rows 0 and 1, one episode each, nothing after."""
    from newton_lab.agents.base import ZeroAgent

    rrd = tmp_path / "eval.rrd"
    logger = RerunLogger(pick_env, save=rrd, max_worlds=2, episodes_per_row=1, images=False)
    s = pick_env.evaluate(agent=ZeroAgent(), episodes=6, max_steps=4, progress=False, on_step=logger.on_step)
    logger.close()
    assert s["episodes"] == 6 and logger.finished
    ended = [t for t in _texts(rrd) if " succeeded (" in t or " failed (" in t]
    assert sorted(t.split(" episode")[0] for t in ended) == ["row 0", "row 1"], ended
    assert all(" episode 1 " in t for t in ended), ended
    assert _rows(rrd)["/world/0/cube"] == 4 and _rows(rrd)["/world/1/cube"] == 4  # one 4-step episode each
    with pytest.raises(ValueError, match="episodes_per_row"):
        RerunLogger(pick_env, save=tmp_path / "x.rrd", episodes_per_row=0)


# ----------------------------------------------------------------------------- cameras
CAMERA = "front_head"
CAM_DATA = ("rgb", "depth", "segmentation")
VIEW_DIR_TO_RDF = {1: (1, -1), 2: (1, 1), 3: (0, 1), 4: (0, -1), 5: (2, 1), 6: (2, -1)}
"""rerun ViewDir code (Up, Down, Right, Left, Forward, Back) -> (RDF axis, sign)."""
STEPS = 3


def _values(rrd, entity: str, column: str) -> dict:
    """``column`` of ``entity`` read back: {step: first value of the cell} (static: key None)."""
    out = {}
    for chunk in RrdReader(str(rrd)).store().stream():
        if chunk.entity_path != entity:
            continue
        b = chunk.to_record_batch()
        if column in b.schema.names:
            steps = b.column("step").to_pylist() if "step" in b.schema.names else [None] * b.num_rows
            out.update({s: v[0] for s, v in zip(steps, b.column(column).to_pylist()) if v})
    return out


def _image(rrd, entity: str, archetype: str) -> dict[int, np.ndarray]:
    """Raw image stream of ``entity`` read back as arrays by step (shape from the logged format)."""
    fmt, buf = _values(rrd, entity, f"{archetype}:format"), _values(rrd, entity, f"{archetype}:buffer")
    dtype = {"Image": np.uint8, "DepthImage": np.float32, "SegmentationImage": np.uint16}[archetype]

    def shape(f):
        return (f["height"], f["width"], 3) if archetype == "Image" else (f["height"], f["width"])

    return {s: np.frombuffer(bytes(buf[s]), dtype=dtype).reshape(shape(fmt[s])) for s in buf}


def _rotation(q) -> np.ndarray:
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


@pytest.fixture(scope="module")
def cam_env():
    from newton_lab.envs import make_env

    return make_env(
        "GalbotG1-PickCube-v0",
        num_envs=2,
        device="cpu",
        seed=1,
        randomize=True,
        cameras={CAMERA: {"resolution": (96, 72), "data": CAM_DATA}},
    )


@pytest.fixture(scope="module")
def cam_run(cam_env, tmp_path_factory):
    """STEPS planner steps of the 96x72 camera env logged to an .rrd; the env's own images, camera poses, body
    poses, states and actions of each step kept for comparison (and for a dataset of row 0)."""
    from newton_lab.envs.rollout import env_args

    env, rrd = cam_env, tmp_path_factory.mktemp("cam") / "cam.rrd"
    logger = RerunLogger(env, save=rrd, max_worlds=2)
    agent = PlannerAgent.from_task(env.task_id)
    env.reset()
    agent.reset()
    kept = {"images": [], "poses": [], "body_q": [], "states": [], "actions": []}
    for _ in range(STEPS):
        action = agent.act(env)
        _, reward, _, _, info = env.step(action)
        logger.on_step(reward, info)
        kept["images"].append({d: env.sensors.images[f"{CAMERA}_{d}"].cpu().numpy().copy() for d in CAM_DATA})
        kept["poses"].append(env.sensors.cameras.poses(CAMERA).cpu().numpy().copy())
        kept["body_q"].append(env.state.body_q.numpy().copy())
        n = env.num_envs
        kept["states"].append(
            np.concatenate(
                [
                    wp.to_torch(env.state.joint_q).view(n, -1).cpu().numpy(),
                    wp.to_torch(env.state.joint_qd).view(n, -1).cpu().numpy(),
                ],
                axis=1,
            )
        )
        kept["actions"].append(action.cpu().numpy().copy())
    logger.close()
    return {"rrd": rrd, "logger": logger, "env_args": env_args(env), **kept}


def test_each_camera_is_a_pinhole_with_its_image_streams(cam_env, cam_run):
    """Per drawn row: a static Pinhole (K, 96x72, RUB axes) with the segmentation names, then one camera pose and
    one RGB / depth / segmentation frame per logged step, equal to the env's images."""
    rrd, names = cam_run["rrd"], list(cam_env.sensors.cameras.segmentation_names)
    assert [c.name for c in cam_run["logger"].cameras] == [CAMERA]
    views, stack = [], [cam_run["logger"].blueprint.root_container]  # the blueprint's 2D panels: row 0's camera
    while stack:
        node = stack.pop()
        views += [(node.origin, node.name)] if type(node).__name__ == "Spatial2DView" else []
        stack += [c for c in getattr(node, "contents", None) or [] if hasattr(c, "origin") or hasattr(c, "contents")]
    assert sorted(views) == [(f"world/0/cameras/{CAMERA}", f"{CAMERA} {d}") for d in sorted(CAM_DATA)]
    rows = _rows(rrd)
    for w in range(2):
        path = f"/world/{w}/cameras/{CAMERA}"
        np.testing.assert_allclose(
            np.reshape(_values(rrd, path, "Pinhole:image_from_camera")[None], (3, 3)).T,
            cam_env.sensors.cameras.intrinsics(CAMERA),
            rtol=1e-6,
        )
        assert _values(rrd, path, "Pinhole:resolution")[None] == [96.0, 72.0]
        assert _values(rrd, path, "Pinhole:camera_xyz")[None] == [3, 1, 6]  # Right, Up, Back
        labels = [
            c["class_description"]["info"]["label"] for c in _values(rrd, path, "AnnotationContext:context")[None]
        ]
        assert labels == names and "cube" in labels and "robot/left_gripper" in labels
        assert rows[path] == rows[f"{path}/rgb"] == rows[f"{path}/depth"] == rows[f"{path}/segmentation"] == STEPS
        rgb, depth = _image(rrd, f"{path}/rgb", "Image"), _image(rrd, f"{path}/depth", "DepthImage")
        seg = _image(rrd, f"{path}/segmentation", "SegmentationImage")
        assert _values(rrd, f"{path}/depth", "DepthImage:meter")[0] == 1.0
        for t in range(STEPS):
            ref = cam_run["images"][t]
            assert rgb[t].shape == (72, 96, 3) and depth[t].shape == seg[t].shape == (72, 96)
            np.testing.assert_array_equal(rgb[t], ref["rgb"][w])
            np.testing.assert_array_equal(seg[t], ref["segmentation"][w])
            d = ref["depth"][w]
            np.testing.assert_array_equal(depth[t], np.where(np.isfinite(d), d, 0.0))  # nothing hit: 0 (no depth)
            np.testing.assert_allclose(
                _values(rrd, path, "Transform3D:translation")[t], cam_run["poses"][t][w, :3], atol=1e-6
            )


def test_camera_frustum_looks_where_its_image_does(cam_env, cam_run):
    """Read back from the recording only: the cube's logged centre, taken into the camera through the logged
    pose and axes (camera_xyz) and projected with the logged K, lands within 3 px of the centroid of the cube's
    logged segmentation mask, in front of the camera, and the logged depth there is the cube's front face."""
    rrd = cam_run["rrd"]
    cube_id = list(cam_env.sensors.cameras.segmentation_names).index("cube")
    for w in range(2):
        path = f"/world/{w}/cameras/{CAMERA}"
        k = np.reshape(_values(rrd, path, "Pinhole:image_from_camera")[None], (3, 3)).T
        to_rdf = np.zeros((3, 3))
        for i, code in enumerate(_values(rrd, path, "Pinhole:camera_xyz")[None]):
            axis, sign = VIEW_DIR_TO_RDF[code]
            to_rdf[axis, i] = sign
        seg = _image(rrd, f"{path}/segmentation", "SegmentationImage")
        depth = _image(rrd, f"{path}/depth", "DepthImage")
        cube = _values(rrd, f"/world/{w}/cube", "Transform3D:translation")
        trans = _values(rrd, path, "Transform3D:translation")
        quat = _values(rrd, path, "Transform3D:quaternion")
        for t in range(STEPS):
            rdf = to_rdf @ (_rotation(quat[t]).T @ (np.asarray(cube[t]) - np.asarray(trans[t])))
            assert rdf[2] > 0.2, "the cube must be in front of the camera"
            u, v = (k @ rdf)[:2] / rdf[2]
            rows, cols = np.nonzero(seg[t] == cube_id)
            assert len(rows) >= 4, f"row {w} step {t}: the cube is not in the image"
            centroid = np.array([cols.mean() + 0.5, rows.mean() + 0.5])
            assert np.linalg.norm(centroid - [u, v]) < 3.0, (w, t, centroid, (u, v))
            assert 0.0 < rdf[2] - depth[t][int(v), int(u)] < 0.06  # metres: the visible face is nearer than the centre


def test_image_stride_jpeg_and_images_off(cam_env, tmp_path):
    """image_every=2 logs the cameras at steps 0 and 2 (bodies every step); jpeg_quality stores RGB as a JPEG of
    the camera's size; images=False logs no camera; bad options raise."""
    import io

    from PIL import Image

    from newton_lab.agents.base import ZeroAgent

    rrd = tmp_path / "stride.rrd"
    logger = RerunLogger(cam_env, save=rrd, max_worlds=1, image_every=2, jpeg_quality=90)
    for _ in range(3):
        _, reward, _, _, info = cam_env.step(ZeroAgent().act(cam_env))
        logger.on_step(reward, info)
    logger.close()
    rows = _rows(rrd)
    path = f"/world/0/cameras/{CAMERA}"
    assert rows["/world/0/cube"] == 3 and rows[path] == rows[f"{path}/rgb"] == rows[f"{path}/depth"] == 2
    blobs = _values(rrd, f"{path}/rgb", "EncodedImage:blob")
    assert sorted(blobs) == [0, 2]
    assert Image.open(io.BytesIO(bytes(blobs[2]))).size == (96, 72)
    off = RerunLogger(cam_env, save=tmp_path / "off.rrd", images=False)
    off.log_step()
    off.close()
    assert off.cameras == [] and not any("/cameras" in p for p in _rows(tmp_path / "off.rrd"))
    for bad in ({"image_every": 0}, {"jpeg_quality": 0}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            RerunLogger(cam_env, save=tmp_path / "x.rrd", **bad)


def test_replay_shows_the_recorded_camera_streams(cam_env, cam_run, tmp_path):
    """A dataset with the image contract (obs/<camera>_<data>, the env_args cameras block, datagen/camera_poses)
    replays with each recorded frame on the recorded pinhole."""
    from newton_lab.datasets import open_writer

    args = cam_run["env_args"]
    names = list(cam_env.sensors.cameras.segmentation_names)
    args["newton_lab"]["cameras"] = {
        CAMERA: {
            "width": 96,
            "height": 72,
            "data": list(CAM_DATA),
            "intrinsics": cam_env.sensors.cameras.intrinsics(CAMERA).tolist(),
            "segmentation_names": names,
        }
    }
    episode = {
        "actions": np.stack([a[0] for a in cam_run["actions"]]).astype(np.float32),
        "states": np.stack([s[0] for s in cam_run["states"]]).astype(np.float32),
        "obs": {f"{CAMERA}_{d}": np.stack([im[d][0] for im in cam_run["images"]]) for d in CAM_DATA},
        "datagen": {"camera_poses": {CAMERA: np.stack([p[0] for p in cam_run["poses"]])}},
    }
    with open_writer(tmp_path / "img.hdf5", task_id=cam_env.task_id, env_args=args) as writer:
        writer.append_episode(episode, success=False)
    rrd = tmp_path / "replay.rrd"
    poses = replay_episode(tmp_path / "img.hdf5", 0, save=rrd)
    bpw = cam_env.sim.layout.bodies_per_world
    np.testing.assert_allclose(poses[:, :bpw, :3], np.stack([q[:bpw, :3] for q in cam_run["body_q"]]), atol=1e-4)
    path = f"/world/0/cameras/{CAMERA}"
    labels = [c["class_description"]["info"]["label"] for c in _values(rrd, path, "AnnotationContext:context")[None]]
    assert labels == names and _values(rrd, path, "Pinhole:resolution")[None] == [96.0, 72.0]
    rgb, seg = _image(rrd, f"{path}/rgb", "Image"), _image(rrd, f"{path}/segmentation", "SegmentationImage")
    assert len(rgb) == len(seg) == STEPS == _rows(rrd)[f"{path}/depth"]
    for t in range(STEPS):
        np.testing.assert_array_equal(rgb[t], episode["obs"][f"{CAMERA}_rgb"][t])
        np.testing.assert_array_equal(seg[t], episode["obs"][f"{CAMERA}_segmentation"][t])
        np.testing.assert_allclose(
            _values(rrd, path, "Transform3D:quaternion")[t], cam_run["poses"][t][0, 3:], atol=1e-6
        )
