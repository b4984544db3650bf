"""gymnasium (1.x) adapter: a ``NewtonEnv`` as a ``gymnasium.vector.VectorEnv`` (``NewtonVectorEnv``) or, with
one world, a ``gymnasium.Env`` (``NewtonGymEnv``); importing this module registers every task id as
``newton_lab/<task id>``::

    import gymnasium as gym
    import newton_lab.envs.gym  # noqa: F401  registers the ids
    envs = gym.make_vec("newton_lab/GalbotG1-PickCube-v0", num_envs=4, device="cpu", randomize=True)
    env = gym.make("newton_lab/GalbotG1-PickCube-v0", device="cpu")  # one world, a gymnasium.Env

(or, without the import: ``gym.make_vec("newton_lab.envs.gym:newton_lab/GalbotG1-PickCube-v0", ...)``).
gymnasium 1.x's ``make`` returns only ``gymnasium.Env`` objects, so N batched worlds come from ``make_vec``
(the ids' ``vector_entry_point``: one ``NewtonEnv`` stepping every world as one batch, not N copies);
``make(id, num_envs=N > 1)`` is refused with that hint. Other keywords go to ``make_env`` (``device``,
``seed``, ``randomize``, ``task_options``, ``cameras``).

Spaces: observations are a ``Dict`` of the task's observation terms (``Box`` float32 of each term's width;
camera images as ``Box`` uint8 rgb / float32 depth / int32 segmentation when the env renders cameras);
actions a ``Box`` float32 of ``action_dim`` bounded per column by its clip, the joint range (absolute
columns) or open .. closed (gripper), in action units (before the term's ``scale``).
``gymnasium.wrappers.vector.FlattenObservation`` turns the ``Dict`` into one ``Box``.

Auto-reset is gymnasium's ``AutoresetMode.SAME_STEP`` (the env resets finished rows inside the step):
a finished row's observation is its new episode's first one; ``info["final_obs"]`` (object array, the
row's last observation, ``None`` in running rows) and ``info["final_info"]`` (``success``,
``termination_reason`` code, ``episode_length`` of the finished episode) hold the finished episode, with
``info["_final_obs"]`` / ``info["_final_info"]`` marking the finished rows. Camera images are rendered from
the current state, so ``final_obs`` holds the state terms only. Arrays are numpy on the host (copied once
per step); the physics runs on the env's device. ``reset(seed=s)`` restarts the seeded reset randomisation
(``NewtonEnv.reseed``); ``reset(options={"reset_mask": mask})`` resets only the masked rows.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Any

import gymnasium
import numpy as np
import torch
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ..task_api.registry import DEFAULT_TASK_ID, list_tasks
from . import make_env
from .env import NewtonEnv

NAMESPACE = "newton_lab"
"""gymnasium id namespace: ``newton_lab/<task id>``."""
INFO_KEYS = ("success", "termination_reason", "episode_length")
"""Per-row info of every step (for finished rows: of the episode that just ended) and of ``final_info``."""
IMAGE_BOUNDS = {"rgb": (0, 255), "depth": (0.0, np.inf), "segmentation": (0, np.iinfo(np.int32).max)}


def action_bounds(env: NewtonEnv) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) float32 (action_dim,) of the actions ``env`` acts on: each column's clip, intersected with
    its joint range for absolute columns, divided by the column's scale."""
    amap = env.joints.binding.actions
    lower, upper = env.joints.absolute_column_ranges()
    lo, hi = np.maximum(amap.low.astype(np.float64), lower), np.minimum(amap.high.astype(np.float64), upper)
    scale = amap.scale.astype(np.float64)
    a, b = lo / scale, hi / scale
    return np.minimum(a, b).astype(np.float32), np.maximum(a, b).astype(np.float32)


def observation_space(env: NewtonEnv) -> spaces.Dict:
    """One row's observation space: a ``Box`` per observation term (then per camera image term), in the env's
    order (flattened, the state terms are ``env.obs``'s columns)."""
    boxes = OrderedDict(
        (name, spaces.Box(-np.inf, np.inf, (sl.stop - sl.start,), np.float32))
        for name, sl in env.task.obs_terms.items()
    )
    for name, term in env.sensors.image_terms.items():
        low, high = IMAGE_BOUNDS[term.data]
        boxes[name] = spaces.Box(low, high, tuple(term.shape), torch.empty(0, dtype=term.dtype).numpy().dtype)
    return spaces.Dict(boxes)


