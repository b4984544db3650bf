"""Teleoperation (reference teleop loop): drive PickCube from a device, then keep / drop / exit each episode.

    python examples/08_teleop.py                                   # keyboard in this terminal (key map shown)
    python examples/08_teleop.py --device replay --replay-dataset data/pick_cube_demos.hdf5 --no-realtime

Type ``done`` + Enter to end an episode, then answer keep, drop or exit (end of input = exit). Flags: those of
``newton-lab teleop`` (``TeleopArgs`` in ``newton_lab.commands.teleop``); add ``--rerun`` to watch the cameras live.
"""

from __future__ import annotations

import json

from newton_lab.agents import TeleopAgent
from newton_lab.agents.teleop import teleop_session
from newton_lab.cli import parse_args
from newton_lab.commands import TeleopArgs
from newton_lab.envs import make_env

DEFAULTS = {"task": "GalbotG1-PickCube-Teleop-v0", "dataset_path": "data/pick_cube_teleop.hdf5"}


def main() -> None:
    args = parse_args(TeleopArgs, description=__doc__, defaults=DEFAULTS)  # checked as newton-lab teleop checks
    # the task's contract is checked before the device opens: an unsupported task fails here, in one line
    agent = TeleopAgent.from_device(args.device, **args.agent_kwargs())
    try:
        env = make_env(args.task, **args.env_kwargs())
        summary = teleop_session(env, agent, **args.session_kwargs())
    finally:
        agent.close()
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
