"""How a PPO policy's actions become the env's action columns.

A Gaussian policy explores around zero with unit scale, so its actions are clipped to [-1, 1] and mapped per column
kind (``env.joints.binding.actions.kinds``): an absolute joint target is an offset from the posture the task starts in
(``joint_scale`` rad at 1), a relative one a step (``relative_scale`` rad at 1), a gripper's target spans the
gripper from open (-1) to closed (+1), and a wheel speed spans +-``wheel_speed`` rad/s. Offsets from the start
posture keep a random policy near the posture the task was designed around (as IsaacLab's joint-position actions
do: default + scale * action).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import torch


@dataclass(frozen=True)
class ActionScales:
    """What an action of 1 means, per column kind."""

    joint_scale: float = 1.0
    """absolute joint targets: offset from the start posture [rad] at action 1. Actions are clipped to [-1, 1], so
    this is also the farthest a joint can go from the start posture: LiftCube's expert moves the shoulder (joint 1)
    0.72 rad and the elbow (joint 4) 0.82 rad from it to reach the cube, and with 0.5 rad PPO (4096 envs, 375
    iterations on an H200) stopped about 10 cm short of the cube and never grasped it (0 of 100)"""
    relative_scale: float = 0.05
    """relative joint targets: step [rad] at action 1"""
    wheel_speed: float = 5.0
    """wheel speeds [rad/s] at action 1"""

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


class ActionMap:
    """``map(a)``: (num_envs, action_dim) policy actions -> the env's action columns (see the module docstring)."""

    def __init__(self, env, scales: ActionScales | None = None, rest: torch.Tensor | None = None) -> None:
        self.scales = scales or ActionScales()
        kinds = env.joints.binding.actions.kinds
        names = list(env.action_joint_names)
        device = env.torch_device
        self.rest = (env.current_action()[0] if rest is None else rest).detach().clone().to(device)
        lo, hi = env.robot.gripper_open, env.robot.gripper_closed
        offset = torch.zeros(len(kinds), device=device)
        scale = torch.zeros(len(kinds), device=device)
        for c, (kind, name) in enumerate(zip(kinds, names)):
            if "gripper" in name:  # open at -1, closed at +1
                offset[c], scale[c] = (lo + hi) / 2, (hi - lo) / 2
            elif kind == "absolute":
                offset[c], scale[c] = self.rest[c], self.scales.joint_scale
            elif kind == "relative":
                scale[c] = self.scales.relative_scale
            elif kind == "velocity":
                scale[c] = self.scales.wheel_speed
            else:  # binary: closed above 0
                offset[c], scale[c] = 0.5, 0.5
        self.offset, self.scale = offset, scale

    def __call__(self, actions: torch.Tensor) -> torch.Tensor:
        return self.offset + self.scale * actions.clamp(-1.0, 1.0)

    def state(self) -> dict[str, Any]:
        """What a checkpoint keeps to map the same way at evaluation."""
        return {"scales": self.scales.as_dict(), "rest": self.rest.cpu().tolist()}
