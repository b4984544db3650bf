"""The per-step view of the simulation that task terms read, and accessors on it.

Every task predicate, reward, observation and reset event is a ``@wp.func`` taking
``(ctx: TaskContext, w: int, ...)`` where ``w`` is the env row (world index). Worlds are laid out
contiguously, so a world-local index ``i`` maps to the flat index ``w * per_world + i``.
Entities (named rigid objects of the scene) are addressed by their slot ``k`` in the task's entity list.
"""

from __future__ import annotations

import warp as wp


@wp.struct
class TaskContext:
    body_q: wp.array(dtype=wp.transform)
    """Body poses, world frame (flat over worlds)."""
    body_qd: wp.array(dtype=wp.spatial_vector)
    joint_q: wp.array(dtype=float)
    """Joint coordinates (flat over worlds) [m | rad]."""
    joint_qd: wp.array(dtype=float)
    joint_target_q: wp.array(dtype=float)
    joint_target_qd: wp.array(dtype=float)
    bodies_per_world: int
    coords_per_world: int
    dofs_per_world: int
    robot_coords: int
    """Joint coordinates of the robot (the first ``robot_coords`` of each world)."""
    entity_body: wp.array(dtype=int)
    """World-local body index of each entity, -1 for a static entity."""
    entity_coord: wp.array(dtype=int)
    """World-local coordinate start of each dynamic entity's free joint, -1 if static."""
    entity_dof: wp.array(dtype=int)
    entity_static_pose: wp.array(dtype=wp.transform)
    """Pose of static entities (identical in every world)."""
    entity_half_extents: wp.array(dtype=wp.vec3)
    """Half sizes of each entity's box (or bounding box) [m]."""
    # ---- the robot half (with ``robot_coords``): described through the robot's binding (``RobotBinding``) and
    # filled by ``robots.bound.RobotContext.fill``; no robot's joint counts or ranges are written here
    base_coord: int
    """World-local coordinate of the planar base's x (its y and yaw follow: ``base_planar_joints``)."""
    lift_coords: wp.array(dtype=int)
    """World-local coordinates of the joints that lift the upper body (``RobotBinding.leg_joints``), in the
    binding's order; length 0 for a robot without them."""
    wheel_coord: int
    """World-local coordinate of the first base wheel (the others follow), -1 for a robot without wheels."""
    wheel_count: int
    """Base wheels (their coordinates are contiguous from ``wheel_coord``)."""
    tcp_body: int
    tcp_offset: wp.transform
    gripper_coord: int
    """World-local coordinate of the controlled arm's gripper master joint."""
    gripper_open: float
    """The gripper master joint's open value [rad] (``RobotBinding.gripper_open``)."""
    gripper_closed: float
    """The gripper master joint's closed value [rad] (``RobotBinding.gripper_closed``)."""
    finger_coords: wp.array(dtype=int)
    """World-local coordinates of the controlled gripper's finger slides (``Arm.fingers``); length 0 without."""
    finger_travel_per_rad: float
    """Finger slide travel per radian of the gripper master, nothing between the fingers [m/rad]."""
    fingertip_reach: float
    """How far the finger pads reach from the TCP along its approach axis (TCP +x) [m]."""
    arm_coords: wp.array(dtype=int)
    """World-local coordinates of the controlled arm's joints (``Arm.joints``, in order)."""
    arm_home: wp.array(dtype=float)
    """Reference arm posture used by carry / retract predicates [rad] (one value per ``arm_coords``)."""
    command: wp.array2d(dtype=float)
    """Per-row task command (e.g. a Reach goal) (num_envs, command_dim)."""
    actions: wp.array2d(dtype=float)
    prev_actions: wp.array2d(dtype=float)
    episode_step: wp.array(dtype=int)
    """Control steps taken in the current episode."""
    phase: wp.array(dtype=int)
    hold: wp.array2d(dtype=int)
    """Per-row counters for predicates that must hold for several consecutive steps."""


@wp.func
def entity_pose(ctx: TaskContext, w: int, k: int) -> wp.transform:
    """World pose of entity ``k`` in row ``w``."""
    b = ctx.entity_body[k]
    if b < 0:
        return ctx.entity_static_pose[k]
    return ctx.body_q[w * ctx.bodies_per_world + b]


@wp.func
def entity_pos(ctx: TaskContext, w: int, k: int) -> wp.vec3:
    return wp.transform_get_translation(entity_pose(ctx, w, k))


