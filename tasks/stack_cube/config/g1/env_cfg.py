"""GalbotG1-StackCube-v0 configuration (reference §3.4)."""

from __future__ import annotations

from newton_lab.task_api.cfg import ObsTermCfg, TaskCfg
from newton_lab.robots.g1 import spec
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
        observations=[
            ObsTermCfg(name="actions", func=common_obs.last_action, dim=8),
            ObsTermCfg(name="joint_pos", func=common_obs.robot_joint_pos, dim=common_obs.ROBOT_COORDS),
            ObsTermCfg(name="joint_vel", func=common_obs.robot_joint_vel, dim=common_obs.ROBOT_COORDS),
            ObsTermCfg(name="cube_positions", func=observations.cube_positions, dim=9),
            ObsTermCfg(name="cube_orientations", func=observations.cube_orientations, dim=12),
            ObsTermCfg(name="eef_pose", func=common_obs.tcp_pose_obs, dim=7),
            ObsTermCfg(name="gripper_pos", func=common_obs.gripper_pos, dim=1),
        ],
        phase_success=[terminations.stack_success],
        terminations={"cube_dropping": terminations.cube_dropping},
        rewards={
            "cube_2_on_cube_1": (rewards.cube_2_on_cube_1, 2.0),
            "cube_3_on_cube_2": (rewards.cube_3_on_cube_2, 2.0),
            "stack_success": (rewards.stack_success, 20.0),
            "action_rate": (rewards.action_rate, -1e-4),
        },
        signals={
            "cube_2_grasped": terminations.cube_2_grasped,
            "cube_2_on_cube_1": terminations.cube_2_on_cube_1,
            "cube_3_grasped": terminations.cube_3_grasped,
            "cube_3_on_cube_2": terminations.cube_3_on_cube_2,
        },
        events=[events.randomize_cube_positions],
        posture=manipulation_posture(spec.PICK_CUBE_LEFT_ARM_INITIAL, spec.STACK_CUBE_HEAD),
        root_pos=spec.MANIPULATION_ROOT_POS,
        # measured peaks (expert, randomised): 21 contacts and 67 constraint rows per world
        constraints_per_world=128,
    )
