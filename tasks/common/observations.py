"""Observation terms every G1 task can list: ``func(ctx, w, out, col)`` writes its columns."""

from __future__ import annotations

import warp as wp
from newton_lab.kernels.context import (
    TaskContext,
    entity_pos,
    entity_pose,
    gripper_q,
    tcp_pose,
    write_transform,
    write_vec3,
)

from newton_lab.task_api.cfg import ACTION_DIM, ARM_JOINTS, ROBOT_COORDS, ObsTermCfg
from newton_lab.task_api.terms import term_factory


@wp.func
def last_action(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """The action applied in the last step (action_dim)."""
    for j in range(ctx.actions.shape[1]):
        out[w, col + j] = ctx.actions[w, j]


@wp.func
def robot_joint_pos(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """Every robot coordinate in model order (robot_coords) [m | rad], the base wheels' angles zeroed (as on the
    reference platform): a wheel's angle is the integral of every drive so far, the same pose reached by another
    path reads another angle, and a policy conditioned on it sees noise (SortToShelf's place phase: 1-9 mrad
    apart after the same nav, where the demos spanned 0.06 mrad)."""
    for j in range(ctx.robot_coords):
        value = ctx.joint_q[w * ctx.coords_per_world + j]
        if j >= ctx.wheel_coord and j < ctx.wheel_coord + ctx.wheel_count:
            value = float(0.0)
        out[w, col + j] = value


@wp.func
def robot_joint_vel(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """Every robot DOF velocity in model order (robot_coords) [m/s | rad/s]."""
    for j in range(ctx.robot_coords):
        out[w, col + j] = ctx.joint_qd[w * ctx.dofs_per_world + j]


@wp.func
def arm_joint_pos(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """The controlled arm's joint positions (arm_joints) [rad]."""
    for j in range(ctx.arm_coords.shape[0]):
        out[w, col + j] = ctx.joint_q[w * ctx.coords_per_world + ctx.arm_coords[j]]


@wp.func
def gripper_pos(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """Gripper master joint (1) [rad]."""
    out[w, col] = gripper_q(ctx, w)


@wp.func
def tcp_pose_obs(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """TCP pose (7): x, y, z, qx, qy, qz, qw, world frame."""
    write_transform(out, w, col, tcp_pose(ctx, w))


@term_factory(entities=("entity",))
def entity_pose_obs(*, entity: int):
    """``entity``'s pose (7): x, y, z, qx, qy, qz, qw, world frame."""

    @wp.func
    def pose_of_entity(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
        write_transform(out, w, col, entity_pose(ctx, w, entity))

    return pose_of_entity


@term_factory(entities=("entities",))
def entity_positions_obs(*, entities: tuple[int, ...]):
    """The centres of ``entities`` (3 each), world frame [m]."""
    n = len(entities)

    @wp.func
    def positions_of_entities(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
        for i in range(wp.static(n)):
            write_vec3(out, w, col + 3 * i, entity_pos(ctx, w, wp.static(entities[i])))

    return positions_of_entities


@term_factory(entities=("entities",))
def entity_orientations_obs(*, entities: tuple[int, ...]):
    """The quaternions of ``entities`` (4 each, xyzw), world frame."""
    n = len(entities)

    @wp.func
    def orientations_of_entities(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
        for i in range(wp.static(n)):
            q = wp.transform_get_rotation(entity_pose(ctx, w, wp.static(entities[i])))
            for j in range(4):
                out[w, col + 4 * i + j] = q[j]

    return orientations_of_entities


def pose_of(entity: str) -> ObsTermCfg:
    """Observation term: the pose (7) of the scene object ``entity``, world frame (privileged, like the three
    below: ``obs_mode="sensors"`` drops it)."""
    return ObsTermCfg(func=entity_pose_obs, params={"entity": entity}, size=7, privileged=True)


def position_of(entity: str) -> ObsTermCfg:
    """Observation term: the centre (3) of the scene object ``entity``, world frame [m]."""
    return ObsTermCfg(func=entity_positions_obs, params={"entities": (entity,)}, size=3, privileged=True)


def positions_of(*entities: str) -> ObsTermCfg:
    """Observation term: the centres (3 each) of the scene objects ``entities``, world frame [m]."""
    return ObsTermCfg(func=entity_positions_obs, params={"entities": entities}, size=3 * len(entities), privileged=True)


def orientations_of(*entities: str) -> ObsTermCfg:
    """Observation term: the quaternions (4 each, xyzw) of the scene objects ``entities``."""
    return ObsTermCfg(
        func=entity_orientations_obs, params={"entities": entities}, size=4 * len(entities), privileged=True
    )


LAST_ACTION = ObsTermCfg(func=last_action, size=ACTION_DIM)
ROBOT_JOINT_POS = ObsTermCfg(func=robot_joint_pos, size=ROBOT_COORDS)
ROBOT_JOINT_VEL = ObsTermCfg(func=robot_joint_vel, size=ROBOT_COORDS)
ARM_JOINT_POS = ObsTermCfg(func=arm_joint_pos, size=ARM_JOINTS)
TCP_POSE = ObsTermCfg(func=tcp_pose_obs, size=7)
GRIPPER_POS = ObsTermCfg(func=gripper_pos, size=1)


def manipulation_observations(**objects: ObsTermCfg) -> dict[str, ObsTermCfg]:
    """The left-arm manipulation observation: last action, robot joints, TCP pose (7), gripper (1), then the
    task's object terms."""
    return {
        "actions": LAST_ACTION,
        "robot_joint_pos": ROBOT_JOINT_POS,
        "tcp_pose": TCP_POSE,
        "gripper_pos": GRIPPER_POS,
        **objects,
    }
