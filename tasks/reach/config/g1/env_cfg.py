"""GalbotG1-Reach-v0 configuration (reference §3.2, left arm absolute targets, 12 s episodes)."""

from __future__ import annotations

from newton_lab.task_api.cfg import ObsTermCfg, TaskCfg
from newton_lab.robots.g1 import spec
from newton_lab.tasks.common import observations as common_obs
from newton_lab.tasks.common.table_top import left_arm_actions, manipulation_posture
from newton_lab.tasks.reach import scene
from newton_lab.tasks.reach.mdp import commands, observations, rewards, terminations


def reach_cfg() -> TaskCfg:
    """Fixed-base G1 at (-1, 0, 0); left arm absolute targets (7); goal resampled at every reset."""
    return TaskCfg(
        task_id="GalbotG1-Reach-v0",
        entities=scene.entities(),
        actions=left_arm_actions(gripper=False),
        observations=[
            ObsTermCfg(name="joint_pos", func=common_obs.arm_joint_pos, dim=7),
            ObsTermCfg(name="joint_vel", func=common_obs.robot_joint_vel, dim=common_obs.ROBOT_COORDS),
            ObsTermCfg(name="pose_command", func=observations.pose_command, dim=3),
            ObsTermCfg(name="tcp_pose", func=common_obs.tcp_pose_obs, dim=7),
            ObsTermCfg(name="actions", func=common_obs.last_action, dim=7),
        ],
        phase_success=[terminations.reached_goal],
        rewards={
            "position_error": (rewards.position_error, -0.2),
            "position_tanh": (rewards.position_tanh, 0.1),
            "action_rate": (rewards.action_rate, -1e-4),
            "joint_vel": (rewards.arm_joint_vel, -1e-4),
        },
        signals={"reached_goal": terminations.reached_goal},
        events=[commands.sample_goal],
        posture=manipulation_posture(spec.PICK_CUBE_LEFT_ARM_INITIAL, (0.0, 0.0)),
        root_pos=spec.MANIPULATION_ROOT_POS,
        command_dim=3,
        episode_length_s=12.0,
    )
