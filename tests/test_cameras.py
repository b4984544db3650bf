"""Cameras on the G1 mounts (issue 13): mounts from the reference offsets, pinhole projection against the rendered
segmentation, what the front head sees at reset, upright images, zero-copy views, lazy rendering, bad input.

One PickCube env (2 worlds, front head RGB + depth + segmentation at 96 x 72) on CPU Warp; every render shares one
render kernel, so Warp compiles it once."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import torch
import warp as wp
from newton.sensors import SensorCamera

from newton_lab.agents import expert_agent
from newton_lab.envs import make_env
from newton_lab.envs.cameras import resolve_cameras
from newton_lab.envs.render_settings import RENDER_BLOCK_DIM, RENDER_ORDER
from newton_lab.robots.g1 import cameras as mounts, spec
from newton_lab.robots.g1.model import mjcf_path
from newton_lab.task_api.registry import lookup

W, H = 96, 72
ALL = ("rgb", "depth", "segmentation")
PICK = "GalbotG1-PickCube-v0"
HIDDEN = ("robot/base", "robot/torso", "robot/head", "robot/right_arm", "robot/right_gripper")
"""The G1 links PickCube's render leaves out (it drives the left arm only)."""


@pytest.fixture(scope="module")
def cam_env():
    view = {"resolution": (W, H), "data": ALL}  # both cameras in one render call (one resolution)
    return make_env(
        PICK, num_envs=2, device="cpu", seed=5, randomize=True, cameras={"front_head": view, "left_wrist": view}
    )


def _rotate(q, v):
    return mounts._quat_rotate(np.asarray(q, dtype=float), v)


def _project(pose: np.ndarray, point: np.ndarray, K: np.ndarray) -> tuple[np.ndarray, float]:
    """Pixel (u, v) of world ``point`` seen from camera ``pose`` (pinhole frame: -z forward, +y up), and its
    distance along the view axis [m]."""
    q_inv = np.array([-pose[3], -pose[4], -pose[5], pose[6]])
    pc = _rotate(q_inv, point - pose[:3])
    z = -pc[2]
    return np.array([K[0, 2] + K[0, 0] * pc[0] / z, K[1, 2] - K[1, 1] * pc[1] / z]), z


def _touches(mask: np.ndarray, other: np.ndarray) -> bool:
    """Whether ``mask`` borders ``other`` (8-neighbourhood): an object partly hidden behind another."""
    grown = mask.copy()
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            grown |= np.roll(np.roll(mask, dr, axis=0), dc, axis=1)
    return bool((grown & other).any())


def _centroid(mask: np.ndarray) -> np.ndarray:
    """Mask centroid in continuous pixel coordinates (pixel (r, c) covers [c, c + 1) x [r, r + 1))."""
    rows, cols = np.nonzero(mask)
    return np.array([cols.mean() + 0.5, rows.mean() + 0.5])


# ---------------------------------------------------------------- mounts (no physics)
def test_mjcf_camera_sites_follow_the_reference_offsets():
    root = ET.parse(mjcf_path()).getroot()
    for mount, site_name in spec.CAMERA_MOUNTS.items():
        body_name, pos, quat = mounts.site_pose(mount)
        body = next(b for b in root.iter("body") if b.get("name") == body_name)
        site = next(s for s in body.findall("site") if s.get("name") == site_name)
        np.testing.assert_allclose([float(x) for x in site.get("pos").split()], pos, atol=1e-8)
        w, x, y, z = (float(v) for v in site.get("quat").split())
        np.testing.assert_allclose((x, y, z, w), quat, atol=1e-8)
    # the head camera looks forward, pitched 28 deg down, level (image x = robot right); wrists along the approach
    _, _, q = mounts.site_pose("front_head")
    fwd, right = _rotate(q, (0, 0, -1)), _rotate(q, (1, 0, 0))
    assert math.degrees(math.asin(-fwd[2])) == pytest.approx(28.1, abs=0.5) and fwd[0] > 0.85
    assert right[1] < -0.99
    for side in ("left_wrist", "right_wrist"):
        _, _, q = mounts.site_pose(side)
        assert _rotate(q, (0, 0, -1))[0] < -0.99  # link7's -x is the gripper's approach


