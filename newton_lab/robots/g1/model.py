"""Build the authored G1 into a Newton ``ModelBuilder`` and index its joints by name (``robots.binding.JointIndex``)."""

from __future__ import annotations

from collections.abc import Mapping
from importlib import resources

import newton
import warp as wp

from ..binding import JointIndex
from ..weld import weld_mjcf
from . import spec

__all__ = ["JointIndex", "PLANAR_BASE_JOINT", "add_g1", "apply_spec_limits", "build_g1", "joint_index", "mjcf_path"]


def mjcf_path() -> str:
    """Path of the packaged G1 MJCF."""
    return str(resources.files("newton_lab.assets").joinpath(spec.MJCF_FILE))


def add_g1(builder: newton.ModelBuilder, weld: Mapping[str, float] | None = None) -> None:
    """Add one G1 at the origin; its planar base coordinates (base_x, base_y, base_yaw) are its pose. The spec's
    joint limits beyond the MJCF ranges are written into Newton's limit fields (``apply_spec_limits``). ``weld``:
    joints welded at these values [rad | m] (``robots.weld``; the joints coupled to a kept one stay free)."""
    first_joint = builder.joint_count
    source = mjcf_path()
    if weld:
        everything = spec.ALL_JOINT_NAMES
        unknown = sorted(set(weld) - set(everything))
        if unknown:
            raise ValueError(f"cannot weld {unknown}: the G1 has no such joints; valid: {sorted(everything)}")
        source, _ = weld_mjcf(source, weld, keep=[j for j in everything if j not in weld])
    builder.add_mjcf(source, enable_self_collisions=False, xform=wp.transform_identity())
    apply_spec_limits(builder, first_joint)


def apply_spec_limits(builder: newton.ModelBuilder, first_joint: int = 0) -> None:
    """Write ``spec.JOINT_VELOCITY_LIMITS`` / ``spec.JOINT_EFFORT_LIMITS`` into the per-DOF
    ``joint_velocity_limit`` / ``joint_effort_limit`` of the robot added from joint ``first_joint`` on.

    SolverMuJoCo applies effort limits (actuator force range) but not velocity limits, so a velocity-limited
    joint's position drive becomes ``POSITION_VELOCITY``: the env moves its drive setpoint toward the command at
    no more than the limit and feeds the setpoint's velocity to the drive (``kernels.actions.drive_setpoints``).
    With a zero velocity target that drive is the same PD as the position-only one.
    """
    dof = {
        label.rsplit("/", 1)[-1]: builder.joint_qd_start[j]
        for j, label in enumerate(builder.joint_label)
        if j >= first_joint
    }
    unknown = sorted((set(spec.JOINT_VELOCITY_LIMITS) | set(spec.JOINT_EFFORT_LIMITS)) - set(spec.ALL_JOINT_NAMES))
    if unknown:
        raise ValueError(f"spec limits name joints the G1 model lacks: {unknown}; valid: {sorted(dof)}")
    position_only = int(newton.JointTargetMode.POSITION)
    for name, limit in spec.JOINT_VELOCITY_LIMITS.items():
        if name not in dof:  # welded: no degree of freedom to limit
            continue
        d = dof[name]
        builder.joint_velocity_limit[d] = float(limit)
        if builder.joint_target_mode[d] == position_only:
            builder.joint_target_mode[d] = int(newton.JointTargetMode.POSITION_VELOCITY)
    for name, limit in spec.JOINT_EFFORT_LIMITS.items():
        if name in dof:
            builder.joint_effort_limit[dof[name]] = float(limit)


PLANAR_BASE_JOINT = "base_x_base_y_base_yaw"
"""The one D6 joint the MJCF importer makes of the three planar base joints (``spec.BASE_PLANAR_JOINTS``)."""


def joint_index(builder: newton.ModelBuilder) -> JointIndex:
    """The ``JointIndex`` of a builder that holds the G1 (its planar base D6 split into base_x, base_y, base_yaw)."""
    return JointIndex.from_builder(builder, merged={PLANAR_BASE_JOINT: spec.BASE_PLANAR_JOINTS})


def build_g1(builder: newton.ModelBuilder, weld: Mapping[str, float] | None = None) -> JointIndex:
    """Add one G1 at the origin (``add_g1``, ``weld``: joints welded at these values) and index the builder's
    joints (``RobotBinding.build``)."""
    add_g1(builder, weld)
    return joint_index(builder)
