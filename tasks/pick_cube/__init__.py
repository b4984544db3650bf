"""GalbotG1-PickCube-v0: pick the red cube and release it on the blue block (+ its Teleop and Mimic variants)."""

from newton_lab.task_api.registry import TaskSpec, mimic_variant, register

from .config.g1.env_cfg import pick_cube_cfg, pick_cube_teleop_cfg
from .config.g1.mimic_cfg import MIMIC
from .config.g1.motion_plan import plan

SPEC = register(
    TaskSpec(
        id="GalbotG1-PickCube-v0",
        cfg=pick_cube_cfg,
        expert=plan,
        description="Pick the 5 cm cube and release it on the blue block.",
        teleop="left_arm_manipulation",
    )
)
TELEOP_SPEC = register(
    TaskSpec(
        id="GalbotG1-PickCube-Teleop-v0",
        cfg=pick_cube_teleop_cfg,
        description="PickCube for an operator: wrist + head cameras at 640x480; the operator ends each episode.",
        teleop="left_arm_manipulation",
    )
)
MIMIC_SPEC = register(mimic_variant(SPEC, id="GalbotG1-PickCube-Mimic-v0", mimic=MIMIC))
