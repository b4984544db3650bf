"""How a PPO policy's actions become the env's action columns.

A Gaussian policy explores around zero with unit scale, so its actions are clipped to [-1, 1] and mapped per column
kind (``env.joints.binding.actions.kinds``): an absolute joint target is an offset from the posture the task starts in
(``joint_scale`` rad at 1), a relative one a step (``relative_scale`` rad at 1), a gripper's target spans the
gripper from open (-1) to closed (+1), and a wheel speed spans +-``wheel_speed`` rad/s. Offsets from the start
posture keep a random policy near the posture the task was designed around (as IsaacLab's joint-position actions
do: default + scale * action).

With ``joint_mode="delta"`` an absolute column is instead a step from the joint's current target (``relative_scale``
rad at 1, as ManiSkill's delta joint-position control), kept within the joint's range (and ``delta_range`` of the
start posture, where given). The env holds the state: its current targets (``env.current_action()``), which its
resets put back at the start posture, and which the policy observes as its last action.
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
    """relative joint targets (and absolute ones under ``joint_mode="delta"``): step [rad] at action 1"""
    joint_mode: str = "absolute"
    """how an absolute joint column is driven: ``absolute`` (start posture + ``joint_scale`` * a) or ``delta``
    (current target + ``relative_scale`` * a, within the joint's range and ``delta_range``). Under ``absolute`` the
    policy's exploration noise moves every arm target by up to its standard deviation in rad at each step: PPO on
    LiftCube (4096 envs, 225 iterations on an H200, noise std 0.19) learned to grasp the cube on the table and never
    lifted it (0 of 100); under ``delta`` the same noise moves a target by 0.05 of that per step"""
    delta_range: float | None = None
    """under ``joint_mode="delta"``, how far a target may go from the start posture [rad]; ``None``: as far as the
    joint's range allows. A 1 rad box stopped PPO's LiftCube lift on an H200: after grasping the cube, arm joints 1,
    6 and 7 sat at the box's edge with the actor pushing past it, and the cube never rose more than 1.3 cm (0 of
    100 lifted)"""
    wheel_speed: float = 5.0
    """wheel speeds [rad/s] at action 1"""

    def __post_init__(self) -> None:
        if self.joint_mode not in JOINT_MODES:
            raise ValueError(f"joint_mode must be one of {', '.join(JOINT_MODES)}, got {self.joint_mode!r}")

    def as_dict(self) -> dict[str, float | str]:
        return asdict(self)


JOINT_MODES = ("absolute", "delta")
"""``ActionScales.joint_mode``'s values."""


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
        stepped = torch.zeros(len(kinds), dtype=torch.bool, device=device)
        for c, (kind, name) in enumerate(zip(kinds, names)):
            if "gripper" in name:  # open at -1, closed at +1
                offset[c], scale[c] = (lo + hi) / 2, (hi - lo) / 2
            elif kind == "absolute" and self.scales.joint_mode == "delta":
                stepped[c], scale[c] = True, self.scales.relative_scale
            elif kind == "absolute":
                offset[c], scale[c] = self.rest[c], self.scales.joint_scale
            elif kind == "relative":
                scale[c] = self.scales.relative_scale
            elif kind == "velocity":
                scale[c] = self.scales.wheel_speed
            else:  # binary: closed above 0
                offset[c], scale[c] = 0.5, 0.5
        self.offset, self.scale = offset, scale
        self.stepped = stepped if bool(stepped.any()) else None
        """absolute columns driven as steps from the current target (``joint_mode="delta"``), else ``None``"""
        self.low, self.high = self._delta_bounds(env)

    def _delta_bounds(self, env) -> tuple[torch.Tensor, torch.Tensor]:
        """Where a stepped target stops: the joint's range, within ``delta_range`` of the start posture if given."""
        low, high = (
            torch.as_tensor(r, dtype=self.rest.dtype, device=self.rest.device)
            for r in env.joints.absolute_column_ranges()
        )
        if self.scales.delta_range is not None:
            low = torch.maximum(low, self.rest - self.scales.delta_range)
            high = torch.minimum(high, self.rest + self.scales.delta_range)
        return low, high

    def __call__(self, actions: torch.Tensor, current: torch.Tensor | None = None) -> torch.Tensor:
        """The env's action for ``actions``; ``current``: the env's current targets (``env.current_action()``),
        needed under ``joint_mode="delta"``."""
        out = self.offset + self.scale * actions.clamp(-1.0, 1.0)
        if self.stepped is None:
            return out
        if current is None:
            raise ValueError("joint_mode='delta' steps from the env's targets: pass current=env.current_action()")
        stepped = torch.minimum(torch.maximum(current + out, self.low), self.high)
        return torch.where(self.stepped, stepped, out)

    def for_env(self, actions: torch.Tensor, env) -> torch.Tensor:
        """``env``'s action for ``actions``: reads its current targets only when a column steps from them."""
        return self(actions, env.current_action() if self.stepped is not None else None)

    def state(self) -> dict[str, Any]:
        """What a checkpoint keeps to map the same way at evaluation."""
        return {"scales": self.scales.as_dict(), "rest": self.rest.cpu().tolist()}
