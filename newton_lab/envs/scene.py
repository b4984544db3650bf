"""Build a task's batched Newton model: one robot (the task's ``RobotBinding``) plus the task's entities per world,
replicated, with the task's contact filter (``TaskCfg.physics.contact_filter``) as Newton collision filter pairs."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import newton
import numpy as np
import warp as wp

from ..robots.binding import JointIndex, RobotBinding
from ..robots.registry import robot_binding
from ..task_api.cfg import EntityCfg, TaskCfg
from ..task_api.physics import ANY_OBJECT, GROUND, ContactFilterCfg

CONTACT_GAP = 0.005
"""Contact detection gap [m]. Newton's default (0.1 m) makes MuJoCo track every pair within 10 cm, which
fills the contact buffers with far-apart pairs (cubes 7 cm apart, the ground under the table)."""


@dataclass
class SceneLayout:
    """The finalized model and the world-local indices every kernel needs."""

    model: newton.Model
    robot: RobotBinding
    """The robot of every world (its coordinates come first in each world's row)."""
    joints: JointIndex
    """World-local coord / dof / body indices of the robot's joints and bodies."""
    robot_coords: int
    robot_dofs: int
    coords_per_world: int
    dofs_per_world: int
    bodies_per_world: int
    entity_names: list[str]
    entity_body: list[int]
    entity_coord: list[int]
    entity_dof: list[int]
    entity_static_pose: list[tuple]
    entity_half_extents: list[tuple]
    default_q: np.ndarray
    """Initial coordinates of one world (robot posture + entity poses)."""
    solver_model: newton.Model
    """The model the solver steps: ``model`` itself, or the same scene with the task's idle robot joints welded
    (``welded``) and the links they held merged into their parents (fewer coordinates and bodies, the same
    shapes)."""
    welded: tuple[str, ...] = ()
    """Robot joints welded in ``solver_model`` (``PhysicsCfg.weld_idle_joints``)."""
    solver_coord: list[int] | None = None
    """Per coordinate of one world of ``model``: its index in a world of ``solver_model``, -1 if welded (``None``:
    nothing welded)."""
    solver_dof: list[int] | None = None
    """Per DOF of one world of ``model``: its index in a world of ``solver_model``, -1 if welded."""


def _add_entity(builder: newton.ModelBuilder, e: EntityCfg) -> int:
    """Add ``e``; returns its body index, or -1 for a static collider."""
    hx, hy, hz = (0.5 * s for s in e.size)
    volume = (8.0 * hx * hy * hz) if e.shape == "box" else (math.pi * hx * hx * 2.0 * hz)
    cfg = newton.ModelBuilder.ShapeConfig(mu=e.friction, density=(e.mass / volume) if e.dynamic else 0.0)
    pose = wp.transform(wp.vec3(*e.pos), wp.quat(*e.quat))
    body = builder.add_body(xform=pose, label=e.name) if e.dynamic else -1
    local = wp.transform_identity() if e.dynamic else pose
    if e.shape == "box":
        builder.add_shape_box(body, xform=local, hx=hx, hy=hy, hz=hz, cfg=cfg, color=e.color, label=e.name)
    elif e.shape == "cylinder":
        builder.add_shape_cylinder(body, xform=local, radius=hx, half_height=hz, cfg=cfg, color=e.color, label=e.name)
    else:
        raise ValueError(f"entity {e.name!r} has unknown shape {e.shape!r}; use 'box' or 'cylinder'")
    return body


def robot_collision_groups(builder: newton.ModelBuilder, robot: RobotBinding, shapes) -> dict[int, str]:
    """The collision group (``ContactFilterCfg``) of each colliding robot shape among ``shapes``: its body's link
    group (``RobotBinding.link_group``) without the ``robot/`` prefix."""
    collide = int(newton.ShapeFlags.COLLIDE_SHAPES)
    out = {}
    for s in shapes:
        if builder.shape_flags[s] & collide:
            body = builder.body_label[builder.shape_body[s]].rsplit("/", 1)[-1]
            out[s] = robot.link_group(body).removeprefix("robot/")
    return out


def check_contact_filter(cfg: TaskCfg, robot: RobotBinding, contact_filter: ContactFilterCfg) -> None:
    """Raise a one-line ``ValueError`` if ``contact_filter`` names a robot group or a scene object that the task's
    robot or scene lacks."""
    groups = {g.removeprefix("robot/") for g in robot.link_groups}
    targets = {e.name for e in cfg.entities} | {ANY_OBJECT, GROUND}
    for group, allowed in contact_filter.robot.items():
        if group not in groups:
            raise ValueError(
                f"task {cfg.task_id!r} contact filter names robot group {group!r}; groups of "
                f"{robot.name}: {sorted(groups)}"
            )
        unknown = sorted(set(allowed) - targets)
        if unknown:
            raise ValueError(
                f"task {cfg.task_id!r} contact filter lets {group!r} touch {unknown}, which the scene "
                f"lacks; targets: {sorted(targets)}"
            )


def _filter_contacts(
    world: newton.ModelBuilder, cfg: TaskCfg, robot: RobotBinding, robot_shapes, entity_shapes: dict[str, int]
) -> list[int]:
    """Add the collision filter pairs of the task's contact filter (``cfg.physics.contact_filter``) between the
    robot's shapes and the scene objects' to the one-world builder; returns the robot shapes that may not touch
    the ground (filtered once the shared ground plane exists). No filter: nothing is added."""
    contact_filter = cfg.physics.contact_filter
    if contact_filter is None:
        return []
    check_contact_filter(cfg, robot, contact_filter)
    groups = robot_collision_groups(world, robot, robot_shapes)
    for shape, group in groups.items():
        for name, other in entity_shapes.items():
            if not contact_filter.allows(group, name):
                world.add_shape_collision_filter_pair(shape, other)
    return [shape for shape, group in groups.items() if not contact_filter.allows(group, GROUND)]


def task_posture(cfg: TaskCfg, robot: RobotBinding) -> dict[str, float]:
    """The robot's joint values at reset by joint name: the planar base at the task's root pose [m, m, rad], then
    the task's posture [rad | m]."""
    base_x, base_y, base_yaw = robot.base_planar_joints
    return {base_x: cfg.root_pos[0], base_y: cfg.root_pos[1], base_yaw: cfg.root_yaw, **cfg.posture}


def welded_joints(cfg: TaskCfg, robot: RobotBinding, joints: JointIndex, default_q) -> dict[str, float]:
    """The robot joints the task asks to weld (``cfg.physics.weld_idle_joints``) and their values [rad | m]: every
    joint no action term drives (the wheels drive the planar base; a free base stays free), at its reset value in
    ``default_q`` (one world's coordinates). Empty when the task welds nothing. The robot's build keeps the joints
    coupled to a driven one free (a gripper's fingers): ``SceneLayout.welded`` lists what was welded."""
    if not cfg.physics.weld_idle_joints:
        return {}
    driven = {j for term in cfg.actions for j in robot.joint_groups[term.group]}
    if driven & set(robot.base_wheel_joints) or not cfg.fixed_base:
        driven |= set(robot.base_planar_joints)
    return {name: float(default_q[c]) for name, c in joints.coord.items() if name not in driven}


def _one_world(cfg: TaskCfg, robot: RobotBinding, weld: dict[str, float] | None = None):
    """One world's builder (robot in the task's posture, entities, the contact filter's pairs), its joint index,
    per-entity indices and the robot shapes that may not touch the ground. ``weld``: robot joints welded at these
    values (``RobotBinding.build``)."""
    world = newton.ModelBuilder()
    newton.solvers.SolverMuJoCo.register_custom_attributes(world)
    world.rigid_gap = CONTACT_GAP
    joints = robot.build(world, weld) if weld else robot.build(world)
    robot_coords, robot_dofs = world.joint_coord_count, world.joint_dof_count

    for name, value in task_posture(cfg, robot).items():
        if weld and name in weld and name not in joints.coord:
            continue  # welded: folded into its body's pose
        if name not in joints.coord:
            raise ValueError(
                f"task {cfg.task_id!r} posture names unknown joint {name!r}; valid: {sorted(joints.coord)}"
            )
        world.joint_q[joints.coord[name]] = value
        if name not in robot.base_planar_joints:
            world.joint_target_q[joints.coord[name]] = value

    robot_shapes = world.shape_count
    entities = {"body": [], "coord": [], "dof": []}
    entity_shapes: dict[str, int] = {}
    for e in cfg.entities:
        n_joints = world.joint_count
        entity_shapes[e.name] = world.shape_count
        b = _add_entity(world, e)
        entities["body"].append(b)
        entities["coord"].append(world.joint_q_start[n_joints] if b >= 0 else -1)
        entities["dof"].append(world.joint_qd_start[n_joints] if b >= 0 else -1)
    off_ground = _filter_contacts(world, cfg, robot, range(robot_shapes), entity_shapes)
    return world, joints, (robot_coords, robot_dofs), entities, off_ground


def _replicate(world: newton.ModelBuilder, off_ground: list[int], num_envs: int, device: str) -> newton.Model:
    """``num_envs`` copies of ``world`` on the shared ground plane, finalized on ``device``."""
    scene = newton.ModelBuilder()
    newton.solvers.SolverMuJoCo.register_custom_attributes(scene)
    scene.rigid_gap = CONTACT_GAP
    scene.replicate(world, num_envs)
    ground = scene.add_ground_plane()
    if off_ground:
        per_world = world.shape_count  # replicate lays the worlds' shapes out block by block
        assert scene.shape_world[per_world * (num_envs - 1)] == num_envs - 1
        for start in range(0, per_world * num_envs, per_world):
            for shape in off_ground:
                scene.add_shape_collision_filter_pair(start + shape, ground)
    return scene.finalize(device=device)


def _joint_map(full: newton.ModelBuilder, solver: newton.ModelBuilder) -> tuple[list[int], list[int]]:
    """For every coordinate and DOF of one full world: its index in the welded world, -1 where welded. Joints are
    matched by label."""

    def spans(b: newton.ModelBuilder):
        q = list(b.joint_q_start) + [b.joint_coord_count]
        qd = list(b.joint_qd_start) + [b.joint_dof_count]
        return {label: (q[j], q[j + 1], qd[j], qd[j + 1]) for j, label in enumerate(b.joint_label)}

    coord, dof = [-1] * full.joint_coord_count, [-1] * full.joint_dof_count
    kept = spans(solver)
    for label, (q0, q1, d0, d1) in spans(full).items():
        if label in kept and q1 > q0:
            s0, s1, t0, t1 = kept[label]
            if (s1 - s0, t1 - t0) != (q1 - q0, d1 - d0):
                continue  # a multi-DOF joint the weld changed (the planar base): welded as a whole
            coord[q0:q1] = range(s0, s1)
            dof[d0:d1] = range(t0, t1)
    return coord, dof


def build_scene(cfg: TaskCfg, num_envs: int, device: str, robot: RobotBinding | None = None) -> SceneLayout:
    """Build, replicate ``num_envs`` times and finalize the task's scene (its robot and entities) on ``device``;
    ``robot``: the task's robot (``robot_binding(cfg.robot)``) when ``None``. The solver steps this model until
    ``with_welded_solver`` gives it a welded one."""
    robot = robot_binding(cfg.robot) if robot is None else robot
    world, joints, (robot_coords, robot_dofs), entities, off_ground = _one_world(cfg, robot)
    model = _replicate(world, off_ground, num_envs, device)
    return SceneLayout(
        model=model,
        robot=robot,
        joints=joints,
        robot_coords=robot_coords,
        robot_dofs=robot_dofs,
        coords_per_world=world.joint_coord_count,
        dofs_per_world=world.joint_dof_count,
        bodies_per_world=world.body_count,
        entity_names=[e.name for e in cfg.entities],
        entity_body=entities["body"],
        entity_coord=entities["coord"],
        entity_dof=entities["dof"],
        entity_static_pose=[(*e.pos, *e.quat) for e in cfg.entities],
        entity_half_extents=[tuple(0.5 * s for s in e.size) for e in cfg.entities],
        default_q=np.asarray(world.joint_q, dtype=np.float32),
        solver_model=model,
    )


def with_welded_solver(
    cfg: TaskCfg, layout: SceneLayout, reset_q: np.ndarray, num_envs: int, device: str
) -> SceneLayout:
    """``layout`` with a solver model in which the task's idle robot joints (``welded_joints``) are welded at
    their reset values ``reset_q`` (one world's coordinates at reset: posture and scenario); ``layout`` itself when
    the task welds nothing."""
    weld = welded_joints(cfg, layout.robot, layout.joints, reset_q)
    if not weld:
        return layout
    world, _, _, _, _ = _one_world(cfg, layout.robot)
    welded_world, _, _, _, off_ground = _one_world(cfg, layout.robot, weld)
    shapes = welded_world.shape_count
    # a welded link rides its parent rigidly: merged into it, it costs the solver nothing (PickCube: 35 -> 11 bodies
    # a world); shapes keep their indices (the contact filter's pairs and ground list stay valid)
    welded_world.collapse_fixed_joints()
    if welded_world.shape_count != shapes:
        raise RuntimeError("collapsing the welded links changed the shapes; the contact filter would not apply")
    solver_coord, solver_dof = _joint_map(world, welded_world)
    welded = tuple(name for name in weld if solver_coord[layout.joints.coord[name]] < 0)
    return dataclasses.replace(
        layout,
        solver_model=_replicate(welded_world, off_ground, num_envs, device),
        welded=welded,
        solver_coord=solver_coord,
        solver_dof=solver_dof,
    )
