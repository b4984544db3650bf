"""The env-side perturbation axes (``newton_lab.envs.perturb``), on real Newton models: each changes what it says
and nothing else (every other array of the models, every other picture), by the level (one for all rows or one per
row), reaches the MuJoCo solver, and is put back exactly; a state-only env refuses a camera axis and a sweep skips
those cells; bad levels are refused in one line."""

from __future__ import annotations

import subprocess
import sys

import newton
import numpy as np
import pytest
import torch
import warp as wp

from newton_lab.agents import expert_agent, perturbation_table
from newton_lab.agents.perturbed import usable_cells
from newton_lab.datasets import DatasetRef
from newton_lab.envs.perturb import MASS_ARRAYS, SIZE_ARRAYS, draw_levels, perturb_env, perturbed, randomize_env
from newton_lab.task_api.perturbations import AXES, LEVELS, parse_cells, parse_randomization

ENV_AXES = [name for name, axis in AXES.items() if axis.acts_on != "agent"]


@pytest.fixture(scope="module")
def camera_env():
    from newton_lab.envs import make_env

    return make_env(
        "GalbotG1-PickCube-v0",
        num_envs=2,
        device="cpu",
        seed=0,
        randomize=True,
        cameras="front_head=64x48:rgb+depth+segmentation",
    )


def _arrays(model) -> dict[str, np.ndarray]:
    """Every Warp array of a Newton model, copied to the host."""
    return {k: v.numpy().copy() for k, v in vars(model).items() if isinstance(v, wp.array)}


def _models(env):
    solver_model = env.sim.layout.solver_model
    return [env.model] if solver_model is env.model else [env.model, solver_model]


def _changed(before: dict, after: dict) -> set[str]:
    return {k for k in before if before[k].tobytes() != after[k].tobytes()}


def _object_bodies(model, name="cube"):
    return [b for b in range(model.body_count) if model.body_label[b] == name]


def test_object_mass_scales_the_objects_alone_per_row(pick_env):
    env = pick_env
    before = [_arrays(m) for m in _models(env)]
    solver_mass = env.solver.mjw_model.body_mass.numpy().copy()
    restore = perturb_env(env, {"object_mass": [1.5, 3.0]})
    for model, old in zip(_models(env), before, strict=True):
        new = _arrays(model)
        assert _changed(old, new) == set(MASS_ARRAYS)
        cubes = _object_bodies(model)
        world = model.body_world.numpy()[cubes]
        level = np.array([1.5, 3.0])[world]
        np.testing.assert_allclose(new["body_mass"][cubes], old["body_mass"][cubes] * level, rtol=1e-6)
        np.testing.assert_allclose(new["body_inertia"][cubes], old["body_inertia"][cubes] * level[:, None, None])
        np.testing.assert_allclose(new["body_inv_mass"][cubes], old["body_inv_mass"][cubes] / level, rtol=1e-6)
        others = [b for b in range(model.body_count) if b not in cubes]
        assert np.array_equal(new["body_mass"][others], old["body_mass"][others])
    ratio = env.solver.mjw_model.body_mass.numpy() / np.where(solver_mass > 0, solver_mass, 1.0)
    assert sorted({round(r, 4) for r in ratio[0]} - {0.0, 1.0}) == [1.5]  # world 0's cube only
    assert sorted({round(r, 4) for r in ratio[1]} - {0.0, 1.0}) == [3.0]
    restore()
    assert all(not _changed(old, _arrays(m)) for m, old in zip(_models(env), before, strict=True))
    assert np.array_equal(env.solver.mjw_model.body_mass.numpy(), solver_mass)


