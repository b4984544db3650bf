"""The env's side of the perturbation axes (``task_api.perturbations.AXES`` that act on ``"physics"``,
``"camera"`` or ``"light"``): ``perturb_env`` writes them into the env once, after it is built and before the
episodes it should change (an evaluation reseeds right after), and returns what puts everything back.

What each writes (nothing else changes; the captured step and render read the same arrays, written in place):
- ``object_mass``: ``body_mass``, ``body_inertia`` and their inverses of the dynamic entities' bodies, in the model
  and in the solver's model (its own when the task welds idle joints), then ``SolverMuJoCo.notify_model_changed``.
- ``object_size``: ``shape_scale`` and ``shape_collision_radius`` of the dynamic entities' shapes, likewise (the
  solver's geoms and the renderer read them; resets keep the objects' centre heights).
- ``friction``: ``shape_material_mu`` of every shape of the row's world (the global ground's kept), likewise.
- ``camera_shift`` / ``camera_tilt``: each view's pose in its mount body (``ViewGroup.view_offset``), moved by an
  offset drawn per camera and row from ``seed``; ``camera_fov``: the views' ray bundles (``ViewGroup.rays``).
- ``light_intensity`` / ``light_direction``: the cameras' one directional light (``Cameras.relight``).
- ``surface_texture``: the renderer's checkerboard on every shape fixed to the world
  (``SensorCamera.assign_checkerboard_material``, its render config's ``enable_textures`` on), ``Cameras.redraw``.

A level is one number (every row alike) or, for the axes that allow it (``Axis.per_row``), one per row: domain
randomisation draws those per row.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from contextlib import contextmanager

import newton
import numpy as np
import warp as wp

from ..task_api.perturbations import AXES, Axis
from ..tasks.common.distractors import distractor_count
from .cameras import Cameras

ENV_KINDS = ("physics", "camera", "surface", "light")
"""The kinds of axis the env applies to itself once built."""
SCENE_KINDS = ("scene",)
"""The kinds of axis the env is built with (``make_env(..., distractors=n)``); the rest act between the agent and the
env."""
MASS_ARRAYS = ("body_mass", "body_inertia", "body_inv_mass", "body_inv_inertia")
"""Model arrays ``object_mass`` rescales (the inverses by the reciprocal)."""
SIZE_ARRAYS = ("shape_scale", "shape_collision_radius")
"""Model arrays ``object_size`` rescales (a shape's size, and the bound its broad phase tests)."""


def env_axes(values: Mapping[str, object]) -> dict[str, object]:
    """The part of ``values`` (axis -> level) the env applies."""
    return {k: v for k, v in values.items() if k in AXES and AXES[k].acts_on in ENV_KINDS}


def scene_axes(values: Mapping[str, object]) -> dict[str, int]:
    """The part of ``values`` (axis -> level) that the env must be built with, as whole numbers."""
    return {k: int(v) for k, v in values.items() if k in AXES and AXES[k].acts_on in SCENE_KINDS}


def built_with(env) -> dict[str, int]:
    """What ``env`` was built with, per scene axis."""
    return {"distractors": distractor_count(env.cfg)}


def check_scene(env, values: Mapping[str, object]) -> None:
    """One-line error when ``values`` asks for a scene ``env`` was not built with."""
    for name, level in scene_axes(values).items():
        if built_with(env)[name] != level:
            raise ValueError(
                f"{name}={level}: this env was built with {built_with(env)[name]}; build it with "
                f"make_env(..., {name}={level}) (evaluate --perturb builds one per count)"
            )


def _levels(env, axis: Axis, value) -> np.ndarray:
    """(num_envs,) level of every row; one-line errors for a wrong count or a per-row level of a global axis."""
    rows = np.asarray(value, dtype=np.float64)
    if rows.ndim == 0:
        return np.full(env.num_envs, float(rows))
    if rows.shape != (env.num_envs,):
        raise ValueError(f"{axis.name}: {rows.size} levels for {env.num_envs} rows; give one, or one per row")
    if not axis.per_row and np.ptp(rows) > 0:
        raise ValueError(f"{axis.name} is one for every row (the renderer's); give a single level")
    return rows


def _models(env) -> list[newton.Model]:
    """The model and, when the task welds idle joints, the solver's own model (the same shapes, fewer bodies)."""
    solver_model = env.sim.layout.solver_model
    return [env.model] if solver_model is env.model else [env.model, solver_model]


def _object_bodies(model: newton.Model, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """(bodies, world of each) of the bodies labelled with an entity name in ``model``."""
    bodies = np.array([b for b in range(model.body_count) if model.body_label[b] in names], dtype=np.int64)
    return bodies, model.body_world.numpy()[bodies]


def _scale_masses(env, scale: np.ndarray) -> None:
    names = [e.name for e in env.task.entities.values() if e.dynamic]
    for model in _models(env):
        bodies, world = _object_bodies(model, names)
        for name in MASS_ARRAYS:
            arr = getattr(model, name)
            data = arr.numpy()
            factor = scale[world] if "inv" not in name else 1.0 / scale[world]
            data[bodies] *= factor.reshape((-1,) + (1,) * (data.ndim - 1))
            arr.assign(data)
    env.solver.notify_model_changed(newton.ModelFlags.BODY_INERTIAL_PROPERTIES)


def _scale_sizes(env, scale: np.ndarray) -> None:
    names = [e.name for e in env.task.entities.values() if e.dynamic]
    for model in _models(env):
        bodies, _ = _object_bodies(model, names)
        shapes = np.flatnonzero(np.isin(model.shape_body.numpy(), bodies))
        factor = scale[model.shape_world.numpy()[shapes]]
        for name in SIZE_ARRAYS:
            arr = getattr(model, name)
            data = arr.numpy()
            data[shapes] *= factor.reshape((-1,) + (1,) * (data.ndim - 1))
            arr.assign(data)
    env.solver.notify_model_changed(newton.ModelFlags.SHAPE_PROPERTIES)


def _scale_friction(env, scale: np.ndarray) -> None:
    for model in _models(env):
        world = model.shape_world.numpy()
        mu = model.shape_material_mu.numpy()
        mine = world >= 0
        mu[mine] *= scale[world[mine]]
        model.shape_material_mu.assign(mu)
    env.solver.notify_model_changed(newton.ModelFlags.SHAPE_PROPERTIES)


def _offset(rng: np.random.Generator, shift_m: float, tilt_rad: float) -> wp.transform:
    """A pose change of ``shift_m`` [m] along a random direction and ``tilt_rad`` [rad] about a random axis."""
    p, axis = rng.normal(size=3), rng.normal(size=3)
    p, axis = p / np.linalg.norm(p) * shift_m, axis / np.linalg.norm(axis)
    return wp.transform(wp.vec3(*p), wp.quat_from_axis_angle(wp.vec3(*axis), float(tilt_rad)))


def _move_cameras(cams: Cameras, shift_m: np.ndarray, tilt_rad: np.ndarray, seed: int) -> None:
    n = cams.num_envs
    for g in cams.view_groups:
        offsets = g.view_offset.numpy()
        for k, camera in enumerate(g.cameras):
            rng = np.random.default_rng([seed, list(cams.specs).index(camera)])
            for w in range(n):
                xf = wp.transform(wp.vec3(*offsets[k * n + w][:3]), wp.quat(*offsets[k * n + w][3:]))
                offsets[k * n + w] = wp.transform_multiply(xf, _offset(rng, shift_m[w], tilt_rad[w]))
        g.view_offset.assign(offsets)


def _widen_fov(cams: Cameras, widen_rad: float) -> None:
    """Spread the rays on the image plane so the horizontal field of view grows by ``widen_rad`` [rad]."""
    for g in cams.view_groups:
        half = math.atan(0.5 * g.width / cams.robot.camera_intrinsics(g.width, g.height)[0, 0])
        k = math.tan(half + 0.5 * widen_rad) / math.tan(half)
        rays = cams.robot.camera_rays(g.width, g.height).astype(np.float64)  # (H, W, 1, origin | direction, xyz)
        rays[..., :2] *= k
        rays[..., 1, :] /= np.linalg.norm(rays[..., 1, :], axis=-1, keepdims=True)
        g.rays.assign(rays.astype(np.float32))


def _texture(cams: Cameras, square_m: float | None) -> None:
    """A grey checkerboard of ``square_m`` [m] squares on every shape fixed to the world (``None``: none). Newton's
    renderer maps a box or plane face to texture coordinates in metres of the shape's frame, one texture a metre,
    so a texture of n x n texels, one a square, draws squares 1/n m wide."""
    config = cams.sensor.default_render_config
    config.enable_textures = square_m is not None
    if square_m is not None:
        fixed = np.flatnonzero(cams.model.shape_body.numpy() < 0)
        cams.sensor.assign_checkerboard_material(
            shape_indices=fixed, resolution=max(2, round(1.0 / square_m)), checker_size=1
        )
    cams.redraw()


def _turned(direction, turn_rad: float) -> tuple[float, float, float]:
    """``direction`` turned by ``turn_rad`` [rad] about the vertical."""
    x, y, z = direction
    c, s = math.cos(turn_rad), math.sin(turn_rad)
    return (c * x - s * y, s * x + c * y, z)


def _vision(env, levels: dict[str, np.ndarray], seed: int) -> Callable[[], None]:
    cams = env.sensors.cameras
    if not env.sensors.camera_specs:
        name = next(iter(levels))
        raise ValueError(
            f"{name} changes the cameras, but this env renders none (cameras=False or a state-only task); "
            f"build it with cameras, or leave {name} out"
        )
    cams.render()  # builds the views' buffers the camera axes write
    saved = [(g.view_offset.numpy().copy(), g.rays.numpy().copy()) for g in cams.view_groups]
    light = cams.light
    zero = np.zeros(env.num_envs)
    if "camera_shift" in levels or "camera_tilt" in levels:
        shift = levels.get("camera_shift", zero) / 100.0
        _move_cameras(cams, shift, np.radians(levels.get("camera_tilt", zero)), seed)
    if "camera_fov" in levels:
        _widen_fov(cams, math.radians(levels["camera_fov"][0]))
    if "light_intensity" in levels or "light_direction" in levels:
        turn = math.radians(levels.get("light_direction", zero)[0])
        cams.relight(_turned(light[0], turn), light[1] * levels.get("light_intensity", zero + 1.0)[0])
    textured = cams.sensor.default_render_config.enable_textures
    if "surface_texture" in levels and levels["surface_texture"][0] > 0:
        _texture(cams, levels["surface_texture"][0] / 100.0)
    cams.stale = True

    def restore() -> None:
        for g, (offsets, rays) in zip(cams.view_groups, saved, strict=True):
            g.view_offset.assign(offsets)
            g.rays.assign(rays)
        if cams.light != light:
            cams.relight(*light)
        if cams.sensor.default_render_config.enable_textures != textured:
            _texture(cams, None)
        cams.stale = True

    return restore


def _physics(env, levels: dict[str, np.ndarray]) -> Callable[[], None]:
    saved = [
        {name: getattr(m, name).numpy().copy() for name in (*MASS_ARRAYS, *SIZE_ARRAYS, "shape_material_mu")}
        for m in _models(env)
    ]
    if "object_mass" in levels:
        _scale_masses(env, levels["object_mass"])
    if "object_size" in levels:
        _scale_sizes(env, levels["object_size"])
    if "friction" in levels:
        _scale_friction(env, levels["friction"])

    def restore() -> None:
        for model, arrays in zip(_models(env), saved, strict=True):
            for name, data in arrays.items():
                getattr(model, name).assign(data)
        flags = newton.ModelFlags
        env.solver.notify_model_changed(flags.BODY_INERTIAL_PROPERTIES | flags.SHAPE_PROPERTIES)

    return restore


def perturb_env(env, values: Mapping[str, object], *, seed: int = 0) -> Callable[[], None]:
    """Apply the env's axes of ``values`` (axis name -> level in its unit, or one level per row; other axes are
    ignored) to ``env``; camera offsets are drawn from ``seed``. Returns a function that puts back everything it
    changed. The rows' current episodes keep their state: reset (``env.reseed``) before the episodes to change. A
    scene axis (``SCENE_KINDS``) is checked against what ``env`` was built with (``check_scene``)."""
    check_scene(env, values)
    levels = {k: _levels(env, AXES[k], v) for k, v in env_axes(values).items()}
    for name, rows in levels.items():
        bad = rows <= 0 if AXES[name].scale else rows < 0
        if bad.any() or not np.isfinite(rows).all():
            raise ValueError(f"{name}: levels are finite numbers {'> 0' if AXES[name].scale else '>= 0'}, got {rows}")
    physics = {k: v for k, v in levels.items() if AXES[k].acts_on == "physics"}
    vision = {k: v for k, v in levels.items() if AXES[k].acts_on != "physics"}
    undo = [_physics(env, physics)] if physics else []
    if vision:
        undo.append(_vision(env, vision, seed))

    def restore() -> None:
        for step in reversed(undo):
            step()

    return restore


@contextmanager
def perturbed(env, values: Mapping[str, object], *, seed: int = 0):
    """``perturb_env`` for the ``with`` block; everything is put back when it ends."""
    restore = perturb_env(env, values, seed=seed)
    try:
        yield env
    finally:
        restore()


def draw_levels(levels: Mapping[str, float], num_envs: int, *, seed: int = 0) -> dict[str, np.ndarray]:
    """A level per row of each axis up to ``levels`` (axis -> level in its unit), drawn from ``seed``: a factor
    log-uniform between 1 / level and level (both sides of the nominal), else a uniform magnitude in [0, level]."""
    rng = np.random.default_rng([seed, 0x5EED])
    out = {}
    for name, level in levels.items():
        u = rng.uniform(-1.0, 1.0, num_envs) if AXES[name].scale else rng.uniform(0.0, 1.0, num_envs)
        out[name] = np.exp(u * abs(math.log(level))) if AXES[name].scale else u * level
    return out


def randomize_env(env, levels: Mapping[str, float], *, seed: int = 0) -> dict[str, list[float]]:
    """Domain randomisation: each row of ``env`` gets its own draw (``draw_levels``) of every axis of ``levels``
    (``task_api.perturbations.parse_randomization``), kept for the env's life; then every row restarts the episodes
    of ``seed`` (``env.reseed``). Returns the draws (axis -> one level per row), for the dataset's provenance."""
    draws = draw_levels(levels, env.num_envs, seed=seed)
    perturb_env(env, draws, seed=seed)
    env.reseed(seed)
    return {name: [round(float(v), 6) for v in rows] for name, rows in draws.items()}


def collect_randomized(env, levels: Mapping[str, float], *, seed: int = 0, **collect: object):
    """``env.collect(**collect)`` under domain randomisation ``levels`` (``randomize_env``; none when empty), the
    rows' draws recorded in the dataset's provenance entry (``config["domain_randomization"]``)."""
    config = {"domain_randomization": randomize_env(env, levels, seed=seed)} if levels else None
    return env.collect(config=config, **collect)
