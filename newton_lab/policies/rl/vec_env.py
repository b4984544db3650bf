"""The batched env as rsl_rl's ``VecEnv``: torch tensors on the env's device, straight from the captured step.

Observations are a ``TensorDict`` of two groups: ``policy`` (the env's observation vector: every term of the task
in ``obs_mode="state"``, proprioception only with ``obs_mode="sensors"``; with ``joint_state`` also the commanded
joints' velocities and targets, ``observations.PolicyObservation``) and ``critic`` (the policy's plus the
privileged object poses when the policy does not see them: the critic is thrown away after training, so it may
read what the robot cannot measure). ``dones`` is terminated or truncated; ``extras["time_outs"]`` marks the
truncated rows (PPO bootstraps their value). Rows that end are reset inside the step (their ``obs`` is the new
episode's first), as rsl_rl expects. The ended episodes, their successes and returns are counted on the device
(no host sync in a step) and read once an iteration (``take_iteration_counts``) and once a chunk
(``take_episode_counts``): an episode counts as a success when the task's success held at any of its steps
(training envs may run on past success, ``PPOConfig.end_on_success``). The env's own check of the actions'
finiteness would read them on the host every step; here it runs on the device, and ``take_iteration_counts``
raises the env's one-line error for an iteration whose actions held NaN or inf.
"""

from __future__ import annotations

import time

import torch
from rsl_rl.env import VecEnv
from tensordict import TensorDict

from .actions import ActionMap, ActionScales
from .observations import PolicyObservation

COUNTS = ("episodes", "successes", "returns", "lengths", "rewards", "nonfinite")
"""What the vec env counts: episodes ended, their successes, return sum and length sum [steps], every row's reward
sum, and the steps whose actions held NaN or inf."""