def test_intrinsics_follow_the_reference_lens():
    K = mounts.intrinsics(298, 224)
    assert K[0, 0] == K[1, 1] == pytest.approx(1.1453 * 298, rel=1e-4)
    assert (K[0, 2], K[1, 2]) == (149.0, 112.0)
    rays = mounts.pinhole_rays(W, H)
    assert rays.shape == (H, W, 1, 2, 3)
    np.testing.assert_allclose(np.linalg.norm(rays[..., 1, :], axis=-1), 1.0, rtol=1e-6)
    np.testing.assert_allclose(-rays[..., 0, 2], spec.CAMERA_CLIPPING[0], rtol=1e-6)  # origins on the near plane


# ---------------------------------------------------------------- rendering
def test_image_terms_are_zero_copy_views(cam_env):
    env = cam_env
    env.reset()
    assert list(env.sensors.image_terms) == [f"{cam}_{data}" for cam in ("front_head", "left_wrist") for data in ALL]
    rgb, depth, seg = (env.sensors.images[f"front_head_{data}"] for data in ALL)
    assert (rgb.shape, rgb.dtype) == ((2, H, W, 3), torch.uint8)
    assert (depth.shape, depth.dtype) == ((2, H, W), torch.float32)
    assert (seg.shape, seg.dtype) == ((2, H, W), torch.int32)
    (group,) = env.sensors.cameras.view_groups  # 2 cameras x 2 worlds: 4 views, camera-major
    assert group.poses.shape == (4,)
    assert rgb.data_ptr() == wp.to_torch(group.color).data_ptr()
    assert env.sensors.images["left_wrist_rgb"].data_ptr() == rgb.data_ptr() + 2 * H * W * 4
    assert seg.data_ptr() == wp.to_torch(group.segmentation).data_ptr()
    assert env.sensors.images["front_head_rgb"] is rgb  # the same view every read


def test_render_only_when_images_are_read_and_capture_matches_eager(cam_env):
    env = cam_env
    env.reset()
    view = env.sensors.images["front_head_segmentation"]
    before = view.clone()
    action = env.current_action()
    action[:, :7] += 0.3  # swing the arm: the wrist and gripper move in the head view
    for _ in range(5):
        env.step(action)
    assert env.sensors.cameras.stale and torch.equal(view, before)  # stepping rendered nothing
    captured = {k: v.clone() for k, v in env.render().items()}
    assert not env.sensors.cameras.stale
    assert env.sensors.cameras.render_graph is not None  # the render is one captured graph
    assert not torch.equal(captured["front_head_segmentation"], before)
    env.sensors.cameras.render(force=True, eager=True)  # the same render, eager
    for name, img in env.sensors.images.items():
        assert torch.equal(img, captured[name]), name


def test_every_render_order_draws_the_same_pixels(cam_env):
    """The renderer's traversal orders and block sizes (``bench --render-orders`` times them) change only the
    speed: each draws the same images of the same state, through the recaptured render graph."""
    env = cam_env
    cams = env.sensors.cameras
    reference = {k: v.clone() for k, v in cams.render(force=True).items()}
    try:
        for order in SensorCamera.RenderOrder:
            cams.use_render_order(order, 128)
            assert cams.sensor.default_render_config.render_order == order
            for name, img in cams.render(force=True).items():
                assert torch.equal(img, reference[name]), (order.name, name)
    finally:
        cams.use_render_order(RENDER_ORDER, RENDER_BLOCK_DIM)
    assert cams.sensor.default_render_config.block_dim == RENDER_BLOCK_DIM


def _hidden_ids_seen(env, every: int, steps: int) -> list[tuple[int, str, str]]:
    """(step, view, link group) wherever a group the env's render leaves out shows in a render of every shape,
    over ``steps`` steps of the expert's episodes, every ``every`` steps."""
    cams = env.sensors.cameras
    hidden = cams.hidden_groups
    ids = {cams.segmentation_names.index(g): g for g in hidden}
    agent = expert_agent(env)
    env.reset()
    agent.reset()
    seen = []
    cams.hide(())
    try:
        for t in range(steps):
            env.step(agent.act(env))
            if t % every == 0:
                for view in ("front_head", "left_wrist"):
                    present = np.unique(env.sensors.images[f"{view}_segmentation"].numpy())
                    seen += [(t, view, ids[i]) for i in present if i in ids]
    finally:
        cams.hide(hidden)
    return seen


