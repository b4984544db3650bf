"""A custom agent (reference example 05): a sinusoid on every action column around the start posture.

    python examples/05_custom_agent.py --task GalbotG1-Reach-v0 --num-envs 9 --episodes 36 --max-steps 200
"""

from __future__ import annotations

import argparse
import json
import math

import torch

from newton_lab.agents import BaseAgent
from newton_lab.envs import make_env


class SinusoidAgent(BaseAgent):
    """Holds the start posture plus 0.1 * sin(2 pi f t) on every action column."""

    def __init__(self, frequency: float):
        self.frequency = frequency
        self.t = 0
        self.start: torch.Tensor | None = None

    def reset(self, env_ids=None) -> None:
        self.t = 0

    def act(self, env, env_ids=None) -> torch.Tensor:
        if self.start is None:
            self.start = env.current_action().clone()
        self.t += 1
        return self.start + 0.1 * math.sin(2 * math.pi * self.frequency * self.t * env.cfg.control_dt)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--task", default="GalbotG1-Reach-v0")
    p.add_argument("--num-envs", type=int, default=9)
    p.add_argument("--episodes", type=int, default=36)
    p.add_argument("--max-steps", type=int, default=200)
    p.add_argument("--frequency", type=float, default=1.0, help="[Hz]")
    p.add_argument("--device", default=None)
    p.add_argument("--headless", action="store_true", help="always headless")
    args = p.parse_args()
    env = make_env(args.task, num_envs=args.num_envs, device=args.device, randomize=True)
    summary = env.evaluate(agent=SinusoidAgent(args.frequency), episodes=args.episodes, max_steps=args.max_steps)
    print(json.dumps({k: summary[k] for k in ("task", "episodes", "success_rate", "average_length",
                                              "termination_reasons")}))


if __name__ == "__main__":
    main()
