"""SortToShelf dense rewards, built per sorting object (ManiSkill PickCube-v1 style, ``tasks.common.rewards``;
each in [0, 1], 1 when the task's success condition holds).

Pick: reaching (``1 - tanh(5 |TCP - object|)`` until within 6 cm), grasping, lifting (the fraction of
the lift from the object's slot height to its lift height done, while grasped), carrying (``1 - tanh(|q_arm -
ready|)``, rad): 1/4 each. Place: grasping (object in hand), placing (``1 - tanh(5 |object - cell target|)``
while grasped, done when it rests in its cell, upright where required), releasing (gripper openness, done
with the gripper open), retracting (``1 - tanh(|q_arm - ready|)``, done at success): 1/4 each.
Coherent task: ``(phase + r_phase) / 3`` with the pick, nav (driving: mean of ``1 - tanh(d)`` to the place
base position, d in m, and ``1 - tanh(|yaw error|)``; posing: ``1 - tanh(|q_legs,arm - place start|)``, rad)
and place rewards.
"""

from __future__ import annotations

from newton_lab.tasks.common.rewards import (
    Stage,
    carry_shaping,
    drive_stage,
    gripper_openness,
    phased_rewards,
    pick_to_carry_stages,
    point_shaping,
    posture_shaping,
    staged_rewards,
)
from newton_lab.tasks.common.terminations import holding

from newton_lab.task_api.cfg import RewardTermCfg

from ..objects import SHELF_NAV_YAW, SortingObject
from .terminations import (
    PLACE_START_BASE_TOL,
    PLACE_START_YAW_TOL,
    at_carry,
    at_place_start,
    in_cell,
    placed,
    released_in_cell,
)


def pick_rewards(obj: SortingObject) -> dict[str, RewardTermCfg]:
    """SortToShelf-Pick: reach, grasp, lift, ready posture (1/4 each)."""
    return staged_rewards(
        *pick_to_carry_stages(entity=obj.name, rest_z=obj.pos[2], lift_z=obj.lift_min_z, at_carry=at_carry(obj))
    )


def place_rewards(obj: SortingObject) -> dict[str, RewardTermCfg]:
    """SortToShelf-Place: hold, place in the cell, release, retract (1/4 each)."""
    return staged_rewards(
        Stage("grasping", holding(entity=obj.name)),
        Stage("placing", in_cell(obj), point_shaping(entity=obj.name, point=obj.target)),
        Stage("releasing", released_in_cell(obj), gripper_openness),
        Stage("retracting", placed(obj), carry_shaping),
    )


def nav_rewards(obj: SortingObject) -> dict[str, RewardTermCfg]:
    """The nav phase of the coherent task: drive to the place base position facing the shelf, then the place-start
    posture (the Nav success condition without its 20-step hold) (1/2 each)."""
    drive = drive_stage(
        goal_xy=obj.place_base_xy, goal_yaw=SHELF_NAV_YAW, radius=PLACE_START_BASE_TOL, yaw_tol=PLACE_START_YAW_TOL
    )
    posing = Stage("posing", at_place_start(obj), posture_shaping(arm=obj.approach_arm, legs=obj.legs))
    return staged_rewards(drive, posing)


def coherent_rewards(obj: SortingObject) -> dict[str, RewardTermCfg]:
    """SortToShelf-v0: ``(phase + r_phase) / 3`` over pick, nav, place."""
    return phased_rewards([("pick", pick_rewards(obj)), ("nav", nav_rewards(obj)), ("place", place_rewards(obj))])
