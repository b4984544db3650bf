"""GalbotG1-StackCube-v0: stack cube_2 on cube_1, then cube_3 on cube_2 (+ its Mimic variant, its two subtasks on
their own and the two as phases of one episode)."""

from newton_lab.task_api.registry import TaskOption, TaskSpec, mimic_variant, register

from .config.g1.env_cfg import CUBE_YAWS, HEADS, cube_2_cfg, cube_3_cfg, phased_cfg, stack_cube_cfg
from .config.g1.mimic_cfg import MIMIC
from .config.g1.motion_plan import cube_2_plan, cube_3_plan, plan

_HEAD = TaskOption(
    name="head",
    choices=("level", "table"),
    default="level",
    doc="StackCube: the head posture; level (the reference's state-only task) or table (tilted 0.45 rad "
    "as in PickCube, so that the front head camera sees the cubes)",
)
_CUBE_YAW = TaskOption(
    name="cube_yaw",
    choices=("random", "zero"),
    default="random",
    doc="StackCube tasks: the cubes' yaw at reset; random (within 1 rad, the reference) or zero "
    "(every cube square to the table's edges)",
)
SPEC = register(
    TaskSpec(
        id="GalbotG1-StackCube-v0",
        cfg=stack_cube_cfg,
        expert=plan,
        description="Stack three 5 cm cubes: cube_2 on cube_1, cube_3 on cube_2.",
        options=(_HEAD, _CUBE_YAW),
        teleop="left_arm_manipulation",
    )
)
if _HEAD.choices != tuple(HEADS) or _CUBE_YAW.choices != tuple(CUBE_YAWS):
    raise ValueError(f"head / cube_yaw choices must name {tuple(HEADS)} / {tuple(CUBE_YAWS)}")
register(
    TaskSpec(
        id="GalbotG1-StackCube-Cube2-v0",
        cfg=cube_2_cfg,
        expert=cube_2_plan,
        options=(_HEAD, _CUBE_YAW),
        description="StackCube's first subtask: cube_2 onto cube_1, released.",
    )
)
register(
    TaskSpec(
        id="GalbotG1-StackCube-Cube3-v0",
        cfg=cube_3_cfg,
        expert=cube_3_plan,
        options=(_HEAD, _CUBE_YAW),
        description="StackCube's second subtask: cube_3 onto cube_2, which starts on cube_1.",
    )
)
register(
    TaskSpec(
        id="GalbotG1-StackCube-Phased-v0",
        cfg=phased_cfg,
        options=(_HEAD, _CUBE_YAW),
        description="StackCube with its two subtasks as phases of one episode (one policy per phase).",
    )
)
MIMIC_SPEC = register(mimic_variant(SPEC, id="GalbotG1-StackCube-Mimic-v0", mimic=MIMIC))
