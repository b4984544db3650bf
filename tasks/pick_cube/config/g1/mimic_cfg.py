"""PickCube Mimic decomposition: grasp the cube (cube frame), then place it (blue-block frame).

The reference replays the place segment in the cube's frame; the blue block is the place target, so its
frame is used here (it is static in PickCube, which makes that segment a world-frame replay)."""

from newton_lab.task_api.mimic_cfg import MimicCfg, SubtaskCfg

MIMIC = MimicCfg(
    subtasks=(
        SubtaskCfg(object_ref="cube", term_signal="grasped_cube", term_offset_range=(5, 15)),
        SubtaskCfg(object_ref="blue_block", term_signal=None),
    )
)
