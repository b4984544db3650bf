"""Collect one component task of a long-horizon task with its expert (reference example 06).

Pick the component with ``COMPONENT_PRESET`` below. Chain components through scenarios: the end of a Pick
episode is the start of a Nav episode, and so on::

    python examples/06_collect_component_task.py --save-end-scenario outputs/pick_end.yaml
    # then set COMPONENT_PRESET = "pick_to_shelf_nav" and
    python examples/06_collect_component_task.py --init-scenario outputs/pick_end.yaml

Flags: the ``CollectArgs`` of ``newton-lab collect`` (``newton_lab.commands``) without ``--task`` (the preset
names it) and the rerun ones.
"""

from __future__ import annotations

import json

from newton_lab.agents import expert_agent
from newton_lab.cli import parse_args
from newton_lab.commands import CollectArgs
from newton_lab.envs import make_env

COMPONENT_PRESET = "pick_to_shelf_pick"
PRESETS = {
    "pick_to_shelf_pick": "GalbotG1-PickToShelf-Pick-v0",
    "pick_to_shelf_nav": "GalbotG1-PickToShelf-Nav-v0",
    "pick_to_shelf_place": "GalbotG1-PickToShelf-Place-v0",
    "sort_to_shelf_pick": "GalbotG1-SortToShelf-Pick-v0",
    "sort_to_shelf_nav": "GalbotG1-SortToShelf-Nav-v0",
    "sort_to_shelf_place": "GalbotG1-SortToShelf-Place-v0",
}


def main() -> None:
    args = parse_args(
        CollectArgs,
        description=__doc__,
        defaults={"task": PRESETS[COMPONENT_PRESET], "dataset_path": f"data/{COMPONENT_PRESET}.hdf5"},
        exclude=("task", "rerun", "rerun_save", "rerun_worlds"),
    )
    env = make_env(args.task, **args.env_kwargs())
    ref = env.collect(agent=expert_agent(env), **args.collect_kwargs())
    keys = ("task", "episodes", "successes", "success_rate", "path", "termination_reasons")
    out = {k: ref[k] for k in keys}
    if args.save_end_scenario:
        out["saved_end_scenario_path"] = ref["saved_end_scenario_path"]
    print(json.dumps(out))


if __name__ == "__main__":
    main()
