"""GalbotG1-PickCube-v0: pick the red cube and release it on the blue block."""

from newton_lab.registry import register

from .config.g1.env_cfg import pick_cube_cfg
from .config.g1.mimic_cfg import MIMIC

register(
    "GalbotG1-PickCube-v0",
    cfg=pick_cube_cfg,
    motion_plan="newton_lab.tasks.pick_cube.config.g1.motion_plan:plan",
    description="Pick the 5 cm cube and release it on the blue block.",
)


def pick_cube_mimic_cfg():
    """PickCube for Mimic generation: the same scene, terms and randomisation."""
    cfg = pick_cube_cfg()
    cfg.task_id = "GalbotG1-PickCube-Mimic-v0"
    return cfg


register(
    "GalbotG1-PickCube-Mimic-v0",
    cfg=pick_cube_mimic_cfg,
    mimic=MIMIC,
    source_task="GalbotG1-PickCube-v0",
    description="Mimic generation variant of GalbotG1-PickCube-v0.",
)
