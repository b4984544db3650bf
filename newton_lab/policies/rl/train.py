"""PPO on a task's dense reward through rsl_rl (the library mjlab and IsaacLab train with): ``train_ppo(task, cfg)``.

The run is cut into chunks of ``cfg.chunk_iterations`` PPO iterations; after each chunk the runner's state is saved
(``resume.pt``: models, optimiser, iteration, the action map) and a row is added to ``curve.json`` (iteration, env
steps, wall seconds, env-steps/s with the update included, success rate and mean return of the episodes that ended in
the chunk, the mean reward of a step, and the seconds of rollout, env steps and update). Every chunk starts from rows
reset with the seed ``cfg.seed + chunk index``, so that a run resumed after a chunk gives the curve and the actor of the
uninterrupted run (the episodes running at a chunk's end are cut there and not counted). A killed run continues from its
last chunk with ``resume=True``; ``cfg.time_budget_s`` ends the run within it, the last chunk cut short to fit at the
pace of the one before (a resumed run's budget counts the seconds before the interruption). rsl_rl writes its
tensorboard log into the same folder. The result is ``checkpoint.pt``: the deterministic actor, its observation
normaliser and the action map, which ``RLPolicyAgent`` (and ``newton-lab evaluate --checkpoint``) runs.
"""

from __future__ import annotations

import io
import json
import sys
import time
import warnings
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import torch
from rsl_rl.runners import OnPolicyRunner

from ...envs import make_env
from ...envs.perturb import randomize_env
from .actions import ActionScales
from .vec_env import RslRlVecEnv

CHECKPOINT_FORMAT = "newton_lab.policies.rl"
"""``format`` tag of an RL checkpoint (the diffusion policy's is ``newton_lab.policies.diffusion``)."""
CHECKPOINT_VERSION = 1
RESUME_NAME = "resume.pt"


@dataclass(kw_only=True)
class PPOConfig:
    """A PPO run: env rows and device, the rollout and update sizes, the networks, when to stop."""

    num_envs: int = 4096
    device: str = "cuda:0"
    seed: int = 0
    task_options: dict[str, Any] = field(default_factory=dict)
    iterations: int = 1500
    """PPO iterations (each: num_steps_per_env env steps on every row, then the update)"""
    time_budget_s: float | None = None
    """wall-clock budget of the training [s]: the last chunk is cut to end within it at the pace of the one before"""
    chunk_iterations: int = 25
    """iterations between resume points and curve rows"""
    num_steps_per_env: int = 24
    hidden_dims: tuple[int, ...] = (256, 128, 64)
    learning_rate: float = 1e-3
    num_learning_epochs: int = 5
    num_mini_batches: int = 4
    entropy_coef: float = 0.005
    gamma: float = 0.99
    lam: float = 0.95
    desired_kl: float = 0.01
    init_noise_std: float = 0.5
    """the Gaussian policy's initial standard deviation, in action units (0.5 rad of joint exploration at the
    joint scale of 1 rad)"""
    end_on_success: bool = False
    """whether a training episode ends at the task's success. Off by default: every dense reward here keeps paying
    while the goal is held (a Reach TCP at its target, a lifted cube), so an episode that ends at success takes
    that income away, and PPO learns to hover just outside the success region (CPU Reach, 128 envs, 60
    iterations: 3 of 16 held-out episodes with it on). Training episodes run to their time limit and count a
    success when it happened at any step; evaluation ends episodes at success as the task says."""
    episode_length_s: float | None = None
    """training episodes' time limit [s] (``None``: the task's). PickCube's is 3600 s, as on the reference
    platform; with it a row whose cube was pushed out of reach stays there for the rest of the run (on an H200,
    iterations 175-300 of a 4096-row PickCube run ended 68-86 episodes per 25 iterations, all by a dropped cube),
    so PPO on it needs a limit well above the expert's episode (PickCube's: 6.9 s; LiftCube's: 4.2 s)"""
    domain_randomize: dict[str, float] = field(default_factory=dict)
    """domain randomisation (``task_api.perturbations.parse_randomization``: physics axes, the rows render no
    cameras): each env row draws its own object mass and friction up to these levels, kept for the run"""
    joint_state: bool = False
    """the actor also observes the commanded joints' velocities and current targets
    (``observations.PolicyObservation``)"""
    scales: ActionScales = field(default_factory=ActionScales)
    """what an action of 1 means per column kind, and how arm joints are driven (``ActionScales.joint_mode``); a
    dict of its fields is taken too (the Prefect flow's ``ppo`` argument)"""

    def __post_init__(self) -> None:
        if isinstance(self.scales, dict):
            self.scales = ActionScales(**self.scales)

    def runner_cfg(self) -> dict[str, Any]:
        """rsl_rl's ``OnPolicyRunner`` configuration (actor on ``policy``, critic on ``critic``)."""
        mlp = {"hidden_dims": list(self.hidden_dims), "activation": "elu", "obs_normalization": True}
        return {
            "num_steps_per_env": self.num_steps_per_env,
            "save_interval": 10**9,
            # the env already guarantees finite observations and rewards (a row whose physics diverges ends with a
            # reward of 0 and restarts finite: tests/test_divergence.py) and refuses non-finite actions; rsl_rl's
            # own check reads four tensors on the host at every step
            "check_for_nan": False,
            "logger": "tensorboard",
            "obs_groups": {"actor": ["policy"], "critic": ["critic"]},
            "actor": {
                "class_name": "MLPModel",
                **mlp,
                "distribution_cfg": {"class_name": "GaussianDistribution", "init_std": self.init_noise_std},
            },
            "critic": {"class_name": "MLPModel", **mlp},
            "algorithm": {
                "class_name": "PPO",
                "learning_rate": self.learning_rate,
                "num_learning_epochs": self.num_learning_epochs,
                "num_mini_batches": self.num_mini_batches,
                "entropy_coef": self.entropy_coef,
                "gamma": self.gamma,
                "lam": self.lam,
                "desired_kl": self.desired_kl,
                "schedule": "adaptive",
                "clip_param": 0.2,
                "value_loss_coef": 1.0,
                "max_grad_norm": 1.0,
                "use_clipped_value_loss": True,
            },
        }


