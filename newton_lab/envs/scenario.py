"""Scenarios: YAML reset overlays that start a component task where another one ended.

A scenario names the robot's base pose and joint positions and the dynamic objects' root poses, in the env
frame; on every reset a row goes to the task's defaults and then to this overlay (velocities zero, joint
targets = positions). ``capture_scenario`` writes one from a row's state (e.g. the end of a pick episode).
Scenarios never connect the phases of a coherent task: those run in one episode without any reset.

File format (positions [m], angles [rad], quaternions xyzw)::

    schema: newton_lab/scenario-v1
    frame: env
    articulations:
      robot:
        base_pose: [x, y, z, qx, qy, qz, qw]     # planar base: x, y and the yaw of the quaternion
        joint_position: {left_arm_joint1: 1.2, left_gripper_joint: 1.2, ...}
    rigid_objects:
      cube: {root_pose: [x, y, z, qx, qy, qz, qw]}
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import warp as wp
import yaml

from ..datasets.files.output_paths import output_path

SCHEMA = "newton_lab/scenario-v1"
ROBOT = "robot"
_TOP_KEYS = {"schema", "frame", "articulations", "rigid_objects", "source"}
_ROBOT_KEYS = {"base_pose", "joint_position"}
_OBJECT_KEYS = {"root_pose"}


class ScenarioError(ValueError):
    """A scenario file that does not fit the schema or the task (the message names the key)."""


@dataclass
class Scenario:
    """A parsed scenario; ``origin`` says where it came from (for messages)."""

    base_pose: tuple[float, ...] | None = None
    joint_position: dict[str, float] = field(default_factory=dict)
    root_poses: dict[str, tuple[float, ...]] = field(default_factory=dict)
    source: str | None = None
    origin: str = "<scenario>"

    # ------------------------------------------------------------------ apply
    def overlay(self, layout, default_q: np.ndarray, *, task_id: str) -> np.ndarray:
        """The task's default coordinates of one world with this scenario applied on top."""
        q = np.array(default_q, dtype=np.float32, copy=True)
        coord, planar = layout.joints.coord, layout.robot.base_planar_joints
        if self.base_pose is not None:
            x, y, _, qx, qy, qz, qw = self.base_pose
            q[coord[planar[0]]], q[coord[planar[1]]] = x, y
            q[coord[planar[2]]] = math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
        robot_joints = sorted(n for n in coord if n not in planar)
        for name, value in self.joint_position.items():
            if name not in coord or name in planar:
                raise ScenarioError(
                    f"{self.origin}: articulations.robot.joint_position names unknown joint "
                    f"{name!r} for {task_id}; valid joints: {robot_joints}"
                )
            q[coord[name]] = value
        slots = {name: k for k, name in enumerate(layout.entity_names)}
        for name, pose in self.root_poses.items():
            if name not in slots:
                raise ScenarioError(
                    f"{self.origin}: rigid_objects.{name} is not an object of {task_id}; "
                    f"valid objects: {layout.entity_names}"
                )
            k = slots[name]
            c = layout.entity_coord[k]
            if c < 0:
                scene = np.asarray(layout.entity_static_pose[k][:3])
                if np.abs(np.asarray(pose[:3]) - scene).max() > 1e-3:
                    raise ScenarioError(
                        f"{self.origin}: rigid_objects.{name} is a static object of {task_id} "
                        f"at {scene.tolist()}; it cannot be moved (drop the entry)"
                    )
                continue
            quat = np.asarray(pose[3:7], dtype=np.float64)
            q[c : c + 3] = pose[:3]
            q[c + 3 : c + 7] = quat / np.linalg.norm(quat)
        return q

    # ------------------------------------------------------------------ serialise
    def to_dict(self) -> dict[str, Any]:
        robot: dict[str, Any] = {}
        if self.base_pose is not None:
            robot["base_pose"] = [float(v) for v in self.base_pose]
        if self.joint_position:
            robot["joint_position"] = {k: float(v) for k, v in self.joint_position.items()}
        out: dict[str, Any] = {"schema": SCHEMA, "frame": "env"}
        if self.source:
            out["source"] = self.source
        out["articulations"] = {ROBOT: robot}
        out["rigid_objects"] = {k: {"root_pose": [float(v) for v in p]} for k, p in self.root_poses.items()}
        return out

    def save(self, path: str | Path) -> Path:
        """Write the YAML; an existing file is never replaced."""
        path = output_path(path)
        with open(path, "x") as f:  # "x": refuse to overwrite
            yaml.safe_dump(self.to_dict(), f, sort_keys=False)
        return path


