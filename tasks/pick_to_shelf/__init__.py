"""PickToShelf: pick a bar from the table, drive to the shelf, place it (components + coherent task)."""

from pathlib import Path

from newton_lab.task_api.experts import yaml_plan
from newton_lab.task_api.registry import TaskOption, TaskSpec, register

from .config.g1.env_cfg import coherent_cfg, nav_cfg, nav_expert, pick_cfg, place_cfg

_PLANS = Path(__file__).parent / "config" / "g1"
_INIT_SCENARIO = TaskOption(
    name="init_scenario", doc="component tasks: start from this scenario YAML (default: the component's captured start)"
)

register(
    TaskSpec(
        id="GalbotG1-PickToShelf-Pick-v0",
        cfg=pick_cfg,
        expert=yaml_plan(_PLANS / "pick_plan.yaml"),
        description="Pick the bar from the table into the carry posture.",
    )
)
register(
    TaskSpec(
        id="GalbotG1-PickToShelf-Nav-v0",
        cfg=nav_cfg,
        expert=nav_expert,
        options=(_INIT_SCENARIO,),
        description="Carry the bar to the shelf on the wheeled base.",
    )
)
register(
    TaskSpec(
        id="GalbotG1-PickToShelf-Place-v0",
        cfg=place_cfg,
        expert=yaml_plan(_PLANS / "place_plan.yaml"),
        options=(_INIT_SCENARIO,),
        description="Place the carried bar upright on the shelf deck.",
    )
)
register(
    TaskSpec(
        id="GalbotG1-PickToShelf-v0",
        cfg=coherent_cfg,
        description="Pick -> nav -> place in one episode (coherent task).",
    )
)
