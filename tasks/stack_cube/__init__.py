"""GalbotG1-StackCube-v0: stack cube_2 on cube_1, then cube_3 on cube_2."""

from newton_lab.registry import register

from .config.g1.env_cfg import stack_cube_cfg
from .config.g1.mimic_cfg import MIMIC

register(
    "GalbotG1-StackCube-v0",
    cfg=stack_cube_cfg,
    motion_plan="newton_lab.tasks.stack_cube.config.g1.motion_plan:plan",
    description="Stack three 5 cm cubes: cube_2 on cube_1, cube_3 on cube_2.",
)


def stack_cube_mimic_cfg():
    """StackCube for Mimic generation: the same scene, terms and randomisation."""
    cfg = stack_cube_cfg()
    cfg.task_id = "GalbotG1-StackCube-Mimic-v0"
    return cfg


register(
    "GalbotG1-StackCube-Mimic-v0",
    cfg=stack_cube_mimic_cfg,
    mimic=MIMIC,
    source_task="GalbotG1-StackCube-v0",
    description="Mimic generation variant of GalbotG1-StackCube-v0.",
)
