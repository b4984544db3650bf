"""Arguments shared by every command that builds an env: task, rows, device, seed, cameras, rerun; and
``newton-lab tasks`` / ``render``."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..task_api.cfg import camera_option
from ..task_api.registry import DEFAULT_TASK_ID


@dataclass(kw_only=True)
class EnvArgs:
    """Which task, how many rows, where, how seeded: everything ``make_env`` takes."""

    task: str = DEFAULT_TASK_ID
    """task id (see `newton-lab tasks`)"""
    num_envs: int = 1
    """Parallel env rows (worlds) stepped as one batch."""
    device: str | None = None
    """Warp device, e.g. cpu or cuda:0 (default: Warp's)"""
    seed: int = 0
    """Seed of the reset randomisation (per row and episode)."""
    randomize: bool = False
    """turn on the task's reset randomisation"""
    task_options: dict[str, Any] = field(default_factory=dict, metadata={"task_options": True})
    """The task's own options (``TaskSpec.options``), e.g. ``{"sorting_object": "red_cube"}``. On the command
    line every option a task declares is a flag of its own (``--sorting-object red_cube``); unset ones are left to
    the task's defaults."""

    def env_kwargs(self) -> dict[str, Any]:
        """Keywords of ``make_env(self.task, **...)``."""
        return {
            "num_envs": self.num_envs,
            "device": self.device,
            "seed": self.seed,
            "randomize": self.randomize,
            "task_options": dict(self.task_options),
        }


@dataclass(kw_only=True)
class RolloutArgs(EnvArgs):
    """An env plus how long to run it: ``env.collect`` / ``env.evaluate``."""

    episodes: int = 1
    """Episodes to run (over all rows)."""
    max_steps: int = 1000
    """episode step limit of the loop [control steps]"""
    no_progress: bool = False
    """No progress bar."""

    def rollout_kwargs(self) -> dict[str, Any]:
        """Keywords shared by ``env.collect`` and ``env.evaluate``."""
        return {"episodes": self.episodes, "max_steps": self.max_steps, "progress": not self.no_progress}


@dataclass(kw_only=True)
class RerunArgs:
    """Streaming a run to the rerun viewer."""

    rerun: bool = False
    """stream to a rerun viewer (spawned)"""
    rerun_save: str | None = None
    """record the run to this .rrd file (headless)"""
    rerun_worlds: int = 4
    """rows drawn in rerun"""
    rerun_image_every: int = 1
    """log the cameras' images to rerun every n-th step (each logged image step renders: CPU time)"""


@dataclass(kw_only=True)
class CameraArgs:
    cameras: str = "default"
    """image terms: default (the task's cameras; mimic: the source dataset's), none (state only: nothing is
    rendered) or <camera>=<W>x<H>[:<data>+...][,...] (e.g. front_head=96x72, or front_head=96x72:rgb to record
    RGB only; data: rgb, depth, segmentation)"""

    def env_kwargs(self) -> dict[str, Any]:
        """``EnvArgs.env_kwargs`` plus ``cameras``."""
        return {**super().env_kwargs(), "cameras": camera_option(self.cameras)}  # type: ignore[misc]


@dataclass(kw_only=True)
class TasksArgs:
    """``newton-lab tasks``: no arguments."""


@dataclass(kw_only=True)
class RenderArgs(EnvArgs):
    """``newton-lab render``: one camera frame of a task as a PNG, RGB | depth | segmentation side by side."""

    camera: str = "front_head"
    """G1 camera: front_head, left_wrist or right_wrist"""
    resolution: list[int] | None = None
    """image width and height [px] (default: the task's, else 298 224)"""
    randomize: bool = True
    """turn on the task's reset randomisation and the cameras' (colours, brightness, pose jitter), seeded by --seed"""
    expert_steps: int = 0
    """run the task's expert this many control steps before the frame"""
    perturb: str | None = None
    """draw the frame under these perturbations of the env, AXIS=LEVEL,... (LEVEL mild, strong or a number; the
    physics, camera, surface, light and scene axes of evaluate --perturb), applied before the episode starts"""
    out: str = "render.png"
    """PNG file to write"""

    def perturbation(self) -> dict[str, float]:
        """``--perturb`` as axis -> level (one-line errors: a sweep or an axis that acts on an agent)."""
        from ..task_api.perturbations import AXES, parse_cells  # deferred: only --perturb needs it (plain Python)

        if self.perturb is None:
            return {}
        cells = parse_cells(self.perturb)
        if len(cells) > 1:
            raise ValueError("--perturb sweep: render draws one frame; give AXIS=LEVEL,... (e.g. surface_texture=mild)")
        agent = [a for a in cells[0].values if AXES[a].acts_on == "agent"]
        if agent:
            raise ValueError(f"--perturb {agent[0]}: acts on an agent's actions, and render runs none; leave it out")
        return cells[0].values
