"""GalbotG1-PickCube-v0 configuration (as on the reference platform), and the operator's variant.

Every term is a generic one (``tasks.common``) with the reference's thresholds. Dense reward (not in the
reference, which has none; ManiSkill PickCube-v1 style): reaching, grasping, placing (``1 - tanh(5 |cube -
resting pose on the block|)`` while grasped), releasing (gripper openness while the cube rests on the block),
success: 0.2 each, in [0, 1].
"""

from __future__ import annotations

import dataclasses

from newton_lab.tasks.common import observations as obs
from newton_lab.tasks.common.config.g1 import cameras, postures
from newton_lab.tasks.common.config.g1.setup import left_arm_actions, manipulation_posture
from newton_lab.tasks.common.events import randomize_position
from newton_lab.tasks.common.rewards import Stage, gripper_openness, place_shaping, reach_stage, staged_rewards
from newton_lab.tasks.common.terminations import all_of, dropped, grasped, gripper_open, holding, resting_on
from newton_lab.tasks.pick_cube.scene import CUBE_INIT, SCENE

from newton_lab.task_api.cfg import TaskCfg, TermCfg, TerminationTermCfg
from newton_lab.task_api.physics import PhysicsCfg

ON_BLOCK = dict(entity="cube", target="blue_block", height=0.035, xy_tol=0.08, z_tol=0.03)
"""The cube rests on the block: centre within 8 cm in xy, 0.035 +- 0.03 m above the block's centre (block half
height 0.01 + cube half size 0.025) [m]."""

PHYSICS = PhysicsCfg(
    cone="pyramidal",
    constraints_per_world=128,  # policy rollouts pressing the cube into the table exceeded the default 64 rows
)
"""PickCube's physics: the pyramidal friction cone (1.04x on an H200 at 4096 envs, 1,006,711 env-steps/s; 1.12x on
the 2-core CPU at 4 envs; the expert 100/100 under both cones, and the ``make demo`` policy trained under the
elliptic cone 297/300 under this one against 300/300). No contact filter: ``gripper_only()`` with 5 iterations (the
most expert solves use is 4) ran at 0.98x on an H100 at 4096 envs, and a filter lets an arm pass through the cube,
which a learned policy's evaluation must not get for free; contact capacities cut to 32 a world (expert peak 14)
gained nothing measurable (benchmarks history, "Per-task physics settings")."""


def pick_cube_cfg() -> TaskCfg:
    """Fixed-base G1 at (-1, 0, 0); left arm + gripper absolute targets (8); success: the cube released on the
    blue block (gripper open within 0.05 rad)."""
    grasped_cube = grasped(entity="cube")
    on_block = resting_on(**ON_BLOCK)
    released = all_of(terms=(on_block, gripper_open(tol=0.05)))
    return TaskCfg(
        entities=SCENE.entities,
        actions=left_arm_actions(),
        observations=obs.manipulation_observations(
            cube_pose=obs.pose_of("cube"), blue_block_pos=obs.position_of("blue_block")
        ),
        phase_success=[released],
        terminations={"cube_dropped": TerminationTermCfg(func=dropped, params={"entity": "cube", "below_z": 0.05})},
        rewards=staged_rewards(
            reach_stage("cube"),
            Stage("grasping", holding(entity="cube")),
            Stage("placing", on_block, place_shaping(entity="cube", target="blue_block", offset=(0.0, 0.0, 0.035))),
            Stage("releasing", released, gripper_openness),
            Stage("success", released),
        ),
        signals={"grasped_cube": TermCfg(func=grasped_cube)},
        events={
            "randomize_cube_position": TermCfg(
                func=randomize_position,
                params={"entity": "cube", "x_range": (-0.38, -0.22), "y_range": (0.12, 0.26), "z": CUBE_INIT[2]},
            )
        },
        posture=manipulation_posture(postures.TABLE_TOP_LEFT_ARM, postures.TABLE_TOP_HEAD),
        root_pos=postures.MANIPULATION_ROOT_POS,
        fixed_base=True,
        cameras=cameras.front_head_rgb(),
        physics=PHYSICS,
    )


def pick_cube_teleop_cfg() -> TaskCfg:
    """PickCube for an operator: the teleop camera set (left wrist + front head RGB, 640 x 480) and the same
    success logic, latched but not ending the episode: the operator ends it (``done``) and reviews it."""
    return dataclasses.replace(pick_cube_cfg(), cameras=cameras.teleop_rgb(), terminate_on_success=False)
