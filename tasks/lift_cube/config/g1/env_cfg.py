"""GalbotG1-LiftCube-v0 configuration: fixed-base G1, left arm + gripper absolute targets (8), 20 s episodes.

Every term is a generic one (``tasks.common``) with this task's constants.
"""

from __future__ import annotations

from newton_lab.tasks.common import observations as obs
from newton_lab.tasks.common.config.g1 import postures
from newton_lab.tasks.common.config.g1.setup import left_arm_actions, manipulation_posture
from newton_lab.tasks.common.events import randomize_position
from newton_lab.tasks.common.rewards import Stage, lift_shaping, reach_stage, staged_rewards
from newton_lab.tasks.common.terminations import all_of, dropped, grasped, held, holding, lifted
from newton_lab.tasks.lift_cube.scene import CUBE_INIT, SCENE

from newton_lab.task_api.cfg import TaskCfg, TermCfg, TerminationTermCfg
from newton_lab.task_api.physics import PhysicsCfg

LIFTED_Z = CUBE_INIT[2] + 0.10
"""Success: the cube centre 10 cm above its resting height [m] ..."""
HOLD_STEPS = 5
"""... grasped, for this many consecutive control steps."""
DROPPED_Z = 0.05
"""A cube centre below this has left the table [m]."""
PHYSICS = PhysicsCfg(cone="pyramidal", constraints_per_world=128)
"""PickCube's physics (the pyramidal friction cone, 128 constraint rows a world): on the 2-core CPU at 4 envs
1.13x the elliptic cone's env-steps/s, the expert 16/16 under both (``python tools/physics_table.py --device cpu
--num-envs 4 --episodes 16 --tasks GalbotG1-LiftCube-v0 --variant cone=pyramidal``)."""


def lift_cube_cfg() -> TaskCfg:
    """The PickCube robot set-up (table-top posture, head pitched down) with one cube to lift. Dense reward:
    reaching, grasping, lifting (the fraction of the 10 cm done, while grasped), success (lifted and grasped),
    1/4 each (``tasks.common.rewards``). The success stage is PickCube's and StackCube's: with three stages and a
    ``1 - tanh(5 dz)`` lift, holding the cube 8 cm up paid 0.967 of the maximum, and PPO held it there."""
    grasped_cube = grasped(entity="cube")
    lifted_and_grasped = all_of(terms=(lifted(entity="cube", min_z=LIFTED_Z), grasped_cube))
    return TaskCfg(
        entities=SCENE.entities,
        actions=left_arm_actions(),
        observations=obs.manipulation_observations(cube_pose=obs.pose_of("cube")),
        phase_success=[held(term=lifted_and_grasped, steps=HOLD_STEPS)],
        terminations={
            "cube_dropped": TerminationTermCfg(func=dropped, params={"entity": "cube", "below_z": DROPPED_Z})
        },
        rewards=staged_rewards(
            reach_stage("cube"),
            Stage("grasping", holding(entity="cube")),
            Stage("lifting", lifted_and_grasped, lift_shaping(entity="cube", from_z=CUBE_INIT[2], min_z=LIFTED_Z)),
            Stage("success", lifted_and_grasped),
        ),
        signals={"grasped_cube": TermCfg(func=grasped_cube)},
        events={
            "randomize_cube": TermCfg(
                func=randomize_position,
                params={"entity": "cube", "x_range": (-0.38, -0.22), "y_range": (0.08, 0.26), "z": CUBE_INIT[2]},
            )
        },
        posture=manipulation_posture(postures.TABLE_TOP_LEFT_ARM, postures.TABLE_TOP_HEAD),
        root_pos=postures.MANIPULATION_ROOT_POS,
        episode_length_s=20.0,
        physics=PHYSICS,
    )