@wp.func
def entity_up_dot(ctx: TaskContext, w: int, k: int) -> float:
    """|local z . world z| of entity ``k`` (1 = upright)."""
    q = wp.transform_get_rotation(entity_pose(ctx, w, k))
    return wp.abs(wp.quat_rotate(q, wp.vec3(0.0, 0.0, 1.0))[2])


@wp.func
def base_pose2d(ctx: TaskContext, w: int) -> wp.vec3:
    """Planar base pose (x [m], y [m], yaw [rad]) of row ``w``, env frame."""
    b = w * ctx.coords_per_world + ctx.base_coord
    return wp.vec3(ctx.joint_q[b], ctx.joint_q[b + 1], ctx.joint_q[b + 2])


@wp.func
def wrap_angle(a: float) -> float:
    """``a`` wrapped to [-pi, pi)."""
    return a - 2.0 * wp.pi * wp.floor((a + wp.pi) / (2.0 * wp.pi))


@wp.func
def tcp_pose(ctx: TaskContext, w: int) -> wp.transform:
    """World pose of the controlled arm's TCP."""
    return wp.transform_multiply(ctx.body_q[w * ctx.bodies_per_world + ctx.tcp_body], ctx.tcp_offset)


@wp.func
def tcp_pos(ctx: TaskContext, w: int) -> wp.vec3:
    return wp.transform_get_translation(tcp_pose(ctx, w))


@wp.func
def tcp_distance(ctx: TaskContext, w: int, k: int) -> float:
    """|TCP - centre of entity ``k``| in row ``w`` [m]."""
    return wp.length(entity_pos(ctx, w, k) - tcp_pos(ctx, w))


@wp.func
def gripper_q(ctx: TaskContext, w: int) -> float:
    """Gripper master joint position [rad] (``ctx.gripper_open`` .. ``ctx.gripper_closed``)."""
    return ctx.joint_q[w * ctx.coords_per_world + ctx.gripper_coord]


@wp.func
def finger_lag(ctx: TaskContext, w: int) -> float:
    """How far the fingers stopped short of where the gripper master drives them, the smaller of the fingers' [m]:
    about 0 closing on nothing, the squeeze when an object is between them (1.6 cm on the G1 closed on a 5 cm cube);
    1 for a robot whose binding names no fingers (``Arm.fingers``: no way to tell)."""
    drive = ctx.finger_travel_per_rad * wp.abs(gripper_q(ctx, w) - ctx.gripper_open)
    lag = float(1.0)
    for k in range(ctx.finger_coords.shape[0]):
        travel = wp.abs(ctx.joint_q[w * ctx.coords_per_world + ctx.finger_coords[k]])
        lag = wp.min(lag, drive - travel)
    return lag


@wp.func
def finger_middle(ctx: TaskContext, w: int) -> float:
    """The middle between the two fingers along the TCP's y (their closing axis) [m]: half the first finger's travel
    less the second's (``Arm.fingers``: the first closes toward +y); 0 for a gripper without two named fingers."""
    middle = float(0.0)
    if ctx.finger_coords.shape[0] == 2:
        first = ctx.joint_q[w * ctx.coords_per_world + ctx.finger_coords[0]]
        second = ctx.joint_q[w * ctx.coords_per_world + ctx.finger_coords[1]]
        middle = 0.5 * (first - second)
    return middle


@wp.func
def in_tcp_frame(ctx: TaskContext, w: int, k: int) -> wp.vec3:
    """Centre of entity ``k`` in the TCP's frame [m]: x along the approach (palm to fingertips), y the fingers'
    closing axis."""
    return wp.transform_point(wp.transform_inverse(tcp_pose(ctx, w)), entity_pos(ctx, w, k))


@wp.func
def arm_near_home(ctx: TaskContext, w: int, tol: float) -> bool:
    """Every arm joint within ``tol`` [rad] of ``ctx.arm_home``."""
    ok = bool(True)
    for j in range(ctx.arm_coords.shape[0]):
        if wp.abs(ctx.joint_q[w * ctx.coords_per_world + ctx.arm_coords[j]] - ctx.arm_home[j]) > tol:
            ok = False
    return ok


