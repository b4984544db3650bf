"""rerun recordings, read back with rerun's own reader: one entity per model shape (every geometry type),
body transforms and per-row scalars every step, episode events, a default blueprint; replaying a dataset
episode reproduces its recorded states."""

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
    return {c.entity_path: c.archetype.rsplit(".", 1)[-1] for c in cols
            if c.is_static and c.archetype.rsplit(".", 1)[-1] in GEOMETRY}


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
    for part in ("leg_link5/collision/torso", "base_footprint/collision/chassis", "left_arm_link3/collision/",
                 "right_arm_link7/collision/right_palm", "head_link2/visual/", "static/visual/table", "cube/visual/"):
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
        "visual/box": "Boxes3D", "collision/ball": "Ellipsoids3D", "visual/capsule": "Capsules3D",
        "visual/cylinder": "Cylinders3D", "visual/cone": "Mesh3D", "visual/ellipsoid": "Ellipsoids3D",
        "visual/mesh": "Mesh3D", "visual/hull": "Mesh3D", "site/tcp": "Ellipsoids3D", "visual/hf": "Mesh3D",
        "visual/ground_plane": "Mesh3D"}
    assert logged.hidden == ["world/0/link/collision/ball"]


def test_view_replays_recorded_states_and_logs_episode_events(pick_env, tmp_path):
    live = tmp_path / "collect.rrd"
    logger = RerunLogger(pick_env, save=live, max_worlds=2)
    ref = pick_env.collect(agent=PlannerAgent.from_task(pick_env.task_id), episodes=1, path=tmp_path / "d.hdf5",
                           max_steps=400, progress=False, on_step=logger.on_step)
    logger.close()
    ep = read_episode(ref.path, 0)
    ended = [t for t in _texts(live) if " episode 1 succeeded (" in t or " episode 1 failed (" in t]
    assert len(ended) >= 1 and f"after {ep['attrs']['num_samples']} steps" in " ".join(ended)
    rrd = tmp_path / "replay.rrd"
    poses = replay_episode(ref.path, 0, save=rrd)
    cube = pick_env.entities["cube"].body
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
    logger = RerunLogger(pick_env, save=rrd, max_worlds=2, episodes_per_row=1)
    s = pick_env.evaluate(agent=ZeroAgent(), episodes=6, max_steps=4, progress=False, on_step=logger.on_step)
    logger.close()
    assert s["episodes"] == 6 and logger.finished
    ended = [t for t in _texts(rrd) if " succeeded (" in t or " failed (" in t]
    assert sorted(t.split(" episode")[0] for t in ended) == ["row 0", "row 1"], ended
    assert all(" episode 1 " in t for t in ended), ended
    assert _rows(rrd)["/world/0/cube"] == 4 and _rows(rrd)["/world/1/cube"] == 4  # one 4-step episode each
    with pytest.raises(ValueError, match="episodes_per_row"):
        RerunLogger(pick_env, save=tmp_path / "x.rrd", episodes_per_row=0)
