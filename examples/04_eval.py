"""Evaluate a trained policy checkpoint (reference example 04); prints the success rate.

    python examples/04_eval.py --task GalbotG1-PickCube-v0 --checkpoint outputs/pick_cube/checkpoint.pt \
        --episodes 50 --num-envs 10 --randomize

Flags: the ``EvaluateArgs`` of ``newton-lab evaluate`` (``newton_lab.commands``) without the rerun ones, with
this example's defaults (a required checkpoint, a seed apart from training data seeds, randomised resets).
"""

from __future__ import annotations

import json

from newton_lab.cli import REQUIRED, parse_args
from newton_lab.commands import EvaluateArgs
from newton_lab.envs import make_env
from newton_lab.envs.rollout import EVAL_REPORT_KEYS
from newton_lab.policies.agent import PolicyAgent

DEFAULTS = {"checkpoint": REQUIRED, "episodes": 36, "num_envs": 9, "seed": 1000, "randomize": True}


def main() -> None:
    args = parse_args(
        EvaluateArgs, description=__doc__, defaults=DEFAULTS, exclude=("rerun", "rerun_save", "rerun_worlds")
    )
    agent = PolicyAgent.from_checkpoint(args.checkpoint)
    env = make_env(args.task, **args.env_kwargs())
    summary = env.evaluate(agent=agent, **args.rollout_kwargs())
    print(f"success rate: {summary['success_rate']:.3f} ({summary['successes']}/{summary['episodes']})")
    print(json.dumps({k: summary[k] for k in EVAL_REPORT_KEYS}))


if __name__ == "__main__":
    main()
