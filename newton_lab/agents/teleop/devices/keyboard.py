"""``keyboard``: a terminal device (raw stdin, no window system). Keys jog the TCP in Cartesian space (the
agent turns the cumulative offset into arm joints through the batched IK), toggle the gripper and, for mobile
contracts, set the base twist and the body height. Letters that are not keys collect into a command line;
Enter submits it: ``done`` ends the episode for review.

Reading is one byte at a time from the stdin file descriptor on a thread, so nothing is read ahead of the
review prompt, and works on a terminal (cbreak mode, restored on pause and close) and on a pipe alike.
"""

from __future__ import annotations

import math
import os
import select
import sys
import termios
import threading
import time
import tty

import numpy as np

from ..frames import TeleopFrame
from .base import TeleopDevice

JOG_KEYS = {
    "i": (0, +1),
    "k": (0, -1),  # TCP x (world, away from the robot / towards it)
    "j": (1, +1),
    "l": (1, -1),  # TCP y (left / right)
    "r": (2, +1),
    "f": (2, -1),  # TCP z (up / down)
    "u": (3, +1),
    "y": (3, -1),  # TCP yaw (counter-clockwise / clockwise seen from above)
}
"""Key -> (offset axis, sign): x, y, z [m] by the jog step, yaw [rad] by the yaw step."""
TWIST_KEYS = {"\x1b[A": (0, +1), "\x1b[B": (0, -1), "\x1b[D": (1, +1), "\x1b[C": (1, -1), "q": (2, +1), "w": (2, -1)}
"""Mobile contracts: arrow keys -> base vx / vy, q / w -> base yaw rate (each press adds one twist step)."""
KEY_MAP = """\
keyboard teleop - keys act at once, no Enter:
  i / k   TCP +x / -x        j / l   TCP +y / -y        r / f   TCP up / down
  u / y   TCP yaw + / -      space   gripper open <-> close
  [ / ]   jog step x0.5 / x2 (now {step_mm:.0f} mm, {yaw_deg:.0f} deg)
  mobile: arrows base vx / vy, q / w yaw rate, x stop, t / b body up / down
type a command and Enter:  done  -> end the episode and review it (keep / drop / exit)"""


class KeyboardDevice(TeleopDevice):
    """Jog state from keys on ``fd`` (default stdin). ``step`` [m] and ``yaw_step`` [rad] per press; twist steps
    ``twist_step`` [m/s] and ``yaw_rate_step`` [rad/s]; body-height step ``height_step`` [rad]."""

    name = "keyboard"
    contracts = ("left_arm_manipulation", "mobile_full_body")

    def __init__(
        self,
        fd: int | None = None,
        *,
        step: float = 0.01,
        yaw_step: float = math.radians(5.0),
        twist_step: float = 0.05,
        yaw_rate_step: float = 0.1,
        height_step: float = 0.02,
        arm: str = "left",
    ):
        super().__init__()
        self.fd = sys.stdin.fileno() if fd is None else fd
        self.step, self.yaw_step = float(step), float(yaw_step)
        self.twist_step, self.yaw_rate_step, self.height_step = (
            float(twist_step),
            float(yaw_rate_step),
            float(height_step),
        )
        self.arm, self.jog_arms = arm, (arm,)
        self.command = ""
        """The command line being typed (shown in the status line)."""
        self.message = ""
        """The answer to the last command (e.g. an unknown one)."""
        self._lock = threading.Lock()
        self._reading = threading.Event()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._saved_tty = None
        self._zero()

    def _zero(self) -> None:
        self.offset = np.zeros(4)
        self.gripper_open = True
        self.twist = np.zeros(3)
        self.height = 0.0

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> None:
        super().start()
        self._thread = threading.Thread(target=self._read_loop, name="keyboard-teleop", daemon=True)
        self._thread.start()  # it reads once the first episode begins (``resume``)

    def resume(self) -> None:
        if os.isatty(self.fd) and self._saved_tty is None:
            self._saved_tty = termios.tcgetattr(self.fd)
            tty.setcbreak(self.fd)  # keys arrive one by one, unechoed; Ctrl-C still interrupts
        self._reading.set()

    def pause(self) -> None:
        with self._lock:  # waits for a key being handled; the reader holds the lock while it reads
            self._reading.clear()
            if self._saved_tty is not None:
                termios.tcsetattr(self.fd, termios.TCSADRAIN, self._saved_tty)
                self._saved_tty = None

    def close(self) -> None:
        self._stop.set()
        self.pause()
        super().close()

    def reset(self) -> None:
        super().reset()
        with self._lock:  # no frame until a key: the agent holds the arm where the episode starts
            self._zero()
            self.command = self.message = ""

    def help(self) -> str:
        return KEY_MAP.format(step_mm=self.step * 1e3, yaw_deg=math.degrees(self.yaw_step))

    # ------------------------------------------------------------------ input
    def _read_byte(self, timeout: float) -> str | None:
        """One byte from ``fd`` within ``timeout`` [s]; '' at end of input, None when nothing came."""
        ready, _, _ = select.select([self.fd], [], [], timeout)
        if not ready:
            return None
        data = os.read(self.fd, 1)
        return data.decode("latin-1") if data else ""

    def _read_loop(self) -> None:
        while not self._stop.is_set():
            if not self._reading.wait(0.05):
                continue
            with self._lock:
                if not self._reading.is_set():
                    continue
                ch = self._read_byte(0.05)
                if ch is None:
                    continue
                if ch == "":  # end of input (a closed pipe): nothing more will come
                    self._reading.clear()
                    self.request_exit()
                    return
                if ch == "\x1b":  # an escape sequence (arrow keys): two more bytes
                    ch += "".join(self._read_byte(0.05) or "" for _ in range(2))
                self.handle_key(ch)
            self._publish()

    def handle_key(self, key: str) -> None:
        """Apply one key (or escape sequence) to the jog state."""
        if key in JOG_KEYS:
            axis, sign = JOG_KEYS[key]
            self.offset[axis] += sign * (self.yaw_step if axis == 3 else self.step)
        elif key == " ":
            self.gripper_open = not self.gripper_open
        elif key in ("[", "]"):
            factor = 0.5 if key == "[" else 2.0
            self.step, self.yaw_step = self.step * factor, self.yaw_step * factor
        elif key in TWIST_KEYS:
            axis, sign = TWIST_KEYS[key]
            self.twist[axis] += sign * (self.yaw_rate_step if axis == 2 else self.twist_step)
        elif key == "x":
            self.twist[:] = 0.0
        elif key in ("t", "b"):
            self.height += self.height_step if key == "t" else -self.height_step
        elif key in ("\r", "\n"):
            self._submit(self.command.strip().lower())
        elif key in ("\x7f", "\b"):
            self.command = self.command[:-1]
        elif key.isprintable() and len(key) == 1:
            self.command += key

    def _submit(self, command: str) -> None:
        self.command = ""
        if command == "done":
            self.message = "episode ended: review it"
            self._reading.clear()  # the review prompt reads the next line
            self.request_exit()
        elif command:
            self.message = f"unknown command {command!r}; type done to end the episode"

    def _publish(self) -> None:
        self.frames.put(
            TeleopFrame(
                timestamp=time.perf_counter(),
                tcp_offset={self.arm: self.offset.copy()},
                gripper_open={self.arm: self.gripper_open},
                base_twist=tuple(float(v) for v in self.twist),
                body_height=self.height,
            )
        )
