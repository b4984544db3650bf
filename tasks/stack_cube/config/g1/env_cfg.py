"""GalbotG1-StackCube-v0 configuration (as on the reference platform), its two subtasks on their own and both as the
phases of GalbotG1-StackCube-Phased-v0."""

from __future__ import annotations

from newton_lab.tasks.common import observations as obs
from newton_lab.tasks.common.config.g1 import postures
from newton_lab.tasks.common.config.g1.setup import left_arm_actions, manipulation_posture
from newton_lab.tasks.common.rewards import phased_rewards
from newton_lab.tasks.stack_cube.mdp import events, rewards
from newton_lab.tasks.stack_cube.mdp.terminations import (
    cube_dropping,
    grasped_cube,
    stack_success,
    stacked_and_released,
)
from newton_lab.tasks.stack_cube.scene import CUBES, SCENE

from newton_lab.task_api.cfg import TaskCfg, TermCfg, TerminationTermCfg
from newton_lab.task_api.compose import coherent_task, phase, task_sequence
from newton_lab.task_api.physics import PhysicsCfg

PHYSICS = PhysicsCfg(
    cone="pyramidal",
    constraints_per_world=128,  # measured peaks (expert, randomised, elliptic): 22 contacts, 67 constraint rows a world
)
"""StackCube's physics (its subtasks' and the phased task's too): the pyramidal friction cone, 1.54x on an H200 at
4096 envs and 1.61x on the 2-core CPU, the expert 98/100 under both cones. No contact filter (``gripper_only()`` with
8 iterations ran at 1.01x on an H100 at 4096 envs; benchmarks history, "Per-task physics settings")."""


HEADS = {"level": postures.LEVEL_HEAD, "table": postures.TABLE_TOP_HEAD}
"""Head postures by the ``head`` option's value [rad]: level (the reference; its front camera sees only the table's
near edge) or tilted down at the table (what a policy from pixels needs)."""


CUBE_YAWS = {"random": True, "zero": False}
"""The ``cube_yaw`` option: whether each cube turns to a random yaw at reset (±1 rad, the reference) or keeps yaw 0."""


def _reset(cube_yaw: str, prestacked: bool = False) -> dict[str, TermCfg]:
    return {
        "randomize_cube_positions": TermCfg(
            func=events.randomize_cube_positions,
            params={"cubes": CUBES, "prestacked": prestacked, "turned": CUBE_YAWS[cube_yaw]},
        )
    }


def _world(head: str, cube_yaw: str, **fields) -> TaskCfg:
    base = dict(
        entities=SCENE.entities,
        actions=left_arm_actions(),
        observations={
            "actions": obs.LAST_ACTION,
            "joint_pos": obs.ROBOT_JOINT_POS,
            "joint_vel": obs.ROBOT_JOINT_VEL,
            "cube_positions": obs.positions_of(*CUBES),
            "cube_orientations": obs.orientations_of(*CUBES),
            "eef_pose": obs.TCP_POSE,
            "gripper_pos": obs.GRIPPER_POS,
        },
        phase_success=[stack_success()],
        terminations={"cube_dropping": TerminationTermCfg(func=cube_dropping())},
        rewards=rewards.dense_rewards(),  # staged, in [0, 1]; reference_rewards() has the reference weights
        signals={
            "cube_2_grasped": TermCfg(func=grasped_cube("cube_2")),
            "cube_2_on_cube_1": TermCfg(func=stacked_and_released("cube_2", "cube_1")),
            "cube_3_grasped": TermCfg(func=grasped_cube("cube_3")),
            "cube_3_on_cube_2": TermCfg(func=stacked_and_released("cube_3", "cube_2")),
        },
        events=_reset(cube_yaw),
        posture=manipulation_posture(postures.TABLE_TOP_LEFT_ARM, HEADS[head]),
        root_pos=postures.MANIPULATION_ROOT_POS,
        physics=PHYSICS,
    )
    base.update(fields)
    return TaskCfg(**base)


def stack_cube_cfg(head: str = "level", cube_yaw: str = "random") -> TaskCfg:
    """Fixed-base G1 at (-1, 0, 0), head ``head`` (``HEADS``), cube yaws ``cube_yaw`` (``CUBE_YAWS``); left arm +
    gripper absolute targets (8). The episode ends when the full stack is released (the collect / evaluate boundary
    of the reference)."""
    return _world(head, cube_yaw)


def _subtask_observations():
    """The subtasks' (and the phased task's) observation: the platform's manipulation terms (``robot_joint_pos``,
    ``tcp_pose``, ...: what the visuomotor training presets read) and the cube poses, where StackCube keeps the
    reference's names (``joint_pos``, ``eef_pose``)."""
    return obs.manipulation_observations(
        cube_positions=obs.positions_of(*CUBES), cube_orientations=obs.orientations_of(*CUBES)
    )


def cube_2_cfg(head: str = "level", cube_yaw: str = "random") -> TaskCfg:
    """The first subtask on its own: StackCube's world and reset; success when cube_2 is stacked on cube_1 and
    released."""
    return _world(
        head,
        cube_yaw,
        observations=_subtask_observations(),
        rewards=rewards.cube_2_rewards(),
        phase_success=[stacked_and_released("cube_2", "cube_1")],
    )


def cube_3_cfg(head: str = "level", cube_yaw: str = "random") -> TaskCfg:
    """The second subtask on its own: the cubes reset with cube_2 already on cube_1; success is StackCube's (the
    full stack, released)."""
    return _world(
        head,
        cube_yaw,
        observations=_subtask_observations(),
        rewards=rewards.cube_3_rewards(),
        events=_reset(cube_yaw, prestacked=True),
    )


def phased_cfg(head: str = "level", cube_yaw: str = "random") -> TaskCfg:
    """StackCube as two phases in one episode (cube_2, then cube_3): StackCube's world, reset and success, with the
    phase a row is in, so that one policy per subtask can drive it (``--phase-checkpoint``); the subtasks'
    observation names."""
    return coherent_task(
        phases=task_sequence(
            phase("cube_2", "GalbotG1-StackCube-Cube2-v0", terms=("left_arm", "left_gripper")),
            phase("cube_3", "GalbotG1-StackCube-Cube3-v0", terms=("left_arm", "left_gripper")),
        ),
        rewards=phased_rewards([("cube_2", rewards.cube_2_rewards()), ("cube_3", rewards.cube_3_rewards())]),
        options={"head": head, "cube_yaw": cube_yaw},
        fixed_base=True,
    )
