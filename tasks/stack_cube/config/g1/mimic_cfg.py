"""StackCube Mimic decomposition (reference MimicCfg, which the reference never registered)."""

import math

from newton_lab.task_api.mimic_cfg import MimicCfg, SubtaskCfg

CUBE = math.pi / 2  # a cube looks the same after a quarter turn

# Segment boundaries sit where the arm is clear of the stack: each grasp segment ends once the expert has
# raised its cube to transfer height (31-43 / 37-48 steps after the grasp signal; an expert that held every
# target 12 frames needed 40-55 / 58-72), and the cube_2 place
# segment ends after the lift-away (12-18 steps after the release signal, TCP back 14 cm above cube_1).
# A boundary at the release itself made the next segment -- replayed in cube_3's frame -- start beside the
# stack at release height, and the interpolation swept the open fingers through cube_2.

MIMIC = MimicCfg(
    subtasks=(
        SubtaskCfg(object_ref="cube_2", term_signal="cube_2_grasped", term_offset_range=(31, 43), yaw_symmetry=CUBE),
        SubtaskCfg(object_ref="cube_1", term_signal="cube_2_on_cube_1", term_offset_range=(12, 18), yaw_symmetry=CUBE),
        SubtaskCfg(object_ref="cube_3", term_signal="cube_3_grasped", term_offset_range=(37, 48), yaw_symmetry=CUBE),
        SubtaskCfg(object_ref="cube_2", term_signal=None, yaw_symmetry=CUBE),
    )
)