def test_friction_scales_every_shape_of_the_rows_but_the_ground(pick_env):
    env = pick_env
    before = [_arrays(m) for m in _models(env)]
    solver_mu = env.solver.mjw_model.geom_friction.numpy().copy()
    with perturbed(env, {"friction": AXES["friction"].strong}):
        for model, old in zip(_models(env), before, strict=True):
            new = _arrays(model)
            assert _changed(old, new) == {"shape_material_mu"}
            rows = model.shape_world.numpy() >= 0
            np.testing.assert_allclose(new["shape_material_mu"][rows], old["shape_material_mu"][rows] * 0.4)
            assert np.array_equal(new["shape_material_mu"][~rows], old["shape_material_mu"][~rows])
        ratio = env.solver.mjw_model.geom_friction.numpy()[..., 0] / solver_mu[..., 0]
        assert (
            set(np.round(ratio.astype(float), 4).ravel().tolist()) <= {0.4, 1.0} and (np.round(ratio, 4) == 0.4).any()
        )
    assert np.array_equal(env.solver.mjw_model.geom_friction.numpy(), solver_mu)


def _frames(env) -> dict[str, torch.Tensor]:
    return {k: v.clone() for k, v in env.sensors.cameras.render(force=True).items()}


def test_object_size_scales_the_objects_shapes_alone_per_row_the_solver_and_pictures_follow(camera_env):
    env = camera_env
    env.reseed(0)
    pictures = _frames(env)
    before = [_arrays(m) for m in _models(env)]
    solver_size = env.solver.mjw_model.geom_size.numpy().copy()
    with perturbed(env, {"object_size": [1.0, 0.7]}):
        for model, old in zip(_models(env), before, strict=True):
            new = _arrays(model)
            assert _changed(old, new) == set(SIZE_ARRAYS)
            cube = np.isin(model.shape_body.numpy(), _object_bodies(model))
            level = np.array([1.0, 0.7])[model.shape_world.numpy()[cube]]
            np.testing.assert_allclose(new["shape_scale"][cube], old["shape_scale"][cube] * level[:, None])
            assert np.array_equal(new["shape_scale"][~cube], old["shape_scale"][~cube])
        size = env.solver.mjw_model.geom_size.numpy()
        assert np.array_equal(size[0], solver_size[0])  # row 0 at level 1
        (changed,) = np.flatnonzero((size[1] != solver_size[1]).any(axis=1))  # row 1: the cube's one box
        np.testing.assert_allclose(size[1, changed], solver_size[1, changed] * 0.7, rtol=1e-6)
        env.reseed(0)
        after = _frames(env)
        for _ in range(25):  # the smaller cube drops onto the table
            env.step(env.current_action())
        cube_z = env.state.body_q.numpy()[_object_bodies(env.model), 2]
    assert all(torch.equal(after[k][0], pictures[k][0]) for k in pictures)
    assert not torch.equal(after["front_head_segmentation"][1], pictures["front_head_segmentation"][1])
    assert cube_z[0] - cube_z[1] == pytest.approx(0.3 * 0.025, abs=1e-3)  # 30 % of the 2.5 cm half height
    assert all(not _changed(old, _arrays(m)) for m, old in zip(_models(env), before, strict=True))
    assert np.array_equal(env.solver.mjw_model.geom_size.numpy(), solver_size)
    env.reseed(0)


@pytest.mark.parametrize(
    "axis", ["camera_shift", "camera_tilt", "camera_fov", "surface_texture", "light_intensity", "light_direction"]
)
def test_camera_and_light_axes_change_the_pictures_they_say(camera_env, axis):
    env = camera_env
    env.reseed(0)
    before, models = _frames(env), [_arrays(m) for m in _models(env)]
    with perturbed(env, {axis: AXES[axis].strong}, seed=1):
        after = _frames(env)
        assert all(not _changed(old, _arrays(m)) for m, old in zip(_models(env), models, strict=True))
    rgb, depth, seg = (f"front_head_{d}" for d in ("rgb", "depth", "segmentation"))
    assert not torch.equal(after[rgb], before[rgb])
    if AXES[axis].acts_on in ("light", "surface"):  # the colours change, not what the camera sees where
        assert torch.equal(after[depth], before[depth]) and torch.equal(after[seg], before[seg])
    else:
        assert not torch.equal(after[depth], before[depth])
        assert all(not torch.equal(after[depth][r], before[depth][r]) for r in range(env.num_envs))
    again = _frames(env)
    assert all(torch.equal(again[k], before[k]) for k in before)  # put back exactly


