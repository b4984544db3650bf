"""Batched envs: ``make_env(task_id, ...)`` builds a ``NewtonEnv`` for a registered task."""

from __future__ import annotations

import dataclasses
from typing import Any

from .. import tasks  # noqa: F401  (registers every task id: the one place the core loads the task packages)
from ..task_api.physics import PhysicsCfg
from ..task_api.registry import lookup
from ..tasks.common.distractors import with_distractors
from .env import NewtonEnv
from .prefetch import prefetch_kernels


def make_env(
    task_id: str,
    num_envs: int = 1,
    device: str | None = None,
    seed: int | None = None,
    randomize: bool = False,
    task_options: dict[str, Any] | None = None,
    *,
    capture: bool = True,
    cameras: bool | dict[str, Any] | str | None = None,
    physics: PhysicsCfg | None = None,
    terminate_on_success: bool | None = None,
    episode_length_s: float | None = None,
    distractors: int = 0,
    **options: Any,
) -> NewtonEnv:
    """Build the env of ``task_id`` with ``num_envs`` rows on ``device`` (Warp's default when ``None``).

    ``randomize`` turns on the task's reset randomisation (seeded per row by ``seed``);
    ``task_options`` are the task's own options (unknown keys raise with the valid ones); they may also be given as
    keywords: ``make_env("GalbotG1-SortToShelf-v0", sorting_object="blue_cuboid", obs_mode="sensors")`` (so
    ``gymnasium.make`` takes them too).
    ``cameras``: ``None`` renders the task's cameras (``TaskCfg.cameras``), ``False`` none (state-only speed),
    ``{"front_head": (96, 72)}`` changes a camera's resolution [px] (or ``{"front_head": {"resolution": (w, h),
    "data": ("rgb", "depth", "segmentation")}}``; a mount of the task's robot that the task lacks is added), or the
    CLI's text for any of these (``"none"``, ``"front_head=96x72:rgb"``).
    ``physics`` replaces the task's physics settings (``TaskCfg.physics``, ``task_api.physics.PhysicsCfg``), e.g.
    ``PhysicsCfg()`` for the settings every task ran with before choosing its own (``tools/physics_table.py``).
    ``terminate_on_success``: whether the last phase's success ends the episode (``None``: the task's choice,
    ``TaskCfg.terminate_on_success``); reinforcement learning trains with ``False`` (``policies.rl.train``).
    ``episode_length_s``: the episodes' time limit [s] (``None``: the task's, ``TaskCfg.episode_length_s``); a
    time-out truncates the episode.
    ``distractors``: that many distractor objects on the table (0 to 3; ``tasks.common.distractors``), placed at
    every reset clear of the task's objects; the ``distractors`` perturbation axis evaluates under them.
    """
    spec = lookup(task_id)
    if not isinstance(num_envs, int) or isinstance(num_envs, bool) or num_envs < 1:
        raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
    both = sorted(set(options) & set(task_options or {}))
    if both:
        raise ValueError(f"task option(s) {both} given twice (as keywords and in task_options); give each once")
    cfg = spec.make_cfg({**(task_options or {}), **options})
    if physics is not None:
        cfg = dataclasses.replace(cfg, physics=physics)
    if terminate_on_success is not None:
        cfg = dataclasses.replace(cfg, terminate_on_success=bool(terminate_on_success))
    if episode_length_s is not None:
        if not episode_length_s > 0:
            raise ValueError(f"episode_length_s must be > 0 [s], got {episode_length_s!r}")
        cfg = dataclasses.replace(cfg, episode_length_s=float(episode_length_s))
    cfg = with_distractors(cfg, distractors)
    prefetch_kernels(device)  # the step's large modules compile on a second thread while the model is built
    return NewtonEnv(
        cfg, num_envs=num_envs, device=device, seed=seed, randomize=randomize, capture=capture, cameras=cameras
    )


__all__ = ["NewtonEnv", "make_env"]
