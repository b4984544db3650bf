"""GalbotG1-Reach-v0 configuration (as on the reference platform: left arm absolute targets, 12 s episodes; one
reward term added, ``position_tanh_fine``, see its docstring)."""

from __future__ import annotations

from newton_lab.tasks.common import observations as common_obs
from newton_lab.tasks.common.commands import COMMAND_POINT, POINT_COMMAND_DIM
from newton_lab.tasks.common.config.g1 import postures
from newton_lab.tasks.common.config.g1.setup import left_arm_actions, manipulation_posture
from newton_lab.tasks.common.rewards import action_rate
from newton_lab.tasks.common.table_top import table
from newton_lab.tasks.reach.mdp import commands, rewards, terminations

from newton_lab.task_api.cfg import RewardTermCfg, TaskCfg, TermCfg


def reach_cfg() -> TaskCfg:
    """Fixed-base G1 at (-1, 0, 0); left arm absolute targets (7); goal resampled at every reset."""
    return TaskCfg(
        entities=[table()],
        actions=left_arm_actions(gripper=False),
        observations={
            "joint_pos": common_obs.ARM_JOINT_POS,
            "joint_vel": common_obs.ROBOT_JOINT_VEL,
            "pose_command": COMMAND_POINT,
            "tcp_pose": common_obs.TCP_POSE,
            "actions": common_obs.LAST_ACTION,
        },
        phase_success=[terminations.reached_goal],
        rewards={
            "position_error": RewardTermCfg(func=terminations.goal_distance, weight=-0.2),
            "position_tanh": RewardTermCfg(func=rewards.position_tanh, weight=0.1),
            "position_tanh_fine": RewardTermCfg(func=rewards.position_tanh_fine, weight=0.1),
            "action_rate": RewardTermCfg(func=action_rate, weight=-1e-4),
            "joint_vel": RewardTermCfg(func=rewards.arm_joint_vel, weight=-1e-4),
        },
        signals={"reached_goal": TermCfg(func=terminations.reached_goal)},
        events={"sample_goal": TermCfg(func=commands.sample_goal)},
        posture=manipulation_posture(postures.TABLE_TOP_LEFT_ARM, (0.0, 0.0)),
        root_pos=postures.MANIPULATION_ROOT_POS,
        command_dim=POINT_COMMAND_DIM,
        episode_length_s=12.0,
    )
