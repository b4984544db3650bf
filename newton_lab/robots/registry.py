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


def camera_facts(name: str = DEFAULT_ROBOT) -> tuple[tuple[str, ...], int, int]:
    """(camera mount names, smallest and largest image side [px]) of robot ``name``, from its pure-data modules
    (no Newton): what the command line checks before anything heavy is imported. A registered robot's binding
    answers for it."""
    if name in BUILTIN_ROBOTS and name not in _ROBOTS:
        from .g1.cameras import MAX_RESOLUTION, MIN_RESOLUTION  # deferred: numpy; the G1's binding imports Newton
        from .g1.spec import CAMERA_MOUNTS  # deferred: as above

        return tuple(CAMERA_MOUNTS), int(MIN_RESOLUTION), int(MAX_RESOLUTION)
    robot = robot_binding(name)
    lo, hi = robot.camera_resolution
    return tuple(robot.camera_mounts), int(lo), int(hi)


def joint_group_facts(name: str = DEFAULT_ROBOT) -> dict[str, tuple[str, ...]]:
    """Joint group -> joint names of robot ``name``, from its pure-data spec (no Newton), for the command line's
    checks; a registered robot's binding answers for it."""
    if name in BUILTIN_ROBOTS and name not in _ROBOTS:
        from .g1.spec import JOINT_GROUPS  # deferred: numpy; the G1's binding imports Newton

        return {k: tuple(v) for k, v in JOINT_GROUPS.items()}
    return {k: tuple(v) for k, v in robot_binding(name).joint_groups.items()}