def train_ppo(
    task_id: str, cfg: PPOConfig, output_dir: str | Path, *, resume: bool = False, progress: bool = True
) -> Path:
    """Train PPO on ``task_id`` into ``output_dir`` (``checkpoint.pt``, ``curve.json``, ``resume.pt``, tensorboard
    events); ``resume``: continue the run whose ``resume.pt`` is there. Returns the checkpoint's path."""
    out = Path(output_dir)
    resume_path = out / RESUME_NAME
    if resume and not resume_path.is_file():
        raise FileNotFoundError(f"nothing to resume in {out} (no {RESUME_NAME}); start the run without --resume")
    if not resume and (out / "checkpoint.pt").exists():
        raise FileExistsError(f"{out} holds a finished run; choose a new --output-dir (or --resume an interrupted one)")
    out.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(cfg.seed)
    env, vec, saved = _training_rows(task_id, cfg, resume_path if resume else None)
    runner = OnPolicyRunner(vec, cfg.runner_cfg(), log_dir=str(out), device=str(env.torch_device))
    times = _IterationLog(runner, vec)
    curve, elapsed = _restore(runner, saved, env.torch_device) if saved is not None else ([], 0.0)
    steps_per_iteration = cfg.num_envs * cfg.num_steps_per_env
    iteration_s = _pace(curve)
    while n := _next_chunk(cfg, _done(curve), elapsed, iteration_s):
        t0 = time.perf_counter()
        vec.restart(cfg.seed + len(curve))  # each chunk from freshly reset rows: a resumed run repeats the same
        runner.learn(num_learning_iterations=n, init_at_random_ep_len=False)
        runner.current_learning_iteration += 1  # rsl_rl leaves it at the last iteration run
        seconds = time.perf_counter() - t0
        elapsed += seconds
        iteration_s = seconds / n
        counts = vec.take_episode_counts()
        row = {
            "iteration": _done(curve) + n,
            "env_steps": (_done(curve) + n) * steps_per_iteration,
            "wall_s": round(elapsed, 2),
            "env_steps_per_s": n * steps_per_iteration / seconds,
            **counts,
            **times.take(),
        }
        curve.append(row)
        _save_resume(resume_path, runner, vec, curve, elapsed)
        for snapshot in out.glob("model_*.pt"):  # rsl_rl's own end-of-learn save: resume.pt holds the same
            snapshot.unlink()
        if progress:
            rate = "–" if row["success_rate"] is None else f"{row['success_rate']:.0%}"
            print(
                f"ppo {task_id}: iteration {row['iteration']}/{cfg.iterations}, success {rate}, "
                f"{row['env_steps_per_s']:,.0f} env-steps/s, {elapsed:.0f} s",
                file=sys.stderr,
                flush=True,
            )
    (out / "curve.json").write_text(json.dumps(curve, indent=1))
    path = out / "checkpoint.pt"
    tmp = out / ".checkpoint.pt.tmp"
    torch.save(_checkpoint(task_id, env, cfg, runner, vec, curve), tmp)
    tmp.replace(path)
    return path


