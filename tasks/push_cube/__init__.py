"""GalbotG1-PushCube-v0: push the cube into a goal region on the table (ManiSkill's PushCube-v1 on the G1)."""

from pathlib import Path

from newton_lab.task_api.experts import yaml_plan
from newton_lab.task_api.mimic_cfg import MimicCfg, SubtaskCfg
from newton_lab.task_api.registry import TaskSpec, mimic_variant, register

from .config.g1.env_cfg import push_cube_cfg

SPEC = register(
    TaskSpec(
        id="GalbotG1-PushCube-v0",
        cfg=push_cube_cfg,
        expert=yaml_plan(Path(__file__).parent / "config" / "g1" / "motion_plan.yaml"),
        description="Push the 5 cm cube 16 cm forward into a goal region of radius 8 cm.",
        teleop="left_arm_manipulation",
    )
)
# The goal sits at a fixed offset from the cube's start, so a whole demo replayed in the cube's frame is a demo.
MIMIC_SPEC = register(
    mimic_variant(
        SPEC,
        id="GalbotG1-PushCube-Mimic-v0",
        mimic=MimicCfg(subtasks=(SubtaskCfg(object_ref="cube", term_signal=None),)),
    )
)