def _pose(value: Any, where: str) -> tuple[float, ...]:
    if not isinstance(value, (list, tuple)) or len(value) != 7:
        raise ScenarioError(f"{where} must be a list of 7 numbers [x, y, z, qx, qy, qz, qw], got {value!r}")
    try:
        pose = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise ScenarioError(f"{where} must hold numbers, got {value!r}") from None
    if not all(math.isfinite(v) for v in pose) or np.linalg.norm(pose[3:]) < 1e-6:
        raise ScenarioError(f"{where} must be finite with a non-zero quaternion, got {list(pose)}")
    return pose


def _check_keys(d: Any, allowed: set[str], where: str) -> dict:
    if not isinstance(d, dict):
        raise ScenarioError(f"{where} must be a mapping, got {type(d).__name__}")
    unknown = sorted(set(d) - allowed)
    if unknown:
        raise ScenarioError(f"{where} has unknown field(s) {unknown}; valid fields: {sorted(allowed)}")
    return d


def parse_scenario(data: Any, origin: str = "<scenario>") -> Scenario:
    """Validate a loaded YAML document; errors name the offending key."""
    data = _check_keys(data, _TOP_KEYS, origin)
    if data.get("schema") != SCHEMA:
        raise ScenarioError(f"{origin}: schema must be {SCHEMA!r}, got {data.get('schema')!r}")
    if data.get("frame", "env") != "env":
        raise ScenarioError(f"{origin}: frame must be 'env', got {data.get('frame')!r}")
    scn = Scenario(source=data.get("source"), origin=origin)
    arts = _check_keys(data.get("articulations") or {}, {ROBOT}, f"{origin}: articulations")
    robot = _check_keys(arts.get(ROBOT) or {}, _ROBOT_KEYS, f"{origin}: articulations.robot")
    if "base_pose" in robot:
        scn.base_pose = _pose(robot["base_pose"], f"{origin}: articulations.robot.base_pose")
    joints = robot.get("joint_position") or {}
    if not isinstance(joints, dict):
        raise ScenarioError(f"{origin}: articulations.robot.joint_position must map joint names to numbers")
    for name, value in joints.items():
        if not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ScenarioError(
                f"{origin}: articulations.robot.joint_position.{name} must be a finite number, got {value!r}"
            )
        scn.joint_position[str(name)] = float(value)
    objects = data.get("rigid_objects") or {}
    if not isinstance(objects, dict):
        raise ScenarioError(f"{origin}: rigid_objects must map object names to {{root_pose: [...]}}")
    for name, entry in objects.items():
        entry = _check_keys(entry, _OBJECT_KEYS, f"{origin}: rigid_objects.{name}")
        if "root_pose" not in entry:
            raise ScenarioError(f"{origin}: rigid_objects.{name} needs a root_pose")
        scn.root_poses[str(name)] = _pose(entry["root_pose"], f"{origin}: rigid_objects.{name}.root_pose")
    return scn


def load_scenario(ref: str | Path) -> Scenario:
    """Load a scenario from a file path or a ``package:file.yaml`` resource."""
    text_ref = str(ref)
    module, sep, name = text_ref.partition(":")
    if sep and name.endswith((".yaml", ".yml")) and "/" not in module and "\\" not in module:
        try:
            text = resources.files(module).joinpath(name).read_text()
        except (ModuleNotFoundError, FileNotFoundError):
            raise ScenarioError(
                f"scenario resource {text_ref!r} not found; pass a YAML path or package:file.yaml"
            ) from None
    else:
        path = Path(text_ref).expanduser()
        if not path.is_file():
            raise ScenarioError(
                f"scenario file {path} does not exist; check the path (or save one with --save-end-scenario)"
            )
        text = path.read_text()
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as e:
        raise ScenarioError(f"scenario {text_ref} is not valid YAML ({str(e).splitlines()[0]})") from None
    return parse_scenario(data, origin=text_ref)


def capture_scenario(env, row: int = 0, *, terminal: bool = False, source: str | None = None) -> Scenario:
    """The scenario of ``row``'s current state (``terminal=True``: the state its last episode ended in)."""
    lay = env.sim.layout
    coords = env.buffers.terminal_joint_q if terminal else wp.to_torch(env.state.joint_q).view(env.num_envs, -1)
    q = coords[row].detach().cpu().numpy().astype(np.float64)
    coord, planar = lay.joints.coord, env.robot.base_planar_joints
    yaw = q[coord[planar[2]]]
    base = (q[coord[planar[0]]], q[coord[planar[1]]], 0.0, 0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))
    joints = {n: float(q[c]) for n, c in sorted(coord.items(), key=lambda kv: kv[1]) if n not in planar}
    poses = {}
    for k, name in enumerate(lay.entity_names):
        c = lay.entity_coord[k]
        if c >= 0:
            poses[name] = tuple(float(v) for v in q[c : c + 7])
    return Scenario(base_pose=base, joint_position=joints, root_poses=poses, source=source or env.task_id)
