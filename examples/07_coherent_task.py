"""Run a coherent long-horizon task (pick -> nav -> place in one episode) with per-phase agents
(reference example 07).

``COMPOUND_AGENT_PRESET`` picks the phase agents:
  * ``task_default``: every phase's own expert (planner for pick / place, nav agent for nav);
  * ``pick_to_shelf_experts``: the same, spelled out phase by phase;
  * ``pick_to_shelf_policy``: diffusion policies for pick and place (checkpoints trained on the component
    tasks' data at outputs/pick/checkpoint.pt and outputs/place/checkpoint.pt), the nav expert for nav;
    each checkpoint is checked against its phase and the env at once (``phase_policy_agent``).
The default is ``task_default`` so the example runs without trained checkpoints. The recipe that trains the two
policies from the coherent task's own expert demos (collect, ``newton-lab split --out``, train per phase) and
evaluates them here, privileged-free (``--obs-mode sensors``, front camera): the user guide's tutorial, chapter 3
(docs/tutorial/compound_task.md).

    python examples/07_coherent_task.py --task GalbotG1-PickToShelf-v0 --episodes 4 --num-envs 4

Flags: the ``CollectArgs`` of ``newton-lab collect`` (``newton_lab.commands``) without the rerun ones, plus
``--mode``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Literal

from newton_lab.agents import TaskFlowAgent, expert_agent
from newton_lab.cli import parse_args
from newton_lab.commands import CollectArgs
from newton_lab.envs import make_env
from newton_lab.policies.agent import phase_policy_agent

COMPOUND_AGENT_PRESET = "task_default"


@dataclass(kw_only=True)
class CompoundArgs(CollectArgs):
    """``CollectArgs`` plus what to do with the episodes."""

    mode: Literal["evaluate", "collect"] = "evaluate"
    """evaluate: report the success rate; collect: also write the episodes to --dataset-path"""


DEFAULTS = {
    "task": "GalbotG1-PickToShelf-v0",
    "dataset_path": "data/coherent_task_demos.hdf5",
    "episodes": 36,
    "num_envs": 9,
    "max_steps": 1500,
    "randomize": True,
}


def coherent_agent(env, preset: str) -> TaskFlowAgent:
    if preset == "task_default":
        return TaskFlowAgent.from_env(env)
    if preset == "pick_to_shelf_experts":
        return TaskFlowAgent.from_env(env, agents={p.name: expert_agent(p.task_id) for p in env.cfg.phases})
    if preset == "pick_to_shelf_policy":
        return phase_policy_agent(env, {"pick": "outputs/pick/checkpoint.pt", "place": "outputs/place/checkpoint.pt"})
    raise ValueError(
        f"unknown COMPOUND_AGENT_PRESET {preset!r}; use task_default, pick_to_shelf_experts or pick_to_shelf_policy"
    )


def main() -> None:
    args = parse_args(
        CompoundArgs, description=__doc__, defaults=DEFAULTS, exclude=("rerun", "rerun_save", "rerun_worlds")
    )
    env = make_env(args.task, **args.env_kwargs())
    agent = coherent_agent(env, COMPOUND_AGENT_PRESET)
    if args.mode == "collect":
        ref = env.collect(agent=agent, **args.collect_kwargs())
        out = {k: ref[k] for k in ("task", "episodes", "successes", "success_rate", "path", "termination_reasons")}
    else:
        res = env.evaluate(agent=agent, **args.rollout_kwargs())
        out = {
            k: res[k]
            for k in (
                "task",
                "episodes",
                "successes",
                "success_rate",
                "average_length",
                "termination_reasons",
                "phases",
            )
        }
    print(json.dumps(out))


if __name__ == "__main__":
    main()
