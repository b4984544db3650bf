"""Run a coherent long-horizon task (pick -> nav -> place in one episode) with per-phase agents
(reference example 07).

``COMPOUND_AGENT_PRESET`` picks the phase agents:
  * ``task_default``: every phase's own expert (planner for pick / place, nav agent for nav);
  * ``pick_to_shelf_experts``: the same, spelled out phase by phase;
  * ``pick_to_shelf_policy``: diffusion policies for pick and place (checkpoints trained on the component
    tasks' data at outputs/pick/checkpoint.pt and outputs/place/checkpoint.pt), the nav expert for nav.
The default is ``task_default`` so the example runs without trained checkpoints.

    python examples/07_compound_task.py --task GalbotG1-PickToShelf-v0 --episodes 4 --num-envs 4
"""

from __future__ import annotations

import argparse
import json

from newton_lab.agents import TaskFlowAgent, default_agent
from newton_lab.policies import PolicyAgent
from newton_lab.envs import make_env

COMPOUND_AGENT_PRESET = "task_default"


def phase_agents(env, preset: str):
    if preset == "task_default":
        return None
    if preset == "pick_to_shelf_experts":
        return {p.name: default_agent(p.task_id) for p in env.cfg.phases}
    if preset == "pick_to_shelf_policy":
        return {"pick": PolicyAgent.from_checkpoint("outputs/pick/checkpoint.pt"),
                "place": PolicyAgent.from_checkpoint("outputs/place/checkpoint.pt")}
    raise ValueError(f"unknown COMPOUND_AGENT_PRESET {preset!r}; use task_default, pick_to_shelf_experts or "
                     f"pick_to_shelf_policy")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--task", default="GalbotG1-PickToShelf-v0")
    p.add_argument("--mode", choices=["evaluate", "collect"], default="evaluate")
    p.add_argument("--dataset-path", default="data/compound_task_demos.hdf5")
    p.add_argument("--episodes", type=int, default=36)
    p.add_argument("--num-envs", type=int, default=9)
    p.add_argument("--max-steps", type=int, default=1500)
    p.add_argument("--sorting-object", default=None)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--headless", action="store_true", help="always headless; kept for the reference's flag set")
    args = p.parse_args()

    options = {"sorting_object": args.sorting_object} if args.sorting_object else None
    env = make_env(args.task, num_envs=args.num_envs, randomize=True, seed=args.seed, task_options=options)
    agent = TaskFlowAgent.from_env(env, agents=phase_agents(env, COMPOUND_AGENT_PRESET))
    if args.mode == "collect":
        ref = env.collect(agent=agent, episodes=args.episodes, path=args.dataset_path, max_steps=args.max_steps)
        out = {k: ref[k] for k in ("task", "episodes", "successes", "success_rate", "path", "termination_reasons")}
    else:
        res = env.evaluate(agent=agent, episodes=args.episodes, max_steps=args.max_steps)
        out = {k: res[k] for k in ("task", "episodes", "successes", "success_rate", "average_length",
                                   "termination_reasons")}
    print(json.dumps(out))


if __name__ == "__main__":
    main()
