"""Weld a robot's joints in its MJCF: the joint element is removed and its value folded into its body's pose, so
MuJoCo rides the body rigidly on its parent (no degree of freedom), together with the actuators and equality
constraints that name it.

Why in the MJCF: Newton's importer makes a joint-less body a fixed joint of the same body, so the welded model
keeps every body (same order, same shapes) and only loses coordinates, which is what ``envs.drive`` needs to
mirror the solver's coordinates into the full robot's layout. MuJoCo has no per-joint "locked" flag; welding by
equality constraints would add rows to every solve instead of removing degrees of freedom.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Mapping

import numpy as np

from .quaternions import quat_mul, quat_rotate


def coupled_joints(root: ET.Element, joints: Iterable[str]) -> set[str]:
    """``joints`` and every joint tied to one of them by an MJCF ``<equality><joint>`` (transitively): a gripper's
    fingers move with its master joint, so welding one without the other would freeze the gripper."""
    pairs = [(e.get("joint1"), e.get("joint2")) for eq in root.findall("equality") for e in eq.findall("joint")]
    out = set(joints)
    grown = True
    while grown:
        grown = False
        for a, b in pairs:
            if (a in out) != (b in out) and None not in (a, b):
                out |= {a, b}
                grown = True
    return out


def weld_mjcf(path: str, values: Mapping[str, float], keep: Iterable[str]) -> tuple[str, tuple[str, ...]]:
    """The MJCF at ``path`` with every joint welded except ``keep`` and the joints coupled to them
    (``coupled_joints``); a welded joint's value is ``values[name]`` (0 when absent) [rad | m]. Returns the MJCF
    text and the welded joint names in document order. Hinges turn their body about the joint axis through the
    body origin; slides shift it along the axis (both in the parent frame)."""
    tree = ET.parse(path)
    root = tree.getroot()
    kept = coupled_joints(root, keep)
    welded: list[str] = []
    for body in root.iter("body"):
        joints = [j for j in body.findall("joint") if j.get("name") not in kept]
        if not joints:
            continue
        pos = np.array([float(v) for v in body.get("pos", "0 0 0").split()])
        w, x, y, z = (float(v) for v in body.get("quat", "1 0 0 0").split())  # MJCF: wxyz
        quat = np.array([[x, y, z, w]])
        for joint in joints:
            if joint.get("pos") not in (None, "0 0 0"):
                raise ValueError(f"joint {joint.get('name')!r} has an offset pivot; welding it is not supported")
            axis = np.array([float(v) for v in joint.get("axis", "0 0 1").split()])
            axis = axis / np.linalg.norm(axis)
            value = float(values.get(joint.get("name"), 0.0))
            if joint.get("type", "hinge") == "slide":
                pos = pos + quat_rotate(quat, axis * value)[0]
            elif joint.get("type", "hinge") == "hinge":
                quat = quat_mul(quat, np.array([[*(axis * math.sin(0.5 * value)), math.cos(0.5 * value)]]))
            else:
                raise ValueError(f"joint {joint.get('name')!r} of type {joint.get('type')!r} cannot be welded")
            welded.append(joint.get("name"))
            body.remove(joint)
        x, y, z, w = quat[0]
        body.set("pos", " ".join(f"{v:.9g}" for v in pos))
        body.set("quat", " ".join(f"{v:.9g}" for v in (w, x, y, z)))
    gone = set(welded)
    for section in ("actuator", "equality"):
        for parent in root.findall(section):
            for child in list(parent):
                if {child.get("joint"), child.get("joint1"), child.get("joint2")} & gone:
                    parent.remove(child)
    return ET.tostring(root, encoding="unicode"), tuple(welded)
