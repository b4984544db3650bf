"""SortToShelf: sort one of four objects from the table into its shelf cell (components + coherent task).

Every id takes ``task_options={"sorting_object": "red_cube" | "blue_cuboid" | "yellow_cylinder" |
"green_cylinder"}``.
"""

from newton_lab.task_api.registry import TaskOption, TaskSpec, register

from .config.g1.env_cfg import coherent_cfg, nav_cfg, pick_cfg, place_cfg
from .config.g1.experts import nav_sequence_expert, pick_plan, place_plan
from .objects import DEFAULT_OBJECT, OBJECTS

_OBJECT = TaskOption(
    name="sorting_object",
    choices=("red_cube", "blue_cuboid", "yellow_cylinder", "green_cylinder"),
    default=DEFAULT_OBJECT,
    doc="SortToShelf tasks: the object to sort (selects its cell, thresholds, nav goal and postures)",
)
if _OBJECT.choices != tuple(OBJECTS):
    raise ValueError(f"sorting_object choices {_OBJECT.choices} must name the objects {tuple(OBJECTS)}")
_INIT_SCENARIO = TaskOption(
    name="init_scenario",
    doc="component tasks: start from this scenario YAML (default: the component's captured start for the object)",
)

register(
    TaskSpec(
        id="GalbotG1-SortToShelf-Pick-v0",
        cfg=pick_cfg,
        expert=pick_plan,
        options=(_OBJECT,),
        description="Pick the sorting object from the table into the ready posture.",
    )
)
register(
    TaskSpec(
        id="GalbotG1-SortToShelf-Nav-v0",
        cfg=nav_cfg,
        expert=nav_sequence_expert,
        options=(_OBJECT, _INIT_SCENARIO),
        description="Drive to the object's shelf cell, lift the legs for the upper row, arm to place start.",
    )
)
register(
    TaskSpec(
        id="GalbotG1-SortToShelf-Place-v0",
        cfg=place_cfg,
        expert=place_plan,
        options=(_OBJECT, _INIT_SCENARIO),
        description="Place the carried object in its shelf cell and retract the arm.",
    )
)
register(
    TaskSpec(
        id="GalbotG1-SortToShelf-v0",
        cfg=coherent_cfg,
        options=(_OBJECT,),
        description="Pick -> nav -> place of one sorting object in one episode (coherent task).",
        teleop="mobile_full_body",
    )
)