@wp.func
def held_for(ctx: TaskContext, w: int, slot: int, cond: bool, steps: int) -> bool:
    """True once ``cond`` has held for ``steps`` consecutive calls (counter in ``ctx.hold[w, slot]``)."""
    if cond:
        ctx.hold[w, slot] = ctx.hold[w, slot] + 1
    else:
        ctx.hold[w, slot] = 0
    return ctx.hold[w, slot] >= steps


@wp.func
def row_diverged(ctx: TaskContext, w: int, max_dist: float, max_lin_speed: float, max_ang_speed: float) -> bool:
    """True when row ``w``'s simulation has diverged: any body position farther than ``max_dist`` [m] from the
    env origin (worlds share the world origin: the scene is replicated without spacing), any body linear speed
    above ``max_lin_speed`` [m/s] or angular speed above ``max_ang_speed`` [rad/s], or any non-finite body pose,
    body velocity, joint coordinate or joint velocity. Comparisons are written ``not (x <= bound)`` so NaN fails."""
    d2 = max_dist * max_dist
    v2 = max_lin_speed * max_lin_speed
    a2 = max_ang_speed * max_ang_speed
    bad = bool(False)
    b0 = w * ctx.bodies_per_world
    for i in range(ctx.bodies_per_world):
        t = ctx.body_q[b0 + i]
        v = ctx.body_qd[b0 + i]  # Newton twist: linear [m/s] first, angular [rad/s] last
        if not (wp.length_sq(wp.transform_get_translation(t)) <= d2):
            bad = True
        if not wp.isfinite(wp.transform_get_rotation(t)):
            bad = True
        if not (wp.length_sq(wp.spatial_top(v)) <= v2) or not (wp.length_sq(wp.spatial_bottom(v)) <= a2):
            bad = True
    c0 = w * ctx.coords_per_world
    for i in range(ctx.coords_per_world):
        if not wp.isfinite(ctx.joint_q[c0 + i]):
            bad = True
    q0 = w * ctx.dofs_per_world
    for i in range(ctx.dofs_per_world):
        if not wp.isfinite(ctx.joint_qd[q0 + i]):
            bad = True
    return bad


@wp.func
def write_vec3(out: wp.array2d(dtype=float), w: int, col: int, v: wp.vec3):
    for i in range(3):
        out[w, col + i] = v[i]


@wp.func
def write_transform(out: wp.array2d(dtype=float), w: int, col: int, t: wp.transform):
    """Write a pose as (x, y, z, qx, qy, qz, qw)."""
    p = wp.transform_get_translation(t)
    q = wp.transform_get_rotation(t)
    for i in range(3):
        out[w, col + i] = p[i]
    for i in range(4):
        out[w, col + 3 + i] = q[i]


@wp.kernel
def record_poses(ctx: TaskContext, tcp_out: wp.array2d(dtype=float), entity_out: wp.array3d(dtype=float)):
    """Per row: TCP pose (7) and every entity's pose (E, 7), world frame, xyzw."""
    w = wp.tid()
    write_transform(tcp_out, w, 0, tcp_pose(ctx, w))
    for k in range(entity_out.shape[1]):
        t = entity_pose(ctx, w, k)
        p = wp.transform_get_translation(t)
        q = wp.transform_get_rotation(t)
        for i in range(3):
            entity_out[w, k, i] = p[i]
        for i in range(4):
            entity_out[w, k, 3 + i] = q[i]


@wp.func
def entity_coord_pos(ctx: TaskContext, w: int, k: int) -> wp.vec3:
    """Entity ``k``'s position read from its free-joint coordinates (for a static entity, its fixed pose): what
    reset events see, since body poses follow the coordinates only after the reset's forward kinematics."""
    c = ctx.entity_coord[k]
    if c < 0:
        return wp.transform_get_translation(ctx.entity_static_pose[k])
    base = w * ctx.coords_per_world + c
    return wp.vec3(ctx.joint_q[base], ctx.joint_q[base + 1], ctx.joint_q[base + 2])


@wp.func
def set_entity_pose(ctx: TaskContext, w: int, k: int, p: wp.vec3, q: wp.quat):
    """Write a dynamic entity's free-joint coordinates (reset events); static entities are ignored."""
    c = ctx.entity_coord[k]
    if c < 0:
        return
    base = w * ctx.coords_per_world + c
    for i in range(3):
        ctx.joint_q[base + i] = p[i]
    for i in range(4):
        ctx.joint_q[base + 3 + i] = q[i]
