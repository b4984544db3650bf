"""GalbotG1-LiftCube-v0: grasp the cube on the table and lift it 10 cm."""

from newton_lab.task_api.registry import TaskSpec, register

from .config.g1.env_cfg import lift_cube_cfg
from .config.g1.motion_plan import plan

SPEC = register(
    TaskSpec(
        id="GalbotG1-LiftCube-v0",
        cfg=lift_cube_cfg,
        expert=plan,
        description="Grasp the 5 cm cube and lift it 10 cm above its start (held 5 steps).",
        teleop="left_arm_manipulation",
    )
)
