"""Collect one component task of a long-horizon task with its expert (reference example 06).

Pick the component with ``COMPONENT_PRESET`` below. Chain components through scenarios: the end of a Pick
episode is the start of a Nav episode, and so on::

    python examples/06_collect_component_task.py --save-end-scenario outputs/pick_end.yaml
    # then set COMPONENT_PRESET = "pick_to_shelf_nav" and
    python examples/06_collect_component_task.py --init-scenario outputs/pick_end.yaml
"""

from __future__ import annotations

import argparse
import json

from newton_lab.agents import expert_agent
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
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--dataset-path", default=f"data/{COMPONENT_PRESET}.hdf5")
    p.add_argument("--episodes", type=int, default=1)
    p.add_argument("--num-envs", type=int, default=1)
    p.add_argument("--max-steps", type=int, default=1000)
    p.add_argument("--init-scenario", default=None)
    p.add_argument("--save-end-scenario", default=None, help="needs --episodes 1 --num-envs 1")
    p.add_argument("--sorting-object", default=None, choices=["red_cube", "blue_cuboid", "yellow_cylinder", "green_cylinder"])
    p.add_argument("--randomize", action="store_true")
    p.add_argument("--headless", action="store_true", help="always headless; kept for the reference's flag set")
    args = p.parse_args()

    task_id = PRESETS[COMPONENT_PRESET]
    options = {}
    if args.init_scenario:
        options["init_scenario"] = args.init_scenario
    if args.sorting_object:
        options["sorting_object"] = args.sorting_object
    env = make_env(task_id, num_envs=args.num_envs, randomize=args.randomize, task_options=options)
    ref = env.collect(agent=expert_agent(env), episodes=args.episodes, path=args.dataset_path,
                      max_steps=args.max_steps, save_end_scenario=args.save_end_scenario)
    keys = ("task", "episodes", "successes", "success_rate", "path", "termination_reasons")
    out = {k: ref[k] for k in keys}
    if args.save_end_scenario:
        out["saved_end_scenario_path"] = ref["saved_end_scenario_path"]
    print(json.dumps(out))


if __name__ == "__main__":
    main()
