"""StackCube Mimic decomposition (reference MimicCfg, which the reference never registered)."""

from newton_lab.datasets.mimic import MimicCfg, SubtaskCfg

MIMIC = MimicCfg(
    subtasks=(
        SubtaskCfg(object_ref="cube_2", term_signal="cube_2_grasped", term_offset_range=(5, 15)),
        SubtaskCfg(object_ref="cube_1", term_signal="cube_2_on_cube_1", term_offset_range=(0, 5)),
        SubtaskCfg(object_ref="cube_3", term_signal="cube_3_grasped", term_offset_range=(5, 15)),
        SubtaskCfg(object_ref="cube_2", term_signal=None),
    ),
)