class NewtonVectorEnv(VectorEnv):
    """``num_envs`` worlds of one task as a gymnasium ``VectorEnv`` (numpy in and out, same-step auto-reset).
    ``env``: the wrapped ``NewtonEnv`` (its Newton model, state and torch views stay reachable)."""

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": []}

    def __init__(
        self, task_id: str = DEFAULT_TASK_ID, num_envs: int = 1, *, env: NewtonEnv | None = None, **make_env_kwargs: Any
    ):
        self.env = env if env is not None else make_env(task_id, num_envs=num_envs, **make_env_kwargs)
        self.num_envs = self.env.num_envs
        self.single_observation_space = observation_space(self.env)
        self.single_action_space = spaces.Box(*action_bounds(self.env), dtype=np.float32)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.termination_reasons = tuple(self.env.task.termination_reasons)
        """Name of each ``termination_reason`` code."""

    def _obs(self, flat: torch.Tensor, images: bool = True) -> dict[str, np.ndarray]:
        host = flat.detach().cpu().numpy().copy()
        out = {name: host[:, sl] for name, sl in self.env.task.obs_terms.items()}
        if images:
            for name in self.env.sensors.image_terms:
                out[name] = self.env.sensors.images[name].detach().cpu().numpy().copy()
        return out

    def _info(self, done: np.ndarray | None = None) -> dict[str, Any]:
        info = {k: self.env.info[k].detach().cpu().numpy().copy() for k in INFO_KEYS}
        mask = np.ones(self.num_envs, dtype=bool) if done is None else done
        info.update({f"_{k}": mask.copy() for k in INFO_KEYS})
        return info

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Reset every row (``seed``: restart the reset randomisation from it) or, with
        ``options={"reset_mask": (num_envs,) bool}``, only the masked rows. Returns ``(obs, info)``."""
        if seed is not None and (not isinstance(seed, (int, np.integer)) or isinstance(seed, bool)):
            raise ValueError(f"seed must be one int (every row draws its own stream from it), got {seed!r}")
        super().reset(seed=None if seed is None else int(seed))
        mask = (options or {}).get("reset_mask")
        if mask is not None:
            mask = np.asarray(mask)
            if mask.shape != (self.num_envs,) or mask.dtype != np.bool_:
                raise ValueError(
                    f"options['reset_mask'] must be a ({self.num_envs},) bool array, got {mask.dtype} {mask.shape}"
                )
            obs, _ = self.env.reset(env_ids=np.flatnonzero(mask))
        elif seed is not None:
            obs, _ = self.env.reseed(int(seed))
        else:
            obs, _ = self.env.reset()
        return self._obs(obs), {}

    def step(self, actions):
        """One control step of every row: ``actions`` (num_envs, action_dim) numpy or torch. Returns
        ``(obs, reward, terminated, truncated, info)`` as numpy (see the module docstring for ``info``)."""
        env = self.env
        act = torch.as_tensor(
            np.asarray(actions, dtype=np.float32) if not isinstance(actions, torch.Tensor) else actions,
            device=env.torch_device,
            dtype=torch.float32,
        )
        obs, reward, terminated, truncated, _ = env.step(act)
        done = env.info["done"].detach().cpu().numpy().copy()
        info = self._info()
        out = (
            self._obs(obs),
            reward.detach().cpu().numpy().copy(),
            terminated.detach().cpu().numpy().copy(),
            truncated.detach().cpu().numpy().copy(),
        )
        if done.any():
            final = self._obs(env.buffers.final_obs, images=False)
            final_obs = np.full(self.num_envs, None, dtype=object)
            for i in np.flatnonzero(done):
                final_obs[i] = {name: value[i] for name, value in final.items()}
            info.update(final_obs=final_obs, _final_obs=done, final_info=self._info(done), _final_info=done.copy())
        return (*out, info)

    def close_extras(self, **kwargs: Any) -> None:
        """Nothing to release beyond the env's arrays (freed with it)."""


class NewtonGymEnv(gymnasium.Env):
    """One world of a task as a ``gymnasium.Env`` (``gymnasium.make``): a step that ends an episode returns
    its last observation; the next ``reset()`` starts a new one."""

    metadata = {"render_modes": []}

    def __init__(self, task_id: str = DEFAULT_TASK_ID, num_envs: int | None = None, **make_env_kwargs: Any):
        if num_envs not in (None, 1):
            raise ValueError(
                f"gymnasium.make builds one world (a gymnasium.Env); for num_envs={num_envs} use "
                f"gymnasium.make_vec('{NAMESPACE}/{task_id}', num_envs={num_envs})"
            )
        self.vector = NewtonVectorEnv(task_id, num_envs=1, **make_env_kwargs)
        self.observation_space = self.vector.single_observation_space
        self.action_space = self.vector.single_action_space

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        obs, _ = self.vector.reset(seed=seed)
        return {k: v[0] for k, v in obs.items()}, {}

    def step(self, action):
        act = torch.as_tensor(action, dtype=torch.float32).reshape(1, -1)
        obs, reward, terminated, truncated, info = self.vector.step(act)
        if info.get("_final_obs", np.zeros(1, bool))[0]:
            obs = info["final_obs"][0]
        else:
            obs = {k: v[0] for k, v in obs.items()}
        row = {k: info[k][0].item() for k in INFO_KEYS}
        return obs, float(reward[0]), bool(terminated[0]), bool(truncated[0]), row


def register_tasks() -> list[str]:
    """Register ``newton_lab/<id>`` for every registered task (each once); returns the gymnasium ids."""
    ids = []
    for task_id in list_tasks():
        gym_id = f"{NAMESPACE}/{task_id}"
        if gym_id not in gymnasium.registry:
            gymnasium.register(
                id=gym_id,
                entry_point=NewtonGymEnv,
                vector_entry_point=NewtonVectorEnv,
                kwargs={"task_id": task_id},
                disable_env_checker=False,
            )
        ids.append(gym_id)
    return ids


GYM_IDS = register_tasks()
"""The gymnasium ids registered by importing this module."""

__all__ = [
    "GYM_IDS",
    "NAMESPACE",
    "NewtonGymEnv",
    "NewtonVectorEnv",
    "action_bounds",
    "observation_space",
    "register_tasks",
]
