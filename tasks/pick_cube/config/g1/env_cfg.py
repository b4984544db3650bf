"""GalbotG1-PickCube-v0 configuration (reference §3.3)."""

from __future__ import annotations

import dataclasses

from newton_lab.task_api.cfg import ObsTermCfg, TaskCfg, TermCfg, TerminationTermCfg
from newton_lab.tasks.common import cameras, postures

from newton_lab.tasks.common import observations as common_obs
from newton_lab.tasks.common.table_top import left_arm_actions, manipulation_posture
from newton_lab.tasks.pick_cube import scene
from newton_lab.tasks.pick_cube.mdp import events, observations, rewards, terminations


def pick_cube_cfg() -> TaskCfg:
    """Fixed-base G1 at (-1, 0, 0); left arm + gripper absolute targets (8)."""
    return TaskCfg(
        task_id="GalbotG1-PickCube-v0",
        entities=scene.entities(),
        actions=left_arm_actions(),
        observations=common_obs.manipulation_observations(
            cube_pose=ObsTermCfg(func=observations.cube_pose, size=7),
            blue_block_pos=ObsTermCfg(func=observations.blue_block_pos, size=3),
        ),
        phase_success=[terminations.released_on_blue_block],
        terminations={"cube_dropped": TerminationTermCfg(func=terminations.cube_dropped)},
        rewards=rewards.dense_rewards(),  # staged, in [0, 1] (not in the reference, which has none)
        signals={"grasped_cube": TermCfg(func=terminations.grasped_cube)},
        events={"randomize_cube_position": TermCfg(func=events.randomize_cube_position)},
        posture=manipulation_posture(postures.TABLE_TOP_LEFT_ARM, postures.TABLE_TOP_HEAD),
        root_pos=postures.MANIPULATION_ROOT_POS,
        fixed_base=True,
        cameras=cameras.front_head_rgb(),
        constraints_per_world=128,  # policy rollouts pressing the cube into the table exceeded the default 64 rows
    )


def pick_cube_teleop_cfg() -> TaskCfg:
    """PickCube for an operator: the teleop camera set (left wrist + front head RGB, 640 x 480) and the same
    success logic, latched but not ending the episode: the operator ends it (``done``) and reviews it."""
    return dataclasses.replace(pick_cube_cfg(), task_id="GalbotG1-PickCube-Teleop-v0", cameras=cameras.teleop_rgb(),
                               terminate_on_success=False)
