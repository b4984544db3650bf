"""The robot registry: ``robot_binding(name)`` -> the ``RobotBinding`` a task config names (``TaskCfg.robot``).

A robot package registers its binding with ``register_robot``; the built-in G1 (``robots.g1.robot``) is registered
on its first look-up, so naming a robot costs nothing until its binding is used (the G1's imports Newton).
"""

from __future__ import annotations

from .binding import RobotBinding

DEFAULT_ROBOT = "g1"
"""The robot a task config names unless it says otherwise (``TaskCfg.robot``), and the one robot-level helpers
(teleop mappers, Mimic's source reader) use without an env."""
BUILTIN_ROBOTS = ("g1",)
"""Robots that ship with newton_lab, registered on their first look-up."""

_ROBOTS: dict[str, RobotBinding] = {}


def register_robot(binding: RobotBinding) -> RobotBinding:
    """Make ``binding`` the robot called ``binding.name``; registering one name twice is refused."""
    if binding.name in _ROBOTS and _ROBOTS[binding.name] is not binding:
        raise ValueError(f"robot {binding.name!r} is already registered")
    _ROBOTS[binding.name] = binding
    return binding


def robot_binding(name: str = DEFAULT_ROBOT) -> RobotBinding:
    """The registered robot called ``name`` (a built-in robot registers on its first look-up)."""
    if name not in _ROBOTS and name in BUILTIN_ROBOTS:
        from .g1.robot import G1  # deferred: the G1's binding imports Newton (its model, kinematics)

        register_robot(G1)
    if name not in _ROBOTS:
        raise ValueError(f"unknown robot {name!r}; registered robots: {sorted(_ROBOTS)}")
    return _ROBOTS[name]


def robot_names() -> list[str]:
    """Names of the registered robots (the built-in ones among them)."""
    for name in BUILTIN_ROBOTS:
        robot_binding(name)
    return sorted(_ROBOTS)