def test_surface_texture_patterns_the_fixed_surfaces_alone(camera_env):
    """The checkerboard changes the colour of pixels that see the ground or the table, and of no other pixel."""
    env = camera_env
    env.reseed(0)
    before = _frames(env)
    with perturbed(env, {"surface_texture": AXES["surface_texture"].mild}):
        after = _frames(env)
    names = env.sensors.cameras.segmentation_names
    seg = before["front_head_segmentation"]
    fixed = torch.zeros_like(seg, dtype=torch.bool)
    for name in ("ground", "table", "blue_block"):
        fixed |= seg == names.index(name)
    changed = (after["front_head_rgb"] != before["front_head_rgb"]).any(dim=-1)
    assert changed[fixed].any() and not changed[~fixed].any()


def test_camera_offsets_are_drawn_per_row_and_seeded(camera_env):
    env = camera_env
    env.reseed(0)
    shots = []
    for seed in (1, 1, 2):
        with perturbed(env, {"camera_shift": 5.0}, seed=seed):
            shots.append(env.sensors.cameras.poses("front_head").clone())
    base = env.sensors.cameras.poses("front_head").clone()
    moved = torch.linalg.norm(shots[0][:, :3] - base[:, :3], dim=1)
    torch.testing.assert_close(moved, torch.full_like(moved, 0.05), atol=1e-4, rtol=0)
    assert torch.equal(shots[0], shots[1]) and not torch.equal(shots[0], shots[2])
    assert not torch.allclose(shots[0][0, :3] - base[0, :3], shots[0][1, :3] - base[1, :3])


def test_a_state_only_env_refuses_a_camera_axis_and_a_sweep_skips_those_cells(pick_env, capsys):
    with pytest.raises(ValueError, match="renders none") as err:
        perturb_env(pick_env, {"camera_tilt": 2.0})
    assert "\n" not in str(err.value)
    kept = usable_cells(pick_env, parse_cells("sweep"))
    assert {a for c in kept for a in c.values} == {a for a in AXES if AXES[a].acts_on in ("agent", "physics", "scene")}
    assert "skipping" in capsys.readouterr().err


@pytest.mark.parametrize(
    "bad", ["object_mass=0", "friction=-0.5", "camera_fov=wide", "light_intensity=inf", "camera_shift=-2"]
)
def test_bad_levels_are_refused_in_one_line(bad):
    with pytest.raises(ValueError, match="--perturb") as err:
        parse_cells(bad)
    assert "\n" not in str(err.value)


def test_per_row_levels_only_where_the_renderer_allows(pick_env):
    with pytest.raises(ValueError, match="one for every row"):
        perturb_env(pick_env, {"light_intensity": [0.5, 0.8]})
    with pytest.raises(ValueError, match="3 levels for 2 rows"):
        perturb_env(pick_env, {"object_mass": [1.0, 2.0, 3.0]})


def test_the_sweep_has_rows_for_the_env_axes_and_puts_the_env_back(pick_env):
    env = pick_env
    cells = parse_cells("sweep")
    assert {c.label for c in cells} >= {f"{a}={lv}" for a in ENV_AXES for lv in LEVELS}
    picked = [c for c in cells if c.label in ("none", "object_mass=strong", "friction=strong", "camera_fov=mild")]
    before = [_arrays(m) for m in _models(env)]
    rows = perturbation_table(env, expert_agent(env), picked, seed=0, episodes=2, max_steps=60, progress=False)
    assert [r["perturbation"] for r in rows] == ["none", "object_mass=strong", "friction=strong"]
    assert rows[1]["values"] == {"object_mass": 3.0} and all(r["episodes"] == 2 for r in rows)
    assert all(not _changed(old, _arrays(m)) for m, old in zip(_models(env), before, strict=True))


# ------------------------------------------------------------------------------------ domain randomisation
def test_domain_randomization_takes_the_per_row_env_axes_only():
    assert parse_randomization("object_mass=mild, friction=0.5,camera_shift=strong") == {
        "object_mass": 1.5,
        "friction": 0.5,
        "camera_shift": 5.0,
    }
    for bad, words in [
        ("light_intensity=mild", "is not drawn per env row"),
        ("camera_fov=mild", "is not drawn per env row"),
        ("action_noise=mild", "is not drawn per env row"),
        ("wind=mild", "is not an axis"),
        ("object_mass", "write AXIS=LEVEL"),
        ("object_mass=0", "a factor"),
        ("friction=1,friction=2", "twice"),
    ]:
        with pytest.raises(ValueError, match="--domain-randomize") as err:
            parse_randomization(bad)
        assert words in str(err.value) and "\n" not in str(err.value)


