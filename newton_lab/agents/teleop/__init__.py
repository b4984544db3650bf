"""Teleoperation: devices (``devices``), the frames they send (``frames``), contracts and the frame -> action
mapper (``contracts``), the Cartesian jog through the batched IK (``jog``), ``TeleopAgent`` and the
keep / drop / exit review loop (``session``)."""

from .agent import USER_EXIT, TeleopAgent
from .contracts import CONTRACTS, FrameMapper, teleop_tasks
from .devices import DEVICES
from .frames import LatestFrame, TeleopFrame
from .session import review_demo, teleop_session

__all__ = [
    "CONTRACTS",
    "DEVICES",
    "FrameMapper",
    "LatestFrame",
    "TeleopAgent",
    "TeleopFrame",
    "USER_EXIT",
    "review_demo",
    "teleop_session",
    "teleop_tasks",
]
