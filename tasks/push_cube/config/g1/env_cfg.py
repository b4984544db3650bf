"""GalbotG1-PushCube-v0 configuration: fixed-base G1, left arm + gripper absolute targets (8), 15 s episodes.

The goal region is a commanded point 16 cm ahead of the cube's start (``tasks.common.commands``); success: the
cube's centre within 8 cm of it in xy. Dense reward (ManiSkill PushCube-v1 style, in [0, 1]): reaching
(``1 - tanh(5 |TCP - cube|)`` until within 6 cm) and pushing (``1 - tanh(5 d)``, d = cube-to-goal xy [m]).
"""

# docs/task_authoring.md lists this file's lines as they stand here: the formatter leaves them.
# fmt: off
from __future__ import annotations

from newton_lab.tasks.common import observations as obs
from newton_lab.tasks.common.commands import (
    COMMAND_POINT,
    POINT_COMMAND_DIM,
    command_shaping,
    entity_at_command,
    point_from_entity,
)
from newton_lab.tasks.common.config.g1 import cameras, postures
from newton_lab.tasks.common.config.g1.setup import left_arm_actions, manipulation_posture
from newton_lab.tasks.common.events import randomize_position
from newton_lab.tasks.common.rewards import Stage, reach_stage, staged_rewards, tcp_near
from newton_lab.tasks.common.terminations import dropped
from newton_lab.tasks.push_cube.scene import CUBE_INIT, SCENE

from newton_lab.task_api.cfg import TaskCfg, TermCfg, TerminationTermCfg
from newton_lab.task_api.physics import PhysicsCfg

GOAL_OFFSET = (0.16, 0.0, 0.0)
"""Goal region centre from the cube's start [m] (forward, away from the robot)."""
GOAL_RADIUS = 0.08
"""Success: cube centre within this xy distance of the goal centre [m]."""


def push_cube_cfg() -> TaskCfg:
    """The table-top robot set-up with one cube to push; the cube's start is randomised."""
    in_goal = entity_at_command(entity="cube", radius=GOAL_RADIUS)
    return TaskCfg(
        entities=SCENE.entities,
        actions=left_arm_actions(),
        observations=obs.manipulation_observations(cube_pose=obs.pose_of("cube"), goal_pos=COMMAND_POINT),
        phase_success=[in_goal],
        terminations={"cube_dropped": TerminationTermCfg(func=dropped, params={"entity": "cube", "below_z": 0.05})},
        rewards=staged_rewards(reach_stage("cube"), Stage("pushing", in_goal, command_shaping(entity="cube"))),
        signals={"reached_cube": TermCfg(func=tcp_near, params={"entity": "cube"})},
        events={"randomize_cube": TermCfg(func=randomize_position, params={
                    "entity": "cube", "x_range": (-0.42, -0.30), "y_range": (0.10, 0.24), "z": CUBE_INIT[2]}),
                "place_goal": TermCfg(func=point_from_entity, params={"entity": "cube", "offset": GOAL_OFFSET})},
        posture=manipulation_posture(postures.TABLE_TOP_LEFT_ARM, postures.TABLE_TOP_HEAD),
        root_pos=postures.MANIPULATION_ROOT_POS,
        command_dim=POINT_COMMAND_DIM,
        episode_length_s=15.0,
        cameras=cameras.front_head_rgb(),
        physics=PhysicsCfg(constraints_per_world=128),
    )
