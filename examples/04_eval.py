"""Evaluate a trained policy checkpoint (reference example 04); prints the success rate.

    python examples/04_eval.py --task GalbotG1-PickCube-v0 --checkpoint outputs/pick_cube/checkpoint.pt \
        --episodes 50 --num-envs 10 --randomize
"""

from __future__ import annotations

import argparse
import json

from newton_lab.policies import PolicyAgent
from newton_lab.envs import make_env
from newton_lab.envs.rollout import EVAL_REPORT_KEYS


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--task", default="GalbotG1-PickCube-v0")
    p.add_argument("--checkpoint", required=True)
    p.add_argument("--episodes", type=int, default=36)
    p.add_argument("--num-envs", type=int, default=9)
    p.add_argument("--max-steps", type=int, default=1000)
    p.add_argument("--seed", type=int, default=1000, help="evaluation seed (keep it apart from training data seeds)")
    p.add_argument("--randomize", action=argparse.BooleanOptionalAction, default=True)
    p.add_argument("--device", default=None)
    p.add_argument("--headless", action="store_true", help="always headless")
    args = p.parse_args()
    agent = PolicyAgent.from_checkpoint(args.checkpoint)
    env = make_env(args.task, num_envs=args.num_envs, device=args.device, seed=args.seed, randomize=args.randomize)
    summary = env.evaluate(agent=agent, episodes=args.episodes, max_steps=args.max_steps)
    print(f"success rate: {summary['success_rate']:.3f} ({summary['successes']}/{summary['episodes']})")
    print(json.dumps({k: summary[k] for k in EVAL_REPORT_KEYS}))


if __name__ == "__main__":
    main()
