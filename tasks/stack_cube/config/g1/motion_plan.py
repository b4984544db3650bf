"""StackCube expert plan (the reference platform's structure): for each (cube, level) in
((cube_2, 1), (cube_3, 2)): approach, descend, close x25, lift, raise to transfer height, move above
cube_1, descend to the stack pose, open, lift away. 33 commands per cube.

Re-derived for the authored gripper: the fingers reach 5 cm below the TCP, so the grasp TCP sits 1 cm
above the cube top (reference: 3 cm) and the release TCP is one grasp offset plus 8 mm above the cube's
stacked pose. The top-down TCP turns to the cube's yaw modulo 90 deg, the fingers closing within 45 deg of
world y (as in PickCube): the wrist target follows the cube's own yaw. Choosing instead the finger axis most
perpendicular to the nearest other cube (this plan until 2026-11-27) put the wrist 90 deg apart for cubes of the
same yaw in 121 of 255 neighbouring scenes, a choice a policy from 96x72 pixels had to guess; the expert then
stacked 96 of 96 randomised episodes, and with this rule 94 of 96 (CPU, seeds 100 and 200).

``cube_2_plan`` and ``cube_3_plan`` are the two subtasks on their own (the phases of GalbotG1-StackCube-Phased-v0):
the second is planned from the poses the first leaves, so it starts by clearing the stack.
"""

from __future__ import annotations

import math

import numpy as np

from newton_lab.task_api.motion_plan import MotionPlan, MotionStep, yaw_of
from newton_lab.robots.g1 import spec
from newton_lab.robots.g1.kinematics import quat_mul

HALF = 0.025
APPROACH = 0.18
GRASP = 0.01
LIFT = 0.10
RELEASE_GAP = 0.008
CLOSE_HOLD = 25


def _turned_top_down(yaw: np.ndarray) -> np.ndarray:
    """The top-down TCP turned by ``yaw`` about world z."""
    turn = np.stack([np.zeros_like(yaw), np.zeros_like(yaw), np.sin(yaw / 2), np.cos(yaw / 2)], axis=1)
    return quat_mul(turn, np.tile(np.asarray(spec.TOP_DOWN_TCP_QUAT), (len(yaw), 1)))


def _grasp_quat(name: str):
    """The top-down TCP turned to ``name``'s yaw modulo 90 deg (fingers close along the TCP y axis, within 45 deg
    of world y)."""
    def quat(poses: dict[str, np.ndarray]) -> np.ndarray:
        yaw = (yaw_of(poses[name][:, 3:7]) + math.pi / 4) % (math.pi / 2) - math.pi / 4
        return _turned_top_down(yaw)

    return quat


def _point(name: str, dz: float):
    def target(poses: dict[str, np.ndarray]) -> np.ndarray:
        p = poses[name][:, :3].copy()
        p[:, 2] += dz
        return p

    return target


def _stack_point(level: int, dz: float):
    def target(poses: dict[str, np.ndarray]) -> np.ndarray:
        p = poses["cube_1"][:, :3].copy()
        p[:, 2] += 0.05 * level + dz
        return p

    return target


def _transfer(name: str, level: int, xy_of: str):
    def target(poses: dict[str, np.ndarray]) -> np.ndarray:
        lift_z = poses[name][:, 2] + HALF + GRASP + LIFT
        stack_z = poses["cube_1"][:, 2] + 0.05 * level + HALF + GRASP + RELEASE_GAP
        p = poses[xy_of][:, :3].copy()
        p[:, 2] = np.maximum(lift_z, stack_z + 0.05)
        return p

    return target


def _cube_steps(name: str, level: int) -> list[MotionStep]:
    grasp_q = _grasp_quat(name)
    place_q = _grasp_quat("cube_1")
    release_dz = HALF + GRASP + RELEASE_GAP
    return [
        MotionStep(name=f"approach_{name}", target=_point(name, HALF + APPROACH), quat=grasp_q),
        MotionStep(name=f"descend_{name}", target=_point(name, HALF + GRASP), quat=grasp_q),
        MotionStep(name=f"close_on_{name}", gripper_open=False, hold=CLOSE_HOLD),
        MotionStep(name=f"lift_{name}", target=_point(name, HALF + GRASP + LIFT), quat=grasp_q, gripper_open=False),
        MotionStep(name=f"raise_{name}", target=_transfer(name, level, name), quat=grasp_q, gripper_open=False),
        MotionStep(name=f"move_{name}_above_stack", target=_transfer(name, level, "cube_1"), quat=place_q,
                   gripper_open=False),
        MotionStep(name=f"descend_{name}_to_stack", target=_stack_point(level, release_dz), quat=place_q,
                   gripper_open=False),
        MotionStep(name=f"release_{name}", target=_stack_point(level, release_dz), quat=place_q),
        MotionStep(name=f"lift_away_from_{name}", target=_transfer(name, level, "cube_1"), quat=place_q),
    ]


def _plan(steps: list[MotionStep]) -> MotionPlan:
    return MotionPlan(steps=tuple(steps), max_joint_step=0.03, settle_steps=12)


def plan(head: str = "level", cube_yaw: str = "random") -> MotionPlan:
    """The expert's plan (the options change nothing it does: it reads the cubes' poses, yaws included, at reset)."""
    return _plan(_cube_steps("cube_2", 1) + _cube_steps("cube_3", 2))


def cube_2_plan(head: str = "level", cube_yaw: str = "random") -> MotionPlan:
    """The first subtask's plan: cube_2 onto cube_1 (the first half of ``plan``)."""
    return _plan(_cube_steps("cube_2", 1))


def cube_3_plan(head: str = "level", cube_yaw: str = "random") -> MotionPlan:
    """The second subtask's plan, resolved from the live poses when it starts: clear the stack (straight up to
    cube_2's transfer height above cube_1, where the first subtask's lift-away goes), then cube_3 onto cube_2."""
    clear = MotionStep(name="clear_the_stack", target=_transfer("cube_2", 1, "cube_1"), quat=_grasp_quat("cube_1"))
    return _plan([clear] + _cube_steps("cube_3", 2))
