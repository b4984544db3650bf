"""JointTargetAgent: command named joints to fixed targets, optionally ramped."""

from __future__ import annotations

import torch

from .base import BaseAgent


class JointTargetAgent(BaseAgent):
    """Drive ``targets`` (joint name -> position [rad | m]); every other column holds its current target.

    With ``max_step`` the command moves from the current targets toward ``targets`` with all joints scaled so
    that the largest remaining error moves at most ``max_step`` per control step. ``done``: every named joint
    within ``tolerance`` of its target for ``hold_steps`` consecutive checks.
    """

    def __init__(
        self, targets: dict[str, float], *, max_step: float | None = None, tolerance: float = 0.12, hold_steps: int = 1
    ):
        if not targets:
            raise ValueError("JointTargetAgent needs at least one joint target")
        self.targets = {str(k): float(v) for k, v in targets.items()}
        self.max_step = None if max_step is None else float(max_step)
        self.tolerance = float(tolerance)
        self.hold_steps = int(hold_steps)

    def setup(self, env) -> None:
        names = list(env.action_joint_names)
        missing = [j for j in self.targets if j not in names]
        if missing:
            raise ValueError(f"env {env.task_id} has no action columns for {missing}; its columns are {names}")
        self._cols = [names.index(j) for j in self.targets]
        self._goal = torch.tensor(list(self.targets.values()), device=env.torch_device)
        self._held = torch.zeros(env.num_envs, dtype=torch.long, device=env.torch_device)

    def reset(self, env_ids=None) -> None:
        super().reset(env_ids)
        if self.bound_env is not None:
            self._held[slice(None) if env_ids is None else torch.as_tensor(env_ids, device=self._held.device)] = 0

    def act(self, env, env_ids=None) -> torch.Tensor:
        self.bind(env)
        out = env.current_action()
        cmd = out[:, self._cols]
        if self.max_step is None:
            cmd = self._goal.expand_as(cmd).clone()
        else:
            err = self._goal - cmd
            scale = torch.clamp(self.max_step / err.abs().amax(dim=1, keepdim=True).clamp_min(1e-9), max=1.0)
            cmd = cmd + err * scale
        out[:, self._cols] = cmd
        return out

    def done(self, env) -> torch.Tensor:
        self.bind(env)
        q = env.joints.positions(list(self.targets))
        ok = ((q - self._goal).abs() <= self.tolerance).all(dim=1)
        self._held = torch.where(ok, self._held + 1, torch.zeros_like(self._held))
        return self._held >= self.hold_steps
