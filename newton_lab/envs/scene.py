"""Build a task's batched Newton model: one robot (the task's ``RobotBinding``) plus the task's entities per world,
replicated, with the task's contact filter (``TaskCfg.physics.contact_filter``) as Newton collision filter pairs."""

from __future__ import annotations

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
            raise ValueError(f"task {cfg.task_id!r} contact filter names robot group {group!r}; groups of "
                             f"{robot.name}: {sorted(groups)}")
        unknown = sorted(set(allowed) - targets)
        if unknown:
            raise ValueError(f"task {cfg.task_id!r} contact filter lets {group!r} touch {unknown}, which the scene "
                             f"lacks; targets: {sorted(targets)}")


def _filter_contacts(world: newton.ModelBuilder, cfg: TaskCfg, robot: RobotBinding, robot_shapes,
                     entity_shapes: dict[str, int]) -> list[int]:
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


def build_scene(cfg: TaskCfg, num_envs: int, device: str, robot: RobotBinding | None = None) -> SceneLayout:
    """Build, replicate ``num_envs`` times and finalize the task's scene (its robot and entities) on ``device``;
    ``robot``: the task's robot (``robot_binding(cfg.robot)``) when ``None``."""
    robot = robot_binding(cfg.robot) if robot is None else robot
    world = newton.ModelBuilder()
    newton.solvers.SolverMuJoCo.register_custom_attributes(world)
    world.rigid_gap = CONTACT_GAP
    joints = robot.build(world)
    robot_coords, robot_dofs = world.joint_coord_count, world.joint_dof_count

    for name, value in task_posture(cfg, robot).items():
        if name not in joints.coord:
            raise ValueError(f"task {cfg.task_id!r} posture names unknown joint {name!r}; valid: {sorted(joints.coord)}")
        world.joint_q[joints.coord[name]] = value
        if name not in robot.base_planar_joints:
            world.joint_target_q[joints.coord[name]] = value

    robot_shapes = world.shape_count
    entity_body, entity_coord, entity_dof, static_pose, half = [], [], [], [], []
    entity_shapes: dict[str, int] = {}
    for e in cfg.entities:
        n_joints = world.joint_count
        entity_shapes[e.name] = world.shape_count
        b = _add_entity(world, e)
        entity_body.append(b)
        if b >= 0:
            entity_coord.append(world.joint_q_start[n_joints])
            entity_dof.append(world.joint_qd_start[n_joints])
        else:
            entity_coord.append(-1)
            entity_dof.append(-1)
        static_pose.append((*e.pos, *e.quat))
        half.append(tuple(0.5 * s for s in e.size))

    off_ground = _filter_contacts(world, cfg, robot, range(robot_shapes), entity_shapes)

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
    model = scene.finalize(device=device)
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
        entity_body=entity_body,
        entity_coord=entity_coord,
        entity_dof=entity_dof,
        entity_static_pose=static_pose,
        entity_half_extents=half,
        default_q=np.asarray(world.joint_q, dtype=np.float32),
    )
