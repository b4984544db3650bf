"""GalbotG1-StackCube-v0: stack cube_2 on cube_1, then cube_3 on cube_2."""

from newton_lab.registry import register

from ..common import register_mimic_variant
from .config.g1.env_cfg import stack_cube_cfg
from .config.g1.mimic_cfg import MIMIC

register(
    "GalbotG1-StackCube-v0",
    cfg=stack_cube_cfg,
    motion_plan="newton_lab.tasks.stack_cube.config.g1.motion_plan:plan",
    description="Stack three 5 cm cubes: cube_2 on cube_1, cube_3 on cube_2.",
)

register_mimic_variant("GalbotG1-StackCube-v0", stack_cube_cfg, MIMIC)
