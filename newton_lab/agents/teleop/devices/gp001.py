"""``gp001``: Galbot's GP001 leader-arm remote (as on the reference platform). Frames come from a transport; the default
one is the vendor driver (``remote_control_lite``, an optional import: a one-line error when absent). Tests and
other hardware inject their own transport: any object with ``open()``, ``read()`` (the newest raw frame dict or
``None``) and ``close()``.

A raw frame: ``{"timestamp", "action_list": {"axes": [10], "buttons": [...]}, "joint_states": {"left_arm":
{"position": [7]}, "right_arm": {...}}, "button_state": [18]}``. Mapping: ``axes[3] >= 0.35`` opens the left
gripper, ``axes[4] >= 0.35`` the right one; unless button 17 or 18 (1-based) is pressed, the base twist is
``axes[0..2] * speed`` and the body height integrates ``axes[5] * 0.05`` per frame; leader-arm joints are copied
1:1 to the G1's arm joints. A frame without an arm's joints leaves that arm to the ``no_frame_policy``.
"""

from __future__ import annotations

import threading
import time

import numpy as np

from ..frames import TeleopFrame
from .base import TeleopDevice

GRIPPER_OPEN_THRESHOLD = 0.35
"""Trigger value at or above which a gripper opens (trigger range 0 .. 0.7)."""
BODY_HEIGHT_GAIN = 0.05
"""Body-height step per frame at full stick [rad]."""
HOLD_BUTTONS = (17, 18)
"""1-based buttons that freeze the base twist and the body height while pressed."""
POLL_S = 0.01
"""Transport polling period [s] (the vendor driver's)."""


class VendorTransport:
    """The vendor's ``remote_control_lite`` driver on the serial port (``GALBOT_GP001_PORT`` or the default)."""

    def __init__(self, port: str | None = None):
        self.port = port
        self._driver = None

    def open(self) -> None:
        try:
            import remote_control_lite  # noqa: PLC0415  deferred: the optional vendor driver (x86_64 binary)
        except ImportError:
            raise ValueError(
                "gp001: the vendor driver remote_control_lite is not installed; install Galbot's "
                "remote SDK, or pass a transport (TeleopAgent.from_device('gp001', transport=...))"
            ) from None
        self._driver = (
            remote_control_lite.GalbotDriver(port=self.port) if self.port else remote_control_lite.GalbotDriver()
        )
        self._driver.start()

    def read(self) -> dict | None:
        return self._driver.latest() if self._driver is not None else None

    def close(self) -> None:
        if self._driver is not None:
            self._driver.stop()
            self._driver = None


def map_gp001(raw: dict, *, height: float, speed: float = 1.0) -> tuple[TeleopFrame, float]:
    """One raw GP001 frame -> a ``TeleopFrame`` and the integrated body-height step [rad]."""
    axes = np.asarray(raw.get("action_list", {}).get("axes", ()), dtype=np.float64)
    axes = np.pad(axes, (0, max(0, 10 - len(axes))))
    buttons = list(raw.get("button_state", ())) + [0] * 18
    held = any(bool(buttons[b - 1]) for b in HOLD_BUTTONS)
    twist = None
    if not held:
        twist = (float(axes[0] * speed), float(axes[1] * speed), float(axes[2] * speed))
        height = height + float(axes[5]) * BODY_HEIGHT_GAIN
    arms = {}
    for arm in ("left", "right"):
        pos = raw.get("joint_states", {}).get(f"{arm}_arm", {}).get("position")
        if pos is not None and len(pos) >= 7:
            arms[arm] = np.asarray(pos[:7], dtype=np.float64)
    grippers = {"left": bool(axes[3] >= GRIPPER_OPEN_THRESHOLD), "right": bool(axes[4] >= GRIPPER_OPEN_THRESHOLD)}
    frame = TeleopFrame(
        timestamp=time.perf_counter(),
        arm_joints=arms,
        gripper_open=grippers,
        base_twist=twist,
        body_height=height,
        raw=raw,
    )
    return frame, height


class Gp001Device(TeleopDevice):
    """Polls ``transport`` every 10 ms on a thread; only the newest frame is kept."""

    name = "gp001"
    contracts = ("left_arm_manipulation", "dual_arm", "mobile_full_body")

    def __init__(self, transport=None, *, speed: float = 1.0, port: str | None = None):
        super().__init__()
        self.transport = transport if transport is not None else VendorTransport(port)
        self.speed = float(speed)
        self.height = 0.0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self.transport.open()
        super().start()
        self._thread = threading.Thread(target=self._poll_loop, name="gp001-teleop", daemon=True)
        self._thread.start()

    def ingest(self, raw: dict) -> TeleopFrame:
        """Map one raw frame and make it the latest (the polling thread calls this)."""
        frame, self.height = map_gp001(raw, height=self.height, speed=self.speed)
        self.frames.put(frame)
        return frame

    def _poll_loop(self) -> None:
        while not self._stop.is_set():
            raw = self.transport.read()
            if raw is not None:
                self.ingest(raw)
            time.sleep(POLL_S)

    def reset(self) -> None:
        super().reset()
        self.height = 0.0

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
        self.transport.close()
        super().close()
