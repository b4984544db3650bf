"""StackCube Mimic decomposition (reference MimicCfg, which the reference never registered)."""

import math

from newton_lab.datasets.mimic import MimicCfg, SubtaskCfg

CUBE = math.pi / 2  # a cube looks the same after a quarter turn

MIMIC = MimicCfg(
    subtasks=(
        SubtaskCfg(object_ref="cube_2", term_signal="cube_2_grasped", term_offset_range=(40, 55), yaw_symmetry=CUBE),
        SubtaskCfg(object_ref="cube_1", term_signal="cube_2_on_cube_1", term_offset_range=(0, 5), yaw_symmetry=CUBE),
        SubtaskCfg(object_ref="cube_3", term_signal="cube_3_grasped", term_offset_range=(58, 72), yaw_symmetry=CUBE),
        SubtaskCfg(object_ref="cube_2", term_signal=None, yaw_symmetry=CUBE),
    ),
)