def test_culled_links_change_no_pixel(cam_env):
    """The render leaves out the robot's links that no view sees (``RobotBinding.hidden_link_groups``: the G1's
    base, torso and head, and the arm no action drives): over PickCube's expert episode a render of every shape
    never shows them, and at its end the culled render draws exactly the same RGB, depth and segmentation. The
    model's own shape flags (the collision pipeline's) are untouched."""
    env = cam_env
    cams = env.sensors.cameras
    flags = env.model.shape_flags.numpy().copy()
    assert cams.hidden_groups == HIDDEN
    assert _hidden_ids_seen(env, every=5, steps=150) == []
    culled = {k: v.clone() for k, v in cams.render(force=True).items()}
    enabled = env.model.bvh_shape_count_enabled
    cams.hide(())
    try:
        assert env.model.bvh_shape_count_enabled > enabled  # the culled BVH really is smaller
        for name, img in cams.render(force=True).items():
            assert torch.equal(img, culled[name]), name
    finally:
        cams.hide(HIDDEN)
    np.testing.assert_array_equal(env.model.shape_flags.numpy(), flags)


def test_culled_links_stay_out_of_view_through_pick_to_shelf():
    """PickToShelf drives the base and lifts the legs on its way to the shelf: its expert episode, rendered with
    every shape, never shows the links its render leaves out either."""
    view = {"resolution": (W, H), "data": ("segmentation",)}
    env = make_env(
        "GalbotG1-PickToShelf-v0",
        num_envs=1,
        device="cpu",
        seed=2,
        randomize=True,
        cameras={"front_head": view, "left_wrist": view},
    )
    assert "robot/right_arm" in env.sensors.cameras.hidden_groups
    assert _hidden_ids_seen(env, every=10, steps=700) == []


def test_projection_matches_segmentation(cam_env):
    """At 15 randomised resets x 2 rows, the cube centre projected through K and the camera pose lands within
    3 px of its mask's centroid, and the cube's depth is its distance along the view axis. A cube far to the left
    (y > 0.22) can be partly behind the gripper's fingers at reset; its mask is then cut and those rows are
    left out."""
    env = cam_env
    names = env.sensors.cameras.segmentation_names
    cube = names.index("cube")
    robot = np.array([n.startswith("robot/") for n in names])
    K = env.sensors.cameras.intrinsics("front_head")
    seen, checked = [], 0
    for _ in range(15):
        env.reset()
        seg = env.sensors.images["front_head_segmentation"].numpy()
        depth = env.sensors.images["front_head_depth"].numpy()
        poses = env.sensors.cameras.poses("front_head").numpy()
        centres = env.buffers.entity_poses[:, env.task.entities["cube"].slot, :3].numpy()
        for row in range(env.num_envs):
            uv, z = _project(poses[row], centres[row], K)
            mask = seg[row] == cube
            assert mask.sum() >= 9, f"cube hardly visible in row {row}"
            seen.append(tuple(centres[row, :2].round(3)))
            if _touches(mask, robot[seg[row]]):
                continue
            checked += 1
            assert np.linalg.norm(_centroid(mask) - uv) < 3.0, (uv, _centroid(mask))
            # the cube's visible faces lie within 2.5 cm of its centre along the view axis
            assert float(np.median(depth[row][mask])) == pytest.approx(z, abs=0.04)
    assert len(set(seen)) >= 25 and checked >= 12  # the resets really moved the cube; most in full view


