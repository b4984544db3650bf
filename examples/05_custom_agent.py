"""A custom agent (reference example 05): a sinusoid on every action column around the start posture.

    python examples/05_custom_agent.py --task GalbotG1-Reach-v0 --num-envs 9 --episodes 36 --max-steps 200

Flags: the env and rollout flags of ``newton-lab evaluate`` (``RolloutArgs`` in ``newton_lab.commands``) plus
``--frequency``.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import torch

from newton_lab.agents import BaseAgent
from newton_lab.cli import parse_args
from newton_lab.commands import RolloutArgs
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


@dataclass(kw_only=True)
class SinusoidArgs(RolloutArgs):
    """``RolloutArgs`` plus the sinusoid's frequency."""

    frequency: float = 1.0
    """Sinusoid frequency [Hz]."""


DEFAULTS = {"task": "GalbotG1-Reach-v0", "num_envs": 9, "episodes": 36, "max_steps": 200, "randomize": True}


def main() -> None:
    args = parse_args(SinusoidArgs, description=__doc__, defaults=DEFAULTS)
    env = make_env(args.task, **args.env_kwargs())
    summary = env.evaluate(agent=SinusoidAgent(args.frequency), **args.rollout_kwargs())
    print(
        json.dumps(
            {k: summary[k] for k in ("task", "episodes", "success_rate", "average_length", "termination_reasons")}
        )
    )


if __name__ == "__main__":
    main()
