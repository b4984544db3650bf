"""SortToShelf-All: sort all four SortToShelf objects into their shelf cells in one episode (coherent task), and the
Return component it needs between objects.

Each episode draws the order at reset (``mdp.events.draw_sort_order``, over the objects also shuffled on the table);
per object the phases are pick, nav, place and, but after the last, return: 15 phases, ``pick_1`` .. ``place_4``
(``order.phase_layout``). The pick, nav and place phases run SortToShelf's components for the row's target object;
return drives back to the table, where every pick starts.

How a phase policy knows its object: the observation ``sorting_object`` is a one-hot of the row's target (4
columns; not privileged, so ``obs_mode="sensors"`` keeps it, while every object pose is dropped). A phase kind is
learned either as one policy conditioned on it, or as one policy per object (the split's ``by_target``, the
pipeline's ``--per-target``), switched per row on it as the task-flow agent switches the experts. The pipeline's gpu
recipe trains the pick per object (a conditioned pick policy lifted the wrong objects) and the place conditioned.

Where episodes stall: the evaluation's ``phases`` (each of the 15) and, per object, the signals ``picked_<object>``
(lifted to the ready posture) and ``sorted_<object>`` (let go in its cell). Its dense reward is SortToShelf's staged
reward of the row's target in each phase, ``(phase + r_phase) / 15`` (``mdp.rewards``).
"""

from newton_lab.tasks.sort_to_shelf.objects import DEFAULT_OBJECT, OBJECTS

from newton_lab.task_api.registry import TaskOption, TaskSpec, register

from .config.g1.env_cfg import TARGET_OPTION, all_cfg, return_cfg
from .config.g1.experts import return_expert

_OBJECT = TaskOption(
    name="sorting_object",
    choices=("red_cube", "blue_cuboid", "yellow_cylinder", "green_cylinder"),
    default=DEFAULT_OBJECT,
    doc="SortToShelf-Return: start where SortToShelf-Place left this object in its cell",
)
if _OBJECT.choices != tuple(OBJECTS) or _OBJECT.name != TARGET_OPTION:
    raise ValueError(f"sorting_object choices {_OBJECT.choices} must name the objects {tuple(OBJECTS)}")
_INIT_SCENARIO = TaskOption(
    name="init_scenario", doc="start from this scenario YAML (default: the end of the object's place)"
)

register(
    TaskSpec(
        id="GalbotG1-SortToShelf-Return-v0",
        cfg=return_cfg,
        expert=return_expert,
        options=(_OBJECT, _INIT_SCENARIO),
        description="Back from the shelf to the table: legs down, arm to ready, drive to the pick position.",
    )
)
register(
    TaskSpec(
        id="GalbotG1-SortToShelf-All-v0",
        cfg=all_cfg,
        description="Sort all four objects into their cells in a per-episode order: 15 phases (coherent task).",
        teleop="mobile_full_body",
    )
)