def test_front_head_view_at_reset_sees_the_scene_upright(cam_env):
    env = cam_env
    env.reset()
    names = env.sensors.cameras.segmentation_names
    seg = env.sensors.images["front_head_segmentation"].numpy()
    for row in range(env.num_envs):
        ids = {names[i] for i in np.unique(seg[row])}
        assert {"cube", "blue_block", "table", "robot/left_gripper"} <= ids, ids
        table = seg[row] == names.index("table")
        assert table[H // 2 :].sum() > 0.6 * table.sum()  # the table lies below the horizon
        ground = seg[row] == names.index("ground")
        assert ground[: H // 2].sum() > 0.9 * ground.sum()  # the far floor above it
        # the cube (robot's left, y > 0.1) is in the image's left half, left of the block (y = -0.08)
        cube_u = _centroid(seg[row] == names.index("cube"))[0]
        block_u = _centroid(seg[row] == names.index("blue_block"))[0]
        assert cube_u < W / 2 and cube_u < block_u
    env.sensors.cameras.randomize = False  # the model's own colours (randomize=True also randomises the look)
    try:
        rgb = env.sensors.images["front_head_rgb"].numpy()
    finally:
        env.sensors.cameras.randomize = True
    red = rgb[0][seg[0] == names.index("cube")].astype(int)
    assert (red[:, 0] > red[:, 1] + 40).all()  # the cube renders red


def test_left_wrist_view_sees_the_cube_while_grasping(cam_env):
    """The expert's grasp: at the step each row's ``grasped_cube`` signal turns on, the cube is in its wrist view,
    between the fingers (the middle third of the image)."""
    env = cam_env
    env.reset()
    agent = expert_agent(env)
    agent.reset()
    names = env.sensors.cameras.segmentation_names
    k = env.task.signal_names.index("grasped_cube")
    checked = set()
    for _ in range(150):
        env.step(agent.act(env))
        for row in set(np.nonzero(env.info["signals"][:, k].numpy() > 0.5)[0].tolist()) - checked:
            cube = env.sensors.images["left_wrist_segmentation"][row].numpy() == names.index("cube")
            assert cube.sum() >= 20, f"row {row}: cube hardly in the wrist view"
            assert W / 3 < _centroid(cube)[0] < 2 * W / 3
            checked.add(row)
        if len(checked) == env.num_envs:
            break
    assert checked == {0, 1}


def test_state_only_envs_do_no_camera_work(stack_env):
    stack_env.reset()
    stack_env.step(stack_env.current_action())
    assert stack_env.sensors.image_terms == {} and stack_env.render() == {}
    assert not stack_env.sensors.cameras.built  # no sensor, no buffers, no graph
    with pytest.raises(KeyError, match="renders none") as err:
        stack_env.sensors.images["front_head_rgb"]
    assert "\n" not in str(err.value)


# ---------------------------------------------------------------- bad input (no env build)
@pytest.mark.parametrize(
    "task, cameras, message",
    [
        (PICK, {"head_cam": (96, 72)}, "unknown camera 'head_cam'"),
        (PICK, {"front_head": (0, 72)}, "resolution must be"),
        (PICK, {"front_head": (-96, 72)}, "resolution must be"),
        (PICK, {"front_head": (100_000, 72)}, "resolution must be"),
        (PICK, {"front_head": (96,)}, "resolution must be"),
        (PICK, {"front_head": "96x72"}, "resolution must be"),
        (PICK, {"front_head": (96.0, 72)}, "resolution must be"),
        (PICK, {"front_head": {"data": ("rgb", "infrared")}}, "data must be"),
        (PICK, {"front_head": {"fov": 1.0}}, "unknown keys"),
        (PICK, "front_head", "use none, default or <camera>="),
        (PICK, 3, "cameras must be"),
        ("GalbotG1-StackCube-v0", {"head_cam": (96, 72)}, "unknown camera 'head_cam'"),
    ],
)
def test_bad_camera_requests_raise_one_line(task, cameras, message):
    cfg = lookup(task).make_cfg(None)
    with pytest.raises(ValueError, match=message) as err:
        resolve_cameras(cfg, cameras)
    assert "\n" not in str(err.value)


def test_camera_sets_per_task_and_overrides():
    def cams(task, cameras=None):
        return resolve_cameras(lookup(task).make_cfg(None), cameras)

    for task in (PICK, "GalbotG1-PickCube-Mimic-v0", "GalbotG1-PickToShelf-v0", "GalbotG1-PickToShelf-Nav-v0"):
        c = cams(task)["front_head"]
        assert (c.width, c.height, c.data) == (298, 224, ("rgb",)), task
    for task in ("GalbotG1-SortToShelf-v0", "GalbotG1-SortToShelf-Place-v0"):
        assert cams(task)["front_head"].data == ALL, task
    for task in ("GalbotG1-StackCube-v0", "GalbotG1-BaseNav-v0", "GalbotG1-Reach-v0"):
        assert cams(task) == {}, task
    # a state-only task renders the cameras it is asked for (StackCube from pixels)
    stack = cams("GalbotG1-StackCube-v0", "front_head=96x72:rgb,left_wrist=96x72:rgb")
    assert {k: (c.width, c.height, c.data) for k, c in stack.items()} == {
        "front_head": (96, 72, ("rgb",)),
        "left_wrist": (96, 72, ("rgb",)),
    }
    assert cams(PICK, False) == {}
    small = cams(PICK, {"front_head": (96, 72)})["front_head"]
    assert (small.width, small.height, small.data) == (96, 72, ("rgb",))
    assert set(cams(PICK, {"left_wrist": (64, 48)})) == {"front_head", "left_wrist"}
    assert cams(PICK, "none") == {} and cams(PICK, "default") == cams(PICK)  # the CLI's text form, as make_env takes it
    text = cams(PICK, "front_head=96x72:rgb+depth")["front_head"]
    assert (text.width, text.height, text.data) == (96, 72, ("rgb", "depth"))


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--camera", "nose_cam"], "--camera 'nose_cam' is unknown"),
        (["--resolution", "0", "72"], "--resolution takes width and height"),
        (["--resolution", "96"], "--resolution takes width and height"),
        (["--resolution", "96", "72000"], "--resolution takes width and height"),
        (["--out", "frame.jpg"], "the picture is a PNG"),
    ],
)
def test_render_command_refuses_bad_input_in_one_line(argv, message, capsys, tmp_path):
    from newton_lab.cli import main

    out = ["--out", str(tmp_path / "x.png")] if "--out" not in argv else []
    assert main(["render", *argv, *out]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err, err
    assert not (tmp_path / "x.png").exists()


def test_render_command_draws_the_frame_under_an_env_perturbation(tmp_path, capsys):
    """``render --perturb surface_texture=mild``: the RGB panel of the PNG changes, its depth and segmentation
    panels do not, and the JSON line names the perturbation."""
    import json

    import numpy as np
    from PIL import Image

    from newton_lab.cli import main

    panels = {}
    for name, extra in (("plain", []), ("textured", ["--perturb", "surface_texture=mild"])):
        out = tmp_path / f"{name}.png"
        argv = ["render", "--device", "cpu", "--resolution", "96", "72", "--out", str(out), *extra]
        assert main(argv) == 0
        line = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
        assert line.get("perturbation") == ({"surface_texture": 10.0} if extra else None)
        image = np.asarray(Image.open(out))
        panels[name] = np.split(image, 3, axis=1)  # RGB | depth | segmentation
    rgb, depth, seg = (not np.array_equal(a, b) for a, b in zip(panels["plain"], panels["textured"]))
    assert rgb and not depth and not seg


# ---------------------------------------------------------------- vision randomisation
def _cube_colour(env, row):
    seg = env.sensors.images["front_head_segmentation"][row].numpy()
    cube = env.sensors.cameras.segmentation_names.index("cube")
    return env.sensors.images["front_head_rgb"][row].numpy()[seg == cube].mean(0)


def test_vision_randomisation_changes_per_reset_and_replays(cam_env):
    """randomize=True: each reset gives a row's cube another colour (and rows differ); the same seed and episode
    give bit-identical images; switched off, the model's colours come back."""
    env = cam_env
    env.reseed(21)
    first = {k: v.clone() for k, v in env.render().items()}
    c0 = [_cube_colour(env, r) for r in range(2)]
    assert np.abs(c0[0] - c0[1]).max() > 10  # rows look different
    env.reset()
    c1 = [_cube_colour(env, r) for r in range(2)]
    assert all(np.abs(a - b).max() > 10 for a, b in zip(c0, c1))  # a new episode, a new look
    env.reseed(21)  # the same seed and episodes: the same pictures
    for name, img in env.render().items():
        assert torch.equal(img, first[name]), name
    env.sensors.cameras.randomize = False
    try:
        red = _cube_colour(env, 0)
        assert red[0] > red[1] + 40  # the cube's own red
        assert np.array_equal(env.model.shape_color.numpy(), env.sensors.cameras.base_shape_colors.numpy())
    finally:
        env.sensors.cameras.randomize = True


def _angle_deg(q1, q2):
    return math.degrees(2 * math.acos(min(1.0, abs(float(np.dot(q1, q2))))))


def test_camera_jitter_is_bounded(cam_env):
    """Each view's pose is its nominal mount pose moved by <= 1 cm and turned by <= 1 deg, not zero, and new per
    reset."""
    env = cam_env
    moved = []
    for _ in range(3):
        env.reset()
        jittered = {c: env.sensors.cameras.poses(c).numpy().copy() for c in ("front_head", "left_wrist")}
        env.sensors.cameras.randomize = False
        try:
            nominal = {c: env.sensors.cameras.poses(c).numpy().copy() for c in jittered}
        finally:
            env.sensors.cameras.randomize = True
        for c in jittered:
            for row in range(env.num_envs):
                d = float(np.linalg.norm(jittered[c][row, :3] - nominal[c][row, :3]))
                a = _angle_deg(jittered[c][row, 3:], nominal[c][row, 3:])
                assert d <= 0.01 + 1e-5 and a <= 1.0 + 1e-3, (c, row, d, a)
                moved.append((round(d, 6), round(a, 4)))
    assert len(set(moved)) == len(moved) and all(d > 0 and a > 0 for d, a in moved)


def test_objects_named_by_their_colour_keep_its_hue():
    """SortToShelf's objects are named by colour (``EntityCfg.keep_hue``): vision randomisation scales each of
    their channels by at most +-20 % (times the row's brightness), while the table gets a new colour per reset."""
    env = make_env(
        "GalbotG1-SortToShelf-Pick-v0",
        num_envs=2,
        device="cpu",
        seed=3,
        randomize=True,
        cameras={"front_head": {"resolution": (32, 24), "data": ("rgb",)}},
    )
    names = env.sensors.cameras.segmentation_names
    objects = [names.index(n) for n in ("red_cube", "blue_cuboid", "yellow_cylinder", "green_cylinder")]
    env.sensors.cameras.randomize = False
    try:
        base = env.sensors.cameras.id_colors()[0]
    finally:
        env.sensors.cameras.randomize = True
    tables = []
    for _ in range(3):
        env.reset()
        colors = env.sensors.cameras.id_colors()
        for row in range(env.num_envs):
            for i in objects:
                ratio = colors[row, i] / base[i]
                assert ratio.max() / ratio.min() <= 1.2 / 0.8 + 1e-3, (names[i], colors[row, i], base[i])
                assert not np.allclose(ratio, 1.0), names[i]
        tables.append(colors[:, names.index("table")])
    assert np.abs(tables[0] - tables[1]).max() > 0.1 and np.abs(tables[1] - tables[2]).max() > 0.1


def test_stack_cube_from_pixels_sees_its_cubes_by_colour():
    """StackCube is state-only in the reference; asked for cameras with ``head="table"`` its front head sees all
    three cubes at reset (the level head sees none of them), and the cubes keep their hue under vision
    randomisation: which cube goes where is named by colour."""

    def seen(head):
        env = make_env(
            "GalbotG1-StackCube-v0",
            task_options={"head": head},
            num_envs=2,
            device="cpu",
            seed=3,
            randomize=True,
            cameras={"front_head": {"resolution": (96, 72), "data": ("segmentation",)}},
        )
        names = env.sensors.cameras.segmentation_names
        seg = env.sensors.images["front_head_segmentation"].numpy()
        return env, names, [{names[i] for i in np.unique(seg[row])} for row in range(env.num_envs)]

    cubes = {"cube_1", "cube_2", "cube_3"}
    _, _, level = seen("level")
    assert all(not (ids & cubes) for ids in level), level
    env, names, table = seen("table")
    assert all(cubes <= ids for ids in table), table
    env.sensors.cameras.randomize = False
    try:
        base = env.sensors.cameras.id_colors()[0]
    finally:
        env.sensors.cameras.randomize = True
    colors = env.sensors.cameras.id_colors()
    for row in range(env.num_envs):
        for cube in sorted(cubes):
            i = names.index(cube)
            assert np.argmax(colors[row, i]) == np.argmax(base[i]), (cube, colors[row, i], base[i])
            ratio = colors[row, i] / base[i]
            assert ratio.max() / ratio.min() <= 1.2 / 0.8 + 1e-3, (cube, colors[row, i], base[i])
