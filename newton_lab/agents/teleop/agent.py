"""``TeleopAgent``: a device's frames -> the task's actions, one operator driving every env row."""

from __future__ import annotations

import time

import numpy as np
import torch

from ..base import BaseAgent
from .contracts import FrameMapper, check_mapping, check_task
from .devices import TeleopDevice, device_class
from .frames import TeleopFrame
from .jog import TcpJog

USER_EXIT = "user_exit"
"""Termination reason of an episode the operator ended (typed ``done``)."""


class TeleopAgent(BaseAgent):
    """Maps the newest device frame to the task's action columns each control step. A frame's Cartesian jog
    goes through the batched IK (``jog.TcpJog``); what no frame names follows ``no_frame_policy``."""

    done_reason = USER_EXIT

    def __init__(
        self,
        device: TeleopDevice,
        *,
        task_id: str,
        contract: str,
        no_frame_policy: str = "hold",
        twist_scale: float = 1.0,
    ):
        self.device, self.task_id, self.contract = device, task_id, contract
        self.no_frame_policy, self.twist_scale = no_frame_policy, twist_scale
        check_mapping(contract, no_frame_policy)  # now, not at the first step
        self.frame: TeleopFrame | None = None
        """The newest frame taken (held while the device sends nothing new)."""
        self.latencies: list[float] = []
        """Frame produced -> action handed to the env step, per new frame [s]."""
        self._jogs: dict[str, TcpJog] = {}

    @classmethod
    def from_device(
        cls, name: str, *, task: str, no_frame_policy: str = "hold", twist_scale: float = 1.0, **device_kwargs
    ) -> TeleopAgent:
        """Check that device ``name`` can drive ``task`` (one line naming the tasks it can, before the device
        is opened), then open it. ``device_kwargs`` go to the device (e.g. ``transport=`` for gp001,
        ``path=`` for replay)."""
        from ... import tasks as _registered  # noqa: F401  deferred: the task packages declare the contracts (imports every task)

        cls_ = device_class(name)
        contract = check_task(task, name, cls_.contracts)
        device = cls_(**device_kwargs)
        agent = cls(device, task_id=task, contract=contract, no_frame_policy=no_frame_policy, twist_scale=twist_scale)
        device.start()
        return agent

    def setup(self, env) -> None:
        if env.task_id != self.task_id:
            raise ValueError(f"this TeleopAgent drives {self.task_id}, not {env.task_id}; build one per task")
        self.mapper = FrameMapper(
            self.contract,
            env.action_joint_names,
            no_frame_policy=self.no_frame_policy,
            twist_scale=self.twist_scale,
            robot=env.robot,
        )
        self._jogs = {arm: TcpJog(env, arm) for arm in self.device.jog_arms}  # IK captured before the operator moves

    def reset(self, env_ids=None) -> None:
        """A new episode: the device restarts its jog and starts reading the operator (``resume``)."""
        self.device.reset()
        self.device.resume()
        self.frame = None
        super().reset(env_ids)

    def act(self, env, env_ids=None) -> torch.Tensor:
        fresh = self.fresh_rows(env, env_ids)
        if fresh.size:
            for jog in self._jogs.values():
                jog.reset(env)
        new = self.device.poll()
        if new is not None:
            self.frame = new
        arm_targets = {}
        if self.frame is not None:
            for arm, offset in self.frame.tcp_offset.items():
                if arm not in self._jogs:
                    self._jogs[arm] = TcpJog(env, arm)
                arm_targets[arm] = self._jogs[arm](env, offset)
        action = self.mapper(self.frame, env.current_action(), arm_targets)
        if new is not None:
            self.latencies.append(time.perf_counter() - new.timestamp)
        return action

    def done(self, env) -> torch.Tensor:
        """Every row, once the operator ended the episode (``done``; a replay at its end)."""
        return torch.full((env.num_envs,), self.device.exit_requested(), dtype=torch.bool, device=env.torch_device)

    def jog_error(self) -> float:
        """TCP position error of the newest IK solution [m] (0 without a Cartesian jog)."""
        return max((j.error for j in self._jogs.values()), default=0.0)

    def latency(self, control_dt: float | None = None) -> dict[str, float]:
        """Device frame -> action applied: mean / max [ms] over the new frames (and max in control steps)."""
        lat = np.asarray(self.latencies) * 1e3
        out = {
            "frames": int(lat.size),
            "mean_ms": float(lat.mean()) if lat.size else 0.0,
            "max_ms": float(lat.max()) if lat.size else 0.0,
        }
        if control_dt:
            out["max_control_steps"] = out["max_ms"] / (control_dt * 1e3)
        return out

    def close(self) -> None:
        self.device.close()