def test_draws_are_per_row_seeded_and_within_the_level():
    a = draw_levels({"object_mass": 2.0, "camera_tilt": 3.0}, 64, seed=5)
    assert np.array_equal(a["object_mass"], draw_levels({"object_mass": 2.0}, 64, seed=5)["object_mass"])
    assert not np.array_equal(a["object_mass"], draw_levels({"object_mass": 2.0}, 64, seed=6)["object_mass"])
    assert ((a["object_mass"] >= 0.5) & (a["object_mass"] <= 2.0)).all()
    assert (a["object_mass"] < 1).any() and (a["object_mass"] > 1).any()  # both sides of the nominal
    assert ((a["camera_tilt"] >= 0) & (a["camera_tilt"] <= 3.0)).all() and np.ptp(a["camera_tilt"]) > 1.0


def test_randomize_env_gives_each_row_its_draw(pick_env):
    env = pick_env
    before = [_arrays(m) for m in _models(env)]
    restore = perturb_env(env, {})  # nothing: the same arrays
    restore()
    seed = env.seed
    draws = randomize_env(env, {"object_mass": 2.0, "friction": 0.5}, seed=3)
    try:
        assert set(draws) == {"object_mass", "friction"} and len(draws["object_mass"]) == env.num_envs
        assert draws["object_mass"][0] != draws["object_mass"][1]
        model, old = env.model, before[0]
        new = _arrays(model)
        cubes = _object_bodies(model)
        world = model.body_world.numpy()[cubes]
        np.testing.assert_allclose(
            new["body_mass"][cubes], old["body_mass"][cubes] * np.array(draws["object_mass"])[world], rtol=1e-5
        )
        shapes = model.shape_world.numpy()
        for w in range(env.num_envs):
            mine = shapes == w
            ratio = new["shape_material_mu"][mine] / old["shape_material_mu"][mine]
            np.testing.assert_allclose(ratio, draws["friction"][w], rtol=1e-5)
        assert _changed(old, new) == {*MASS_ARRAYS, "shape_material_mu"}
    finally:
        for model, arrays in zip(_models(env), before, strict=True):  # the fixture is shared: put it back
            for name in (*MASS_ARRAYS, "shape_material_mu"):
                getattr(model, name).assign(arrays[name])
        env.solver.notify_model_changed(newton.ModelFlags.BODY_INERTIAL_PROPERTIES | newton.ModelFlags.SHAPE_PROPERTIES)
        env.reseed(seed)  # and its seed (randomize_env reseeded it with 3)


def test_collect_records_the_rows_draws_in_the_dataset(tmp_path):
    path = tmp_path / "demos.hdf5"
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "newton_lab.cli",
            "collect",
            "--task",
            "GalbotG1-Reach-v0",
            "--episodes",
            "2",
            "--num-envs",
            "2",
            "--device",
            "cpu",
            "--randomize",
            "--max-steps",
            "150",
            "--domain-randomize",
            "friction=mild",
            "--dataset-path",
            str(path),
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    (entry,) = [p for p in DatasetRef.open(path).provenance if p.operation == "collect"]
    rows = entry.config["domain_randomization"]["friction"]
    assert len(rows) == 2 and all(0.7 <= r <= 1 / 0.7 for r in rows) and rows[0] != rows[1]


def test_the_robustness_page_is_generated_from_the_axes():
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    sys.path.insert(0, str(root / "tools"))  # tools/ is no package
    import docs_tables  # noqa: PLC0415

    table = docs_tables.perturbations_page()
    assert all(f"| `{name}` | {axis.acts_on} | {axis.unit} |" in table for name, axis in AXES.items())
    assert "<!-- generated: perturbations -->" in (root / "docs" / "robustness.md").read_text()
