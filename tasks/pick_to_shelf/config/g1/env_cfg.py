"""PickToShelf configurations (reference §3.6): the Pick, Nav and Place components and the coherent task.

All four share the PickToShelf world; the robot starts at (-1.2, 0, 0) on its wheels, left arm in the carry
posture. The Nav and Place components start from scenarios (``scenarios/*.yaml``) captured at the end of the
previous component with ``--save-end-scenario``; the coherent task chains the components without resets.
"""

from __future__ import annotations

from pathlib import Path

from newton_lab.task_api.cfg import ObsTermCfg, TaskCfg, TermCfg, TerminationTermCfg
from newton_lab.task_api.experts import NavExpert
from newton_lab.task_api.compose import coherent_task, phase, task_sequence
from newton_lab.robots.g1 import spec
from newton_lab.tasks.common import cameras, postures
from newton_lab.tasks.common import navigation as nav
from newton_lab.tasks.common import observations as common_obs
from newton_lab.tasks.common.table_top import left_arm_actions, shelf_posture
from newton_lab.tasks.pick_to_shelf import scene
from newton_lab.tasks.pick_to_shelf.mdp import events, observations, rewards, terminations

NAV_GOAL_XY = (-1.7, -1.15)
"""Base goal in front of the shelf: deck front edge + 0.65 m [m]."""
NAV_GOAL_YAW = -1.5707963267948966
NAV_SUCCESS_RADIUS = 0.02
SCENARIOS = Path(__file__).parent / "scenarios"

_goal_reached = nav.make_goal_reached(NAV_GOAL_XY, NAV_SUCCESS_RADIUS)


def _world(task_id: str, **fields) -> TaskCfg:
    base = dict(
        task_id=task_id,
        entities=scene.entities(),
        actions=left_arm_actions(),
        observations=common_obs.manipulation_observations(cube_pose=ObsTermCfg(func=observations.cube_pose, size=7)),
        phase_success=[],
        terminations={"cube_dropped": TerminationTermCfg(func=terminations.cube_dropped),
                      "cube_tipped": TerminationTermCfg(func=terminations.cube_tipped)},
        signals={"grasped_cube": TermCfg(func=terminations.grasped_cube)},
        posture=shelf_posture(),
        root_pos=scene.ROBOT_ROOT,
        arm_home=postures.CARRY_LEFT_ARM,
        fixed_base=True,
        cameras=cameras.front_head_rgb(),
    )
    base.update(fields)
    return TaskCfg(**base)


def pick_cfg() -> TaskCfg:
    """Pick the bar from the table and bring it to the carry posture (success: ``at_carry``)."""
    return _world("GalbotG1-PickToShelf-Pick-v0", phase_success=[terminations.at_carry], rewards=rewards.pick_rewards(),
                  events={"randomize_bar_position": TermCfg(func=events.randomize_bar_position)})


def nav_cfg(init_scenario: str | None = None) -> TaskCfg:
    """Drive with the bar in hand to the shelf (success: base within 2 cm of the goal; yaw not checked)."""
    return _world(
        "GalbotG1-PickToShelf-Nav-v0",
        actions=nav.base_actions(),
        observations=nav.nav_observations(NAV_GOAL_XY),
        phase_success=[_goal_reached],
        rewards=nav.nav_rewards(NAV_GOAL_XY, NAV_SUCCESS_RADIUS),
        signals={"goal_reached": TermCfg(func=_goal_reached)},
        scenario=init_scenario or str(SCENARIOS / "nav_default.yaml"),
        initial_targets={spec.LEFT_GRIPPER_JOINT: spec.GRIPPER_CLOSED},
        fixed_base=False,
    )


def place_cfg(init_scenario: str | None = None) -> TaskCfg:
    """Put the bar upright on the shelf deck and let go (success: ``cube_on_shelf`` held 20 steps)."""
    return _world(
        "GalbotG1-PickToShelf-Place-v0",
        phase_success=[terminations.cube_on_shelf],
        rewards=rewards.place_rewards(),
        scenario=init_scenario or str(SCENARIOS / "place_default.yaml"),
        initial_targets={spec.LEFT_GRIPPER_JOINT: spec.GRIPPER_CLOSED},
    )


def coherent_cfg() -> TaskCfg:
    """Pick -> Nav -> Place in one episode; the episode succeeds when the bar stands on the shelf."""
    return coherent_task(
        "GalbotG1-PickToShelf-v0",
        phases=task_sequence(
            phase("pick", "GalbotG1-PickToShelf-Pick-v0", terms=("left_arm", "left_gripper")),
            phase("nav", "GalbotG1-PickToShelf-Nav-v0", terms=("base",)),
            phase("place", "GalbotG1-PickToShelf-Place-v0", terms=("left_arm", "left_gripper")),
        ),
        rewards=rewards.coherent_rewards(NAV_GOAL_XY, NAV_GOAL_YAW, NAV_SUCCESS_RADIUS),
    )


def nav_expert(init_scenario: str | None = None) -> NavExpert:
    """PickToShelf-Nav expert: turn to face the shelf, then drive straight to the goal."""
    return NavExpert(goal=NAV_GOAL_XY, goal_yaw=NAV_GOAL_YAW, success_radius=NAV_SUCCESS_RADIUS, yaw_tolerance=0.03,
                     rotate_before_translate=True, waypoint_spacing=10.0)