def _training_rows(task_id: str, cfg: PPOConfig, resume_path: Path | None):
    """The training env, its vec env and the interrupted run's state (``None`` for a new run): a resumed run
    maps its actions as the interrupted one did (its start posture)."""
    env = make_env(
        task_id,
        num_envs=cfg.num_envs,
        device=cfg.device,
        seed=cfg.seed,
        randomize=True,
        task_options=cfg.task_options,
        cameras=False,
        terminate_on_success=cfg.end_on_success,
        episode_length_s=cfg.episode_length_s,
    )
    if cfg.domain_randomize:  # each row's own physics for the whole run (a resumed run draws the same)
        randomize_env(env, cfg.domain_randomize, seed=cfg.seed)
    saved = torch.load(resume_path, weights_only=False, map_location=str(env.torch_device)) if resume_path else None
    vec = RslRlVecEnv(env, cfg.scales, joint_state=cfg.joint_state)
    if saved is not None:
        mode = saved["action_map"]["scales"].get("joint_mode", "absolute")
        if mode != cfg.scales.joint_mode:
            raise ValueError(f"the interrupted run drove its joints with joint_mode {mode}; resume it with that mode")
        vec.action_map.rest = torch.tensor(saved["action_map"]["rest"], device=env.torch_device)
        vec.action_map.__init__(env, cfg.scales, rest=vec.action_map.rest)
    return env, vec, saved


def _pace(curve: list[dict[str, Any]]) -> float | None:
    """Seconds per iteration of the curve's last chunk (a resumed run's pace), ``None`` for an empty curve."""
    if not curve:
        return None
    a, b = curve[-2] if len(curve) > 1 else {"wall_s": 0.0, "iteration": 0}, curve[-1]
    return (b["wall_s"] - a["wall_s"]) / max(b["iteration"] - a["iteration"], 1)


def _next_chunk(cfg: PPOConfig, done: int, elapsed: float, iteration_s: float | None) -> int:
    """Iterations in the next chunk: up to ``cfg.chunk_iterations`` and the run's remaining iterations, and within
    ``cfg.time_budget_s`` at the last chunk's pace (0: the run is over)."""
    n = min(cfg.chunk_iterations, cfg.iterations - done)
    if cfg.time_budget_s is not None:
        left = cfg.time_budget_s - elapsed
        n = min(n, int(left / iteration_s)) if iteration_s else (n if left > 0 else 0)
    return max(n, 0)


class _IterationLog:
    """What rsl_rl's runner reports after each iteration, beside its own log: where a chunk's seconds went
    (``rollout_s``: policy and env steps, the curve row's ``env_step_s`` being the env's part; ``update_s``:
    returns and the PPO update), and the success rate of the episodes that ended in the iteration
    (``Episode/success_rate`` in the tensorboard log). The runner hands its times to its logger only, so the
    logger's ``log`` is wrapped. The logger's own step bookkeeping is replaced: it read the ended rows' returns on
    the host at every step (a sync that kept the host from queueing the next step while the device ran this one);
    its mean return and episode length are the iteration's, from the vec env's device counters."""

    def __init__(self, runner, vec: RslRlVecEnv) -> None:
        self.rollout_s = self.update_s = 0.0
        logger = runner.logger
        log = logger.log

        def log_and_add(**kwargs):
            self.rollout_s += kwargs["collect_time"]
            self.update_s += kwargs["learn_time"]
            counts = vec.take_iteration_counts()
            if counts["episodes"]:
                logger.rewbuffer.clear()
                logger.lenbuffer.clear()
                logger.rewbuffer.append(counts["mean_return"])
                logger.lenbuffer.append(counts["mean_length"])
                if logger.writer is not None:
                    rate = counts["successes"] / counts["episodes"]
                    logger.writer.add_scalar("Episode/success_rate", rate, kwargs["it"])
            return log(**kwargs)

        logger.log = log_and_add
        logger.process_env_step = lambda *args, **kwargs: None

    def take(self) -> dict[str, float]:
        out = {"rollout_s": round(self.rollout_s, 3), "update_s": round(self.update_s, 3)}
        self.rollout_s = self.update_s = 0.0
        return out


