"""Collect expert demonstrations with the batched planner (reference example 01).

    python examples/01_collect.py --task GalbotG1-PickCube-v0 --episodes 10 --num-envs 4 \
        --dataset-path data/pick_cube_demos.hdf5

Flags: the ``CollectArgs`` of ``newton-lab collect`` (``newton_lab.commands``), without the rerun ones.
"""

from __future__ import annotations

import json

from newton_lab.agents import expert_agent
from newton_lab.cli import parse_args
from newton_lab.commands import CollectArgs
from newton_lab.envs import make_env


def main() -> None:
    args = parse_args(CollectArgs, description=__doc__, exclude=("rerun", "rerun_save", "rerun_worlds"))
    env = make_env(args.task, **args.env_kwargs())
    summary = env.collect(agent=expert_agent(env), **args.collect_kwargs())
    keys = ("task", "episodes", "successes", "success_rate", "path", "termination_reasons")
    print(json.dumps({k: summary[k] for k in keys}))


if __name__ == "__main__":
    main()
