"""The reference table-top scene pieces (env frame, [m], [kg])."""

from __future__ import annotations

from newton_lab.task_api.cfg import ActionTermCfg, EntityCfg
from newton_lab.robots.g1 import spec

from . import postures

TABLE_TOP_Z = 0.10
CUBE_SIZE = 0.05
CUBE_MASS = 0.04


def table() -> EntityCfg:
    """0.8 x 1.0 x 0.05 static table, top at z = 0.10."""
    return EntityCfg(name="table", size=(0.8, 1.0, 0.05), pos=(-0.30, 0.0, 0.075), dynamic=False,
                     color=(0.42, 0.44, 0.40))


def cube(name: str, pos, color) -> EntityCfg:
    """A 5 cm, 40 g dynamic cube."""
    return EntityCfg(name=name, size=(CUBE_SIZE,) * 3, pos=pos, mass=CUBE_MASS, color=color)


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
