"""``spacemouse`` (hidapi) and ``gamepad`` (evdev): optional extras, opened where the OS exposes the device.

Both jog the TCP like the keyboard does: the spacemouse's translation axes and yaw move the jog offset at
``speed`` [m/s] / ``yaw_speed`` [rad/s], its left button toggles the gripper; the gamepad's left stick moves x / y,
the triggers z, the right stick x the yaw, button south toggles the gripper (and for mobile contracts the d-pad
sets the base twist). Without the library or the device they fail in one line naming the fix.
"""

from __future__ import annotations

import threading
import time

import numpy as np

from ..frames import TeleopFrame
from .base import TeleopDevice

SPACEMOUSE_VENDOR_ID = 0x256F
"""3Dconnexion's USB vendor id."""
POLL_S = 0.01


class _JogDevice(TeleopDevice):
    """Integrates velocity readings into the cumulative TCP offset on a polling thread."""

    def __init__(self, *, speed: float = 0.1, yaw_speed: float = 0.5, arm: str = "left"):
        super().__init__()
        self.speed, self.yaw_speed, self.arm, self.jog_arms = float(speed), float(yaw_speed), arm, (arm,)
        self.offset = np.zeros(4)
        self.gripper_open = True
        self.twist = (0.0, 0.0, 0.0)
        self._stop = threading.Event()
        self._last = time.perf_counter()

    def read_velocity(self) -> tuple[np.ndarray, bool] | None:
        """(vx, vy, vz, wyaw) in [-1, 1] and whether the gripper button was pressed since the last read."""
        raise NotImplementedError

    def _loop(self) -> None:
        while not self._stop.is_set():
            reading = self.read_velocity()
            now = time.perf_counter()
            dt, self._last = now - self._last, now
            if reading is not None:
                vel, toggled = reading
                self.offset += np.asarray(vel) * dt * np.array([self.speed] * 3 + [self.yaw_speed])
                self.gripper_open ^= toggled
                self.frames.put(
                    TeleopFrame(
                        timestamp=now,
                        tcp_offset={self.arm: self.offset.copy()},
                        gripper_open={self.arm: self.gripper_open},
                        base_twist=self.twist,
                    )
                )
            time.sleep(POLL_S)

    def start(self) -> None:
        self.open()
        super().start()
        threading.Thread(target=self._loop, name=f"{self.name}-teleop", daemon=True).start()

    def reset(self) -> None:
        super().reset()
        self.offset = np.zeros(4)

    def close(self) -> None:
        self._stop.set()
        super().close()


class SpaceMouseDevice(_JogDevice):
    name = "spacemouse"
    contracts = ("left_arm_manipulation",)

    def open(self) -> None:
        try:
            import hid  # noqa: PLC0415  deferred: an optional extra (hidapi)
        except ImportError:
            raise ValueError(
                "spacemouse: the hidapi package is not installed; pip install 'newton_lab[teleop]' "
                "(or use --device keyboard)"
            ) from None
        found = [d for d in hid.enumerate() if d.get("vendor_id") == SPACEMOUSE_VENDOR_ID]
        if not found:
            raise ValueError(
                "spacemouse: no 3Dconnexion device is connected (hidapi found none); plug one in or use "
                "--device keyboard"
            )
        self._dev = hid.device()
        self._dev.open(found[0]["vendor_id"], found[0]["product_id"])
        self._dev.set_nonblocking(True)
        self._button = False

    def read_velocity(self):
        data = self._dev.read(13)
        if not data:
            return None
        if data[0] == 1:  # translation report: three little-endian int16 in [-350, 350]
            t = [int.from_bytes(bytes(data[1 + 2 * i : 3 + 2 * i]), "little", signed=True) / 350.0 for i in range(3)]
            return np.array([t[1], t[0], -t[2], 0.0]), False
        if data[0] == 2:  # rotation report: yaw is the third axis
            r = [int.from_bytes(bytes(data[1 + 2 * i : 3 + 2 * i]), "little", signed=True) / 350.0 for i in range(3)]
            return np.array([0.0, 0.0, 0.0, -r[2]]), False
        if data[0] == 3:  # buttons: bit 0 = left
            pressed = bool(data[1] & 1)
            toggled, self._button = pressed and not self._button, pressed
            return np.zeros(4), toggled
        return None


class GamepadDevice(_JogDevice):
    name = "gamepad"
    contracts = ("left_arm_manipulation", "mobile_full_body")

    def open(self) -> None:
        try:
            import evdev  # noqa: PLC0415  deferred: an optional extra (Linux input events)
        except ImportError:
            raise ValueError(
                "gamepad: the evdev package is not installed; pip install 'newton_lab[teleop]' "
                "(or use --device keyboard)"
            ) from None
        pads = [evdev.InputDevice(p) for p in evdev.list_devices()]
        pads = [p for p in pads if evdev.ecodes.EV_ABS in p.capabilities()]
        if not pads:
            raise ValueError(
                "gamepad: no joystick is exposed under /dev/input (evdev found none); plug one in or "
                "use --device keyboard"
            )
        self._pad, self._ecodes = pads[0], evdev.ecodes
        self._axes = np.zeros(4)

    def read_velocity(self):
        e, toggled, seen = self._ecodes, False, False
        while (event := self._pad.read_one()) is not None:
            seen = True
            if event.type == e.EV_ABS:
                norm = event.value / 32768.0
                axis = {e.ABS_Y: (0, -1), e.ABS_X: (1, -1), e.ABS_RX: (3, -1)}.get(event.code)
                if axis is not None:
                    self._axes[axis[0]] = axis[1] * norm
                elif event.code in (e.ABS_Z, e.ABS_RZ):  # triggers 0..255: down / up
                    self._axes[2] = (event.value / 255.0) * (1 if event.code == e.ABS_RZ else -1)
            elif event.type == e.EV_KEY and event.code == e.BTN_SOUTH and event.value == 1:
                toggled = True
        return (self._axes.copy(), toggled) if seen or self._axes.any() else None
