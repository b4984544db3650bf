"""GalbotG1-PickCube-v0: pick the red cube and release it on the blue block."""

from newton_lab.registry import register

from ..common import register_mimic_variant
from .config.g1.env_cfg import pick_cube_cfg
from .config.g1.mimic_cfg import MIMIC

register(
    "GalbotG1-PickCube-v0",
    cfg=pick_cube_cfg,
    motion_plan="newton_lab.tasks.pick_cube.config.g1.motion_plan:plan",
    description="Pick the 5 cm cube and release it on the blue block.",
)

register_mimic_variant("GalbotG1-PickCube-v0", pick_cube_cfg, MIMIC)