def _restore(runner, saved: dict[str, Any], device: torch.device) -> tuple[list[dict[str, Any]], float]:
    """Put the interrupted run's models, optimiser, iteration and random state back; its curve and seconds."""
    runner.alg.load(saved["runner"], None, True)
    runner.current_learning_iteration = saved["iteration"]
    torch.set_rng_state(saved["torch_rng"])
    if saved.get("cuda_rng") is not None and device.type == "cuda":
        torch.cuda.set_rng_state(saved["cuda_rng"], device)
    return saved["curve"], saved["elapsed_s"]


def run_summary(curve: list[dict[str, Any]]) -> dict[str, Any]:
    """A finished run from its curve: iterations, env steps, training seconds, the last chunk's success rate, and
    env-steps/s over the whole run with the updates included (the mean, not the last chunk's)."""
    final = curve[-1] if curve else {}
    steps, seconds = final.get("env_steps"), final.get("wall_s")
    return {
        "iterations": final.get("iteration"),
        "env_steps": steps,
        "wall_s": seconds,
        "success_rate": final.get("success_rate"),
        "env_steps_per_s": steps / seconds if steps and seconds else None,
    }


def _done(curve: list[dict[str, Any]]) -> int:
    return curve[-1]["iteration"] if curve else 0


def _save_resume(path: Path, runner, vec: RslRlVecEnv, curve, elapsed: float) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    torch.save(
        {
            "runner": runner.alg.save(),
            "iteration": runner.current_learning_iteration,
            "curve": curve,
            "elapsed_s": elapsed,
            "action_map": vec.action_map.state(),
            "torch_rng": torch.get_rng_state(),
            "cuda_rng": torch.cuda.get_rng_state(vec.device) if vec.device.type == "cuda" else None,
        },
        tmp,
    )
    tmp.replace(path)


def _checkpoint(task_id: str, env, cfg: PPOConfig, runner, vec: RslRlVecEnv, curve) -> dict[str, Any]:
    """The deterministic actor (TorchScript), what it observes and how its actions map."""
    actor = runner.alg.get_policy()
    config = {k: v for k, v in asdict(cfg).items() if k not in ("device",)}
    return {
        "format": CHECKPOINT_FORMAT,
        "version": CHECKPOINT_VERSION,
        "backend": "ppo",
        "config": config,
        "info": {
            "task_id": task_id,
            "task_options": dict(env.cfg.options),
            "obs_dim": int(env.obs.shape[1]),
            "joint_state": cfg.joint_state,
            "action_joint_names": list(env.action_joint_names),
            "image_keys": [],
            "iterations": _done(curve),
            "final": curve[-1] if curve else None,
        },
        "action_map": vec.action_map.state(),
        "actor_script": _scripted(actor),
    }


def _scripted(actor) -> torch.Tensor:
    """The actor as TorchScript, its bytes in a uint8 tensor (rsl_rl's deterministic export: normaliser, MLP, mean
    action), so that running it needs neither rsl_rl nor its model classes, and the checkpoint loads with
    ``weights_only``."""
    buf = io.BytesIO()
    with warnings.catch_warnings():  # torch 2.13 calls TorchScript deprecated; rsl_rl exports its actor so
        warnings.simplefilter("ignore", DeprecationWarning)
        torch.jit.save(torch.jit.script(actor.as_jit().cpu()), buf)  # as_jit copies: training's model stays
    return torch.frombuffer(bytearray(buf.getvalue()), dtype=torch.uint8)
