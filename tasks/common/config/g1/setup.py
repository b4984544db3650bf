"""The G1 set-up the tasks share: action terms by joint group, start postures by joint name, the wheel clip.

The G1-specific half of ``tasks/common`` (with ``postures`` and ``cameras`` beside it); the terms in
``tasks/common`` read the robot only through the task context.
"""

from __future__ import annotations

from newton_lab.robots.g1 import spec
from newton_lab.task_api.cfg import ActionTermCfg

from . import postures


def manipulation_posture(left_arm, head) -> dict[str, float]:
    """Fixed-base manipulation posture: legs 0, the given left arm and head, right arm stowed."""
    posture = dict(zip(spec.LEFT_ARM_JOINTS, left_arm))
    posture.update(zip(spec.RIGHT_ARM_JOINTS, spec.STOWED_RIGHT_ARM))
    posture.update(zip(spec.HEAD_JOINTS, head))
    return posture


def shelf_posture() -> dict[str, float]:
    """Mobile shelf tasks (PickToShelf, SortToShelf): left arm carry / ready, right arm stowed, head (0, 0.25),
    legs 0."""
    return manipulation_posture(postures.CARRY_LEFT_ARM, postures.SHELF_HEAD)


def left_arm_actions(*, gripper: bool = True) -> list[ActionTermCfg]:
    """Left arm absolute joint targets (7), plus the left gripper command (1) when ``gripper``."""
    terms = [ActionTermCfg(name="arm_action", group="left_arm", type="absolute")]
    if gripper:
        terms.append(ActionTermCfg(name="gripper_action", group="left_gripper", type="binary"))
    return terms


def base_actions(*, clip: bool = True) -> list[ActionTermCfg]:
    """The 4-wheel velocity action [rad/s], clipped to +-4.5 rad/s (= 0.45 m/s) unless ``clip`` is False."""
    lim = spec.WHEEL_VELOCITY_CLIP
    return [ActionTermCfg(name="base_action", group="base", type="velocity", clip=(-lim, lim) if clip else None)]


def carried_gripper_closed() -> dict[str, float]:
    """``TaskCfg.initial_targets`` of a task that starts with the object in the hand: the left gripper's drive
    target closed while its fingers rest on the object."""
    return {spec.LEFT_GRIPPER_JOINT: spec.GRIPPER_CLOSED}
