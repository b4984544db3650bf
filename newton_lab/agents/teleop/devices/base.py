"""The teleop device protocol: ``start`` opens the hardware or terminal, ``poll`` returns the newest frame since
the last poll (``None``: nothing new), ``reset`` begins an episode, ``exit_requested`` says the operator ended it
(``done``), ``close`` releases everything. A device declares which teleop contracts it can drive."""

from __future__ import annotations

import threading

from ..frames import LatestFrame, TeleopFrame


class TeleopDevice:
    """Base class: a latest-wins frame slot, an exit flag, and a pause switch (the review prompt reads the
    terminal while the device is paused)."""

    name = "device"
    contracts: tuple[str, ...] = ()
    """Teleop contracts (``contracts.CONTRACTS``) this device can drive."""
    jog_arms: tuple[str, ...] = ()
    """Arms this device moves by Cartesian jog (the agent prepares their IK when it binds to an env)."""

    def __init__(self) -> None:
        self.frames = LatestFrame()
        self._exit = threading.Event()
        self.started = False

    def start(self) -> None:
        """Open the device (hardware, terminal); called once, after the task's contract was checked."""
        self.started = True

    def poll(self) -> TeleopFrame | None:
        return self.frames.take()

    def reset(self) -> None:
        """A new episode begins: clear the exit request and any frame not taken yet (cumulative jog offsets
        restart in subclasses)."""
        self._exit.clear()
        self.frames.take()

    def request_exit(self) -> None:
        self._exit.set()

    def exit_requested(self) -> bool:
        return self._exit.is_set()

    def pause(self) -> None:
        """Stop reading the operator's input (the review prompt reads the terminal)."""

    def resume(self) -> None:
        """Read the operator's input again after :meth:`pause`."""

    def help(self) -> str:
        """What the operator can do (e.g. the key map), shown when the session starts."""
        return ""

    def close(self) -> None:
        self.started = False
