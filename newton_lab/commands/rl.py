"""Arguments of ``newton-lab train-rl``: PPO on a task's dense reward."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

from ..task_api.registry import DEFAULT_TASK_ID


@dataclass(kw_only=True)
class TrainRLArgs:
    """``newton-lab train-rl``: PPO (rsl_rl) on a task's dense reward, from state (or ``--obs-mode sensors``:
    proprioception for the actor, the objects' poses for the critic)."""

    task: str = DEFAULT_TASK_ID
    """task id (see `newton-lab tasks`)"""
    num_envs: int = 4096
    """parallel env rows"""
    device: str = "cuda:0"
    """Warp and torch device (cpu for a small trial)"""
    seed: int = 0
    """seed of the env's reset randomisation and of the networks"""
    iterations: int = 1500
    """PPO iterations (each: --steps-per-env env steps on every row, then the update)"""
    time_budget_s: float | None = None
    """wall-clock budget of the training [s]: the last chunk of iterations is cut to end within it"""
    steps_per_env: int = 24
    """env steps per row in each iteration's rollout"""
    chunk_iterations: int = 25
    """iterations between resume points and curve rows"""
    hidden_dims: list[int] | None = None
    """hidden layer widths of the actor and the critic (default 256 128 64)"""
    learning_rate: float = 1e-3
    """Adam's initial learning rate (adapted to the KL target)"""
    epochs: int = 5
    """passes over each iteration's rollout in the PPO update"""
    mini_batches: int = 4
    """minibatches each pass is cut into (an update is epochs x mini_batches optimiser steps)"""
    end_on_success: bool = False
    """end training episodes at the task's success (default: they run to the time limit, so that PPO is not taught
    to hover outside the success region; see PPOConfig.end_on_success)"""
    episode_length_s: float | None = None
    """time limit of the training episodes [s] (default: the task's; PickCube's 3600 s is too long for PPO: a row
    whose cube went out of reach would keep it there)"""
    output_dir: str = "outputs/ppo"
    """folder of checkpoint.pt, curve.json, resume.pt and the tensorboard log"""
    resume: bool = False
    """continue the interrupted run in --output-dir from its resume.pt"""
    eval_episodes: int | None = None
    """then evaluate the actor on this many held-out randomised episodes (seed + 10000; default: no evaluation)"""
    run_record: str | None = None
    """write the run record (JSON) here (default outputs/records/train-rl-<task>-<UTC time>.json)"""
    joint_mode: Literal["absolute", "delta"] = "absolute"
    """how the actor drives the arm joints: absolute (start posture + 1 rad * action) or delta (current target +
    0.05 rad * action per step, within the joint's range; see ActionScales.joint_mode)"""
    init_noise_std: float = 0.5
    """the policy's initial exploration noise (the Gaussian's standard deviation), in action units"""
    joint_state: bool = False
    """the actor also observes the commanded joints' velocities and current targets (delta targets move from the
    target, which the task's observation does not hold)"""
    domain_randomize: str | None = None
    """domain randomisation: AXIS=LEVEL,... of the physics axes (object_mass, object_size, friction; LEVEL mild,
    strong or a factor): each env row draws its own value between 1/LEVEL and LEVEL, kept for the run"""
    task_options: dict[str, Any] = field(default_factory=dict, metadata={"task_options": True})

    def domain_randomization(self) -> dict[str, float]:
        """``--domain-randomize`` as axis -> level; one-line errors (the rows render no cameras: physics only)."""
        from ..task_api.perturbations import AXES, parse_randomization  # deferred: only this flag needs it

        levels = parse_randomization(self.domain_randomize) if self.domain_randomize is not None else {}
        seen = [name for name in levels if AXES[name].acts_on != "physics"]
        if seen:
            raise ValueError(f"--domain-randomize {seen[0]}: train-rl's rows render no cameras; randomise physics")
        return levels

    def ppo_config(self):
        """The ``PPOConfig`` of these arguments."""
        from ..policies.rl.actions import ActionScales  # deferred: torch is slow to import
        from ..policies.rl.train import PPOConfig  # deferred: rsl_rl and torch are slow to import

        return PPOConfig(
            num_envs=self.num_envs,
            device=self.device,
            seed=self.seed,
            task_options=dict(self.task_options),
            iterations=self.iterations,
            time_budget_s=self.time_budget_s,
            chunk_iterations=self.chunk_iterations,
            num_steps_per_env=self.steps_per_env,
            **({"hidden_dims": tuple(self.hidden_dims)} if self.hidden_dims else {}),
            learning_rate=self.learning_rate,
            num_learning_epochs=self.epochs,
            num_mini_batches=self.mini_batches,
            end_on_success=self.end_on_success,
            episode_length_s=self.episode_length_s,
            domain_randomize=self.domain_randomization(),
            joint_state=self.joint_state,
            init_noise_std=self.init_noise_std,
            scales=ActionScales(joint_mode=self.joint_mode),
        )
