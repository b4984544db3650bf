"""GalbotG1-StackCube-v0 configuration (reference §3.4)."""

from __future__ import annotations

from newton_lab.task_api.cfg import ObsTermCfg, TaskCfg, TermCfg, TerminationTermCfg
from newton_lab.tasks.common import postures
from newton_lab.tasks.common import observations as common_obs
from newton_lab.tasks.common.table_top import left_arm_actions, manipulation_posture
from newton_lab.tasks.stack_cube import scene
from newton_lab.tasks.stack_cube.mdp import events, observations, rewards, terminations


def stack_cube_cfg() -> TaskCfg:
    """Fixed-base G1 at (-1, 0, 0), head level; left arm + gripper absolute targets (8). The episode
    ends when the full stack is released (the collect / evaluate boundary of the reference)."""
    return TaskCfg(
        task_id="GalbotG1-StackCube-v0",
        entities=scene.entities(),
        actions=left_arm_actions(),
        observations={
            "actions": common_obs.LAST_ACTION,
            "joint_pos": common_obs.ROBOT_JOINT_POS,
            "joint_vel": common_obs.ROBOT_JOINT_VEL,
            "cube_positions": ObsTermCfg(func=observations.cube_positions, size=9),
            "cube_orientations": ObsTermCfg(func=observations.cube_orientations, size=12),
            "eef_pose": common_obs.TCP_POSE,
            "gripper_pos": common_obs.GRIPPER_POS,
        },
        phase_success=[terminations.stack_success],
        terminations={"cube_dropping": TerminationTermCfg(func=terminations.cube_dropping)},
        rewards=rewards.dense_rewards(),  # staged, in [0, 1]; reference_rewards() has the reference weights
        signals={
            "cube_2_grasped": TermCfg(func=terminations.cube_2_grasped),
            "cube_2_on_cube_1": TermCfg(func=terminations.cube_2_on_cube_1),
            "cube_3_grasped": TermCfg(func=terminations.cube_3_grasped),
            "cube_3_on_cube_2": TermCfg(func=terminations.cube_3_on_cube_2),
        },
        events={"randomize_cube_positions": TermCfg(func=events.randomize_cube_positions)},
        posture=manipulation_posture(postures.TABLE_TOP_LEFT_ARM, postures.LEVEL_HEAD),
        root_pos=postures.MANIPULATION_ROOT_POS,
        # measured peaks (expert, randomised): 21 contacts and 67 constraint rows per world
        constraints_per_world=128,
    )
