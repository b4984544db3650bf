"""``RLPolicyAgent``: a PPO checkpoint (``newton_lab.policies.rl.train``) as an agent of ``env.evaluate`` /
``newton-lab evaluate --checkpoint``: the deterministic actor on the env's observation vector, its actions mapped to
the env's columns as in training."""

from __future__ import annotations

import io
import warnings
from pathlib import Path
from typing import Any

import torch

from ...agents.base import BaseAgent
from .actions import ActionMap, ActionScales
from .observations import PolicyObservation

CHECKPOINT_FORMAT = "newton_lab.policies.rl"
"""``format`` tag of an RL checkpoint (``train.CHECKPOINT_FORMAT``; kept here so that running one needs no rsl_rl)."""


def is_rl_checkpoint(path: str | Path) -> bool:
    """Whether ``path`` holds a PPO checkpoint (read with ``weights_only``: plain data only)."""
    try:
        ckpt = torch.load(path, weights_only=True, map_location="cpu")
    except Exception:  # noqa: BLE001  (not ours to judge here: the diffusion loader says what is wrong)
        return False
    return isinstance(ckpt, dict) and ckpt.get("format") == CHECKPOINT_FORMAT


class RLPolicyAgent(BaseAgent):
    """The actor of a PPO checkpoint; bound to an env (task, observation width, action columns) at its first act."""

    def __init__(self, checkpoint: dict[str, Any], device: str = "cpu") -> None:
        self.info = checkpoint["info"]
        self.device = device
        script = io.BytesIO(checkpoint["actor_script"].numpy().tobytes())
        with warnings.catch_warnings():  # torch 2.13 calls TorchScript deprecated; rsl_rl exports its actor so
            warnings.simplefilter("ignore", DeprecationWarning)
            self.actor = torch.jit.load(script, map_location=device).eval()
        self.map_state = checkpoint["action_map"]
        self.action_map: ActionMap | None = None
        self.observe: PolicyObservation | None = None

    @classmethod
    def from_checkpoint(cls, path: str | Path, *, device: str | None = None) -> RLPolicyAgent:
        if not Path(path).exists():
            raise FileNotFoundError(f"checkpoint {path} does not exist; train one first (newton-lab train-rl)")
        ckpt = torch.load(path, weights_only=True, map_location="cpu")
        if not isinstance(ckpt, dict) or ckpt.get("format") != CHECKPOINT_FORMAT:
            raise ValueError(f"{path} is not a newton_lab PPO checkpoint; give a checkpoint.pt of newton-lab train-rl")
        return cls(ckpt, device=device or "cpu")

    def setup(self, env) -> None:
        task = self.info["task_id"]
        if task != env.task_id:
            raise ValueError(f"checkpoint was trained for {task} but the env runs {env.task_id}; evaluate it on {task}")
        if int(env.obs.shape[1]) != self.info["obs_dim"]:
            raise ValueError(
                f"checkpoint observes {self.info['obs_dim']} values, {env.task_id} gives "
                f"{env.obs.shape[1]}: evaluate with the task options it was trained with "
                f"({self.info['task_options']})"
            )
        if list(env.action_joint_names) != list(self.info["action_joint_names"]):
            raise ValueError(
                f"checkpoint actions {self.info['action_joint_names']} differ from the env's "
                f"{list(env.action_joint_names)}"
            )
        rest = torch.tensor(self.map_state["rest"], dtype=torch.float32)
        self.action_map = ActionMap(env, ActionScales(**self.map_state["scales"]), rest=rest)
        self.observe = PolicyObservation(env, self.info.get("joint_state", False))

    def act(self, env, env_ids=None) -> torch.Tensor:
        self.bind(env)
        with torch.no_grad():
            actions = self.actor(self.observe().to(self.device)).to(env.torch_device)
        return self.action_map.for_env(actions, env)
