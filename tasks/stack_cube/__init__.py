"""GalbotG1-StackCube-v0: stack cube_2 on cube_1, then cube_3 on cube_2 (+ its Mimic variant)."""

from newton_lab.task_api.registry import TaskOption, TaskSpec, mimic_variant, register

from .config.g1.env_cfg import HEADS, stack_cube_cfg
from .config.g1.mimic_cfg import MIMIC
from .config.g1.motion_plan import plan

SPEC = register(TaskSpec(
    id="GalbotG1-StackCube-v0",
    cfg=stack_cube_cfg,
    expert=plan,
    description="Stack three 5 cm cubes: cube_2 on cube_1, cube_3 on cube_2.",
    options=(TaskOption(name="head", choices=("level", "table"), default="level",
                        doc="StackCube: the head posture; level (the reference's state-only task) or table (tilted "
                            "0.45 rad as in PickCube, so that the front head camera sees the cubes)"),),
    teleop="left_arm_manipulation",
))
if SPEC.options[0].choices != tuple(HEADS):
    raise ValueError(f"head choices {SPEC.options[0].choices} must name the postures {tuple(HEADS)}")
MIMIC_SPEC = register(mimic_variant(SPEC, id="GalbotG1-StackCube-Mimic-v0", mimic=MIMIC))