class RslRlVecEnv(VecEnv):
    """``env`` (a ``NewtonEnv``) stepped by PPO actions through ``ActionMap``; ``privileged``: a second env of the
    same task and seed in state mode is not needed, the critic reads ``env.buffers.entity_poses`` directly."""

    def __init__(self, env, scales: ActionScales | None = None, *, joint_state: bool = False) -> None:
        self.env = env
        self.num_envs = env.num_envs
        self.num_actions = env.action_dim
        self.device = env.torch_device
        self.max_episode_length = int(env.cfg.max_episode_steps)
        self.cfg = {"task_id": env.task_id, "task_options": dict(env.cfg.options)}
        env.reset()
        self.action_map = ActionMap(env, scales)
        self.policy_obs = PolicyObservation(env, joint_state)
        self.episode_length_buf = torch.zeros(self.num_envs, dtype=torch.long, device=self.device)
        self.sensors = env.cfg.options.get("obs_mode") == "sensors"
        self.returns = torch.zeros(self.num_envs, device=self.device)
        self.succeeded = torch.zeros(self.num_envs, dtype=torch.bool, device=self.device)
        self.pending = torch.zeros(len(COUNTS), dtype=torch.float64, device=self.device)
        """``COUNTS`` of the steps since the last host read (``_fold``), on the device"""
        self.iteration = dict.fromkeys(COUNTS, 0.0)
        """``COUNTS`` since the last ``take_iteration_counts``, on the host"""
        self.chunk = dict.fromkeys(COUNTS, 0.0)
        """``COUNTS`` since the last ``take_episode_counts``, on the host"""
        self.reward_steps = 0
        self.step_s = 0.0
        """seconds in ``step`` (the env's step and this bookkeeping) since the last ``take_episode_counts``: wall
        time on the CPU; on a GPU the stream's time between CUDA events around each step (``step_events``), as a
        step no longer waits for the device"""
        self.step_events: list[tuple[torch.cuda.Event, torch.cuda.Event]] = []

    def restart(self, seed: int) -> None:
        """Reseed and reset every row (``env.reseed``) and forget the running episodes' returns: a chunk of PPO
        iterations that starts here depends only on ``seed`` and the runner's state, so a resumed run continues as
        the uninterrupted one did."""
        self.env.buffers.actions.zero_()  # as a new env's: its last-action observation term reads them after the reset
        self.env.reseed(seed)
        self.returns.zero_()
        self.succeeded.zero_()
        self.episode_length_buf.zero_()

    def _observations(self) -> TensorDict:
        policy = self.policy_obs()
        critic = policy
        if self.sensors:  # the critic also sees where the objects are
            critic = torch.cat([policy, self.env.buffers.entity_poses.reshape(self.num_envs, -1)], dim=1)
        return TensorDict({"policy": policy, "critic": critic}, batch_size=[self.num_envs], device=self.device)

    def get_observations(self) -> TensorDict:
        return self._observations()

    def step(self, actions: torch.Tensor):
        t0 = time.perf_counter()
        timed = self._timing_events()
        mapped = self.action_map.for_env(actions, self.env)
        nonfinite = (~torch.isfinite(mapped).all()).to(torch.float64)
        _, reward, terminated, truncated, info = self.env.step(mapped, check_finite=False)
        dones = terminated | truncated
        reward = reward.clone()
        self.returns += reward
        self.reward_steps += self.num_envs
        self.succeeded |= info["success"]
        self.episode_length_buf += 1
        ended = dones.to(torch.float64)
        wins = (self.succeeded & dones).sum().to(torch.float64)
        returns, lengths = (self.returns * ended).sum(), (self.episode_length_buf * ended).sum()
        self.pending += torch.stack([ended.sum(), wins, returns, lengths, reward.sum().to(torch.float64), nonfinite])
        self.returns.masked_fill_(dones, 0.0)
        self.succeeded &= ~dones
        self.episode_length_buf.masked_fill_(dones, 0)
        obs = self._observations()
        if timed is None:
            self.step_s += time.perf_counter() - t0
        else:
            timed[1].record()
            self.step_events.append(timed)
        return obs, reward, dones.long(), {"time_outs": truncated.clone()}

    def _timing_events(self) -> tuple[torch.cuda.Event, torch.cuda.Event] | None:
        """A recorded start event and an end event for this step on a GPU, else ``None``."""
        if self.device.type != "cuda":
            return None
        start, end = torch.cuda.Event(enable_timing=True), torch.cuda.Event(enable_timing=True)
        start.record()
        return start, end

    def _fold(self) -> None:
        """Add the device counts into the iteration's and the chunk's (one host sync); raises the env's one-line
        error if a step's actions held NaN or inf."""
        pending = dict(zip(COUNTS, self.pending.tolist()))
        self.pending.zero_()
        for totals in (self.iteration, self.chunk):
            for key, value in pending.items():
                totals[key] += value
        if pending["nonfinite"]:
            raise ValueError(
                f"actions contain NaN or inf in {int(pending['nonfinite'])} steps of this PPO iteration; the actor "
                "diverged: resume from the last chunk with a lower --learning-rate"
            )

    def take_iteration_counts(self) -> dict[str, float | None]:
        """Episodes ended, their successes, mean return and mean length [steps] since the last call (then reset):
        one host sync. Raises the env's one-line error if a step's actions held NaN or inf since the last call."""
        try:
            self._fold()
        finally:
            counts, self.iteration = self.iteration, dict.fromkeys(COUNTS, 0.0)
        n = int(counts["episodes"])
        return {
            "episodes": n,
            "successes": int(counts["successes"]),
            "mean_return": counts["returns"] / n if n else None,
            "mean_length": counts["lengths"] / n if n else None,
        }

    def take_episode_counts(self) -> dict[str, float]:
        """Episodes ended, successes, their mean return, the mean reward of a step and the seconds spent stepping
        since the last call (then reset)."""
        self._fold()
        counts, self.chunk = self.chunk, dict.fromkeys(COUNTS, 0.0)
        n, successes = int(counts["episodes"]), counts["successes"]
        out = {
            "episodes": n,
            "successes": int(successes),
            "success_rate": successes / n if n else None,
            "mean_return": counts["returns"] / n if n else None,
            "mean_step_reward": counts["rewards"] / self.reward_steps if self.reward_steps else None,
            "env_step_s": round(self.step_s + sum(s.elapsed_time(e) for s, e in self.step_events) / 1e3, 3),
        }
        self.step_s = 0.0
        self.step_events.clear()
        self.reward_steps = 0
        return out
