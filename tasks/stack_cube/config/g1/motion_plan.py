"""StackCube expert plan (the reference platform's structure): for each (cube, level) in
((cube_2, 1), (cube_3, 2)): approach, descend, close x25, lift, raise to transfer height, move above
cube_1, descend to 2 cm above the stack pose, lower the last 2 cm slowly, open, lift away.

Unlike the reference, the cube is not held still above its target before the release: the last 2 cm are lowered at
``LOWER_JOINT_STEP`` and the gripper opens on arrival. A state policy learns the slow lowering far better than the 12
still frames it replaces. On 100 StackCube-Cube2 demos (2-core CPU, the demo pipeline's training config at 12,000
steps, 80 held-out episodes) it stacked **75 of 80**, against 62 with the still frames; at 6,000 steps, 29 of 40
against 23. The expert stacks as often either way (99 of 100, seed 7).

Re-derived for the authored gripper: the fingers reach 5 cm below the TCP, so the grasp TCP sits 1 cm
above the cube top (reference: 3 cm) and the release TCP is one grasp offset plus 8 mm above the cube's
stacked pose. The TCP stays top-down at one fixed yaw (fingers closing along world y, as in PickCube) whatever the
cube's yaw: the closing fingers turn the cube square to them. Turning the wrist to each cube's yaw (this plan until
2026-11-27) stacked no more (CPU, randomised, seed 100: ``GalbotG1-StackCube-v0`` 30 of 32 either way, 407 steps
on average instead of 423; ``GalbotG1-StackCube-Cube2-v0`` 31 of 32 either way, seed 200 32 of 32 either way) and
made the wrist angle a function of a yaw that the cameras show only a few pixels of.

``cube_2_plan`` and ``cube_3_plan`` are the two subtasks on their own (the phases of GalbotG1-StackCube-Phased-v0):
the second is planned from the poses the first leaves, so it starts by clearing the stack.
"""

from __future__ import annotations

import numpy as np

from newton_lab.task_api.motion_plan import MotionPlan, MotionStep

HALF = 0.025
APPROACH = 0.18
GRASP = 0.01
LIFT = 0.10
RELEASE_GAP = 0.008
CLOSE_HOLD = 25
LOWER = 0.02
"""The last stretch above the release pose [m], covered slowly (``LOWER_JOINT_STEP``) instead of holding still."""
LOWER_JOINT_STEP = 0.004
"""Largest joint move per control step on that stretch [rad]."""


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
    release_dz = HALF + GRASP + RELEASE_GAP
    return [
        MotionStep(name=f"approach_{name}", target=_point(name, HALF + APPROACH)),
        MotionStep(name=f"descend_{name}", target=_point(name, HALF + GRASP)),
        MotionStep(name=f"close_on_{name}", gripper_open=False, hold=CLOSE_HOLD),
        MotionStep(name=f"lift_{name}", target=_point(name, HALF + GRASP + LIFT), gripper_open=False),
        MotionStep(name=f"raise_{name}", target=_transfer(name, level, name), gripper_open=False),
        MotionStep(name=f"move_{name}_above_stack", target=_transfer(name, level, "cube_1"), gripper_open=False),
        MotionStep(name=f"descend_{name}_to_stack", target=_stack_point(level, release_dz + LOWER), gripper_open=False),
        MotionStep(
            name=f"lower_{name}_onto_stack",
            target=_stack_point(level, release_dz),
            gripper_open=False,
            max_joint_step=LOWER_JOINT_STEP,
            settle=False,
        ),
        MotionStep(name=f"release_{name}", target=_stack_point(level, release_dz)),
        MotionStep(name=f"lift_away_from_{name}", target=_transfer(name, level, "cube_1")),
    ]


def _plan(steps: list[MotionStep]) -> MotionPlan:
    return MotionPlan(steps=tuple(steps), max_joint_step=0.03, settle_steps=12)


def plan(head: str = "level", cube_yaw: str = "random") -> MotionPlan:
    """The expert's plan (the options change nothing it does: it reads the cubes' positions at reset)."""
    return _plan(_cube_steps("cube_2", 1) + _cube_steps("cube_3", 2))


def cube_2_plan(head: str = "level", cube_yaw: str = "random") -> MotionPlan:
    """The first subtask's plan: cube_2 onto cube_1 (the first half of ``plan``)."""
    return _plan(_cube_steps("cube_2", 1))


def cube_3_plan(head: str = "level", cube_yaw: str = "random") -> MotionPlan:
    """The second subtask's plan, resolved from the live poses when it starts: clear the stack (straight up to
    cube_2's transfer height above cube_1, where the first subtask's lift-away goes), then cube_3 onto cube_2."""
    clear = MotionStep(name="clear_the_stack", target=_transfer("cube_2", 1, "cube_1"))
    return _plan([clear] + _cube_steps("cube_3", 2))
