"""What a teleop device sends: one ``TeleopFrame`` per reading, and the latest-wins slot between a device's
reader thread and the agent (older frames are dropped, as the reference's GP001 queue does)."""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class TeleopFrame:
    """One device reading. Every field is optional: what a frame leaves out is filled by the agent's
    ``no_frame_policy`` (hold the current targets, or zero)."""

    timestamp: float = field(default_factory=time.perf_counter)
    """``time.perf_counter()`` when the device produced the frame [s] (latency is measured from it)."""
    arm_joints: dict[str, np.ndarray] = field(default_factory=dict)
    """Absolute arm joint targets by arm (``left`` / ``right``): joint1..7 [rad] (leader arms, replays)."""
    tcp_offset: dict[str, np.ndarray] = field(default_factory=dict)
    """Cartesian jog by arm: (dx, dy, dz [m], dyaw [rad]) of the TCP from its pose at the episode start, in the
    world frame (keyboard, spacemouse). Cumulative, so a dropped frame loses nothing."""
    gripper_open: dict[str, bool] = field(default_factory=dict)
    """Gripper command by arm: True = open (0.0), False = closed (1.2). Missing: open."""
    base_twist: tuple[float, float, float] | None = None
    """Base twist (vx, vy [m/s] in the base frame, wz [rad/s]); mapped to the four wheel velocities."""
    body_height: float | None = None
    """Body-height step s [rad]: legs 1..3 = (s, 3s, 2s), clamped (as on the reference platform)."""
    raw: dict | None = None
    """The device's own frame (e.g. the GP001 dict), for logging."""


class LatestFrame:
    """A one-frame mailbox: ``put`` replaces what is there (the older frame is dropped and counted), ``take``
    empties it. Thread-safe; the device's reader thread puts, the agent takes once per control step."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._frame: TeleopFrame | None = None
        self.dropped = 0
        """Frames replaced before the agent took them."""

    def put(self, frame: TeleopFrame) -> None:
        with self._lock:
            self.dropped += self._frame is not None
            self._frame = frame

    def take(self) -> TeleopFrame | None:
        with self._lock:
            frame, self._frame = self._frame, None
            return frame
