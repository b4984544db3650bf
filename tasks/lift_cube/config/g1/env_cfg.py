"""GalbotG1-LiftCube-v0 configuration: fixed-base G1, left arm + gripper absolute targets (8), 20 s episodes."""

from __future__ import annotations

from newton_lab.tasks.common import postures
from newton_lab.task_api.cfg import ObsTermCfg, TaskCfg, TermCfg, TerminationTermCfg
from newton_lab.tasks.common import observations as common_obs
from newton_lab.tasks.common.table_top import left_arm_actions, manipulation_posture
from newton_lab.tasks.lift_cube import scene
from newton_lab.tasks.lift_cube.mdp import events, observations, rewards, terminations


def lift_cube_cfg() -> TaskCfg:
    """The PickCube robot set-up (table-top posture, head pitched down) with one cube to lift."""
    return TaskCfg(
        task_id="GalbotG1-LiftCube-v0",
        entities=scene.entities(),
        actions=left_arm_actions(),
        observations=common_obs.manipulation_observations(cube_pose=ObsTermCfg(func=observations.cube_pose, size=7)),
        phase_success=[terminations.cube_lifted],
        terminations={"cube_dropped": TerminationTermCfg(func=terminations.cube_dropped)},
        rewards=rewards.dense_rewards(),  # staged, in [0, 1]
        signals={"grasped_cube": TermCfg(func=terminations.grasped_cube)},
        events={"randomize_cube": TermCfg(func=events.randomize_cube)},
        posture=manipulation_posture(postures.TABLE_TOP_LEFT_ARM, postures.TABLE_TOP_HEAD),
        root_pos=postures.MANIPULATION_ROOT_POS,
        episode_length_s=20.0,
        constraints_per_world=128,
    )
