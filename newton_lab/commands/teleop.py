"""``newton-lab teleop``: the arguments of an operator session (``newton_lab.agents.teleop.teleop_session``), and
their one-line checks before Warp is imported."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .env import CameraArgs, EnvArgs, RerunArgs

DEVICE_NAMES = ("keyboard", "replay", "gp001", "galbot_remote", "remote", "spacemouse", "gamepad")
"""``agents.teleop.devices.DEVICES`` (spelled here so a typo is refused before anything heavy is imported)."""


@dataclass(kw_only=True)
class TeleopArgs(CameraArgs, RerunArgs, EnvArgs):
    """``newton-lab teleop``: operator episodes of a task into a dataset, each reviewed (keep / drop / exit)."""

    task: str = "GalbotG1-PickCube-Teleop-v0"
    """task id with a teleop contract (e.g. GalbotG1-PickCube-Teleop-v0, GalbotG1-StackCube-v0)"""
    device: str = "keyboard"
    """teleop device: keyboard, replay, gp001, spacemouse or gamepad"""
    dataset_path: str = "outputs/teleop/pick_cube_teleop.hdf5"
    """dataset the kept demos are appended to (.hdf5 / .h5 / .zarr)"""
    max_steps: int = 6000
    """episode step limit [control steps] (6000 = 5 min at 20 Hz)"""
    keep: int | None = None
    """stop after keeping this many demos (default: until the operator answers exit)"""
    no_frame_policy: str = "hold"
    """joints no device frame names: hold (their current targets) or zero"""
    replay_dataset: str | None = None
    """--device replay: the dataset whose demo is played back"""
    replay_demo: int | None = None
    """--device replay: the demo id (default: the first)"""
    replay_mode: str = "actions"
    """--device replay: actions (the recorded joint targets) or tcp (the recorded TCP path, through the IK)"""
    no_realtime: bool = False
    """step as fast as the simulation goes instead of at the control rate (20 Hz)"""
    sim_device: str | None = None
    """Warp device of the simulation, e.g. cpu or cuda:0 (--device names the teleop device here)"""

    def env_kwargs(self) -> dict[str, Any]:
        """``make_env`` keywords: the simulation runs on ``--sim-device``."""
        return {**super().env_kwargs(), "device": self.sim_device}

    def agent_kwargs(self) -> dict[str, Any]:
        """Keywords of ``TeleopAgent.from_device(self.device, **...)``."""
        replay = (
            {"path": self.replay_dataset, "demo": self.replay_demo, "mode": self.replay_mode}
            if self.device == "replay"
            else {}
        )
        return {"task": self.task, "no_frame_policy": self.no_frame_policy, **replay}

    def session_kwargs(self) -> dict[str, Any]:
        """Keywords of ``teleop_session(env, agent, **...)`` (less its ``on_step`` hook)."""
        return {
            "path": self.dataset_path,
            "max_steps": self.max_steps,
            "keep": self.keep,
            "realtime": not self.no_realtime,
        }


def check_teleop(args: TeleopArgs) -> None:
    """One-line errors before Warp is imported."""
    if args.device not in DEVICE_NAMES:
        raise ValueError(f"--device {args.device!r} is unknown; valid devices: {', '.join(DEVICE_NAMES)}")
    if args.no_frame_policy not in ("hold", "zero"):
        raise ValueError(f"--no-frame-policy {args.no_frame_policy!r} is unknown; use hold or zero")
    if args.device == "replay" and (args.replay_dataset is None or not Path(args.replay_dataset).exists()):
        raise FileNotFoundError(
            f"--device replay needs --replay-dataset naming an existing dataset, got {args.replay_dataset!r}"
        )
    if args.replay_mode not in ("actions", "tcp"):
        raise ValueError(f"--replay-mode {args.replay_mode!r} is unknown; use actions or tcp")
    if args.num_envs != 1:
        raise ValueError(f"--num-envs {args.num_envs}: one operator drives one env; use --num-envs 1")
    if args.keep is not None and args.keep < 1:
        raise ValueError(f"--keep must be an integer >= 1, got {args.keep}")
