"""Teleop devices by name: ``keyboard`` (terminal), ``replay`` (a recorded demo), ``gp001`` (Galbot's leader
arms, injectable transport), ``spacemouse`` / ``gamepad`` (optional hidapi / evdev)."""

from __future__ import annotations

from .base import TeleopDevice
from .gp001 import Gp001Device
from .hid import GamepadDevice, SpaceMouseDevice
from .keyboard import KeyboardDevice
from .replay import ReplayDevice

DEVICES: dict[str, type[TeleopDevice]] = {
    "keyboard": KeyboardDevice,
    "replay": ReplayDevice,
    "gp001": Gp001Device,
    "galbot_remote": Gp001Device,  # the reference's aliases
    "remote": Gp001Device,
    "spacemouse": SpaceMouseDevice,
    "gamepad": GamepadDevice,
}


def device_class(name: str) -> type[TeleopDevice]:
    """The device class called ``name``; one line listing the valid names otherwise."""
    if name not in DEVICES:
        raise ValueError(f"unknown teleop device {name!r}; valid devices: {', '.join(DEVICES)}")
    return DEVICES[name]


__all__ = [
    "DEVICES",
    "Gp001Device",
    "GamepadDevice",
    "KeyboardDevice",
    "ReplayDevice",
    "SpaceMouseDevice",
    "TeleopDevice",
    "device_class",
]
