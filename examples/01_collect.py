"""Collect expert demonstrations with the batched planner (reference example 01).

    python examples/01_collect.py --task GalbotG1-PickCube-v0 --episodes 10 --num-envs 4 \
        --dataset-path data/pick_cube_demos.hdf5
"""

from __future__ import annotations

import argparse
import json

from newton_lab.agents import expert_agent
from newton_lab.envs import make_env


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--task", default="GalbotG1-PickCube-v0")
    p.add_argument("--dataset-path", default="data/pick_cube_demos.hdf5", help=".hdf5 / .h5 / .zarr")
    p.add_argument("--episodes", type=int, default=1)
    p.add_argument("--num-envs", type=int, default=1)
    p.add_argument("--max-steps", type=int, default=1000)
    p.add_argument("--randomize", action="store_true")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--device", default=None)
    p.add_argument("--init-scenario", default=None, help="component tasks: start from this scenario YAML")
    p.add_argument("--save-end-scenario", default=None, help="write the final scene (needs 1 env, 1 episode)")
    p.add_argument("--headless", action="store_true", help="always headless; kept for the reference's flag set")
    args = p.parse_args()

    options = {"init_scenario": args.init_scenario} if args.init_scenario else None
    env = make_env(args.task, num_envs=args.num_envs, device=args.device, seed=args.seed, randomize=args.randomize,
                   task_options=options)
    agent = expert_agent(env)
    summary = env.collect(agent=agent, episodes=args.episodes, path=args.dataset_path, max_steps=args.max_steps,
                          save_end_scenario=args.save_end_scenario)
    keys = ("task", "episodes", "successes", "success_rate", "path", "termination_reasons")
    print(json.dumps({k: summary[k] for k in keys}))


if __name__ == "__main__":
    main()
