"""Galbot G1 action packers: numpy + torch (no Newton).

Turn human-level commands into batched action tensors of shape ``(num_envs, A)``:

* base twist ``(vx, vy, wz)`` <-> mecanum wheel velocities ``wheel1..wheel4`` [rad/s], through the one wheel
  formula (``robots.g1.mecanum``, a Warp function run on the tensors' device);
* named absolute joint targets [rad] packed into an action-joint order, keeping a baseline elsewhere;
* named relative joint deltas (scaled) with zeros elsewhere;
* binary gripper open/close flags -> master-joint targets [rad], on some rows keeping a baseline elsewhere.

All tensors are float32 unless stated. Every validation failure raises ``ValueError`` with a one-line
message naming the problem and the fix.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch

from newton_lab.robots.g1 import spec
from newton_lab.robots.g1.mecanum import twist_to_wheels_torch, wheel_gains, wheels_to_twist_torch

__all__ = [
    "G1_ACTION_TYPES",
    "base_twist_to_wheel_velocities",
    "g1_action",
    "gripper_binary",
    "pack_joint_positions",
    "pack_relative_joint_positions",
    "wheel_gains",
    "wheel_velocities_to_base_twist",
]

DTYPE = torch.float32

G1_ACTION_TYPES: dict[str, tuple[str, ...]] = {
    "base": ("velocity",),
    "legs": ("absolute", "relative"),
    "left_arm": ("absolute", "relative"),
    "right_arm": ("absolute", "relative"),
    "left_gripper": ("binary",),
    "right_gripper": ("binary",),
}
"""Valid ``g1_action`` (group -> types) combinations."""


# ---------------------------------------------------------------- shared helpers
def _device_of(device: Any, *tensors: Any) -> torch.device:
    """Explicit ``device`` if given, else the first torch tensor's device, else CPU."""
    if device is not None:
        return torch.device(device)
    for t in tensors:
        if isinstance(t, torch.Tensor):
            return t.device
    return torch.device("cpu")


def _as_float(x: Any, device: torch.device) -> torch.Tensor:
    """Any scalar / list / numpy / torch input -> float32 tensor on ``device``."""
    if isinstance(x, torch.Tensor):
        return x.to(device=device, dtype=DTYPE)
    return torch.as_tensor(np.asarray(x, dtype=np.float32), device=device)


def _check_num_envs(num_envs: Any, fn: str) -> int:
    if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
        raise ValueError(f"{fn}: num_envs must be a positive int, got {num_envs!r}; pass num_envs>=1")
    return int(num_envs)


def _env_rows(env_indices: Any, num_envs: int, device: torch.device, fn: str) -> torch.Tensor | None:
    """Validate ``env_indices`` (1-D, non-empty, unique, in [0, num_envs)) -> int64 tensor, or None."""
    if env_indices is None:
        return None
    idx = env_indices.detach().cpu().numpy() if isinstance(env_indices, torch.Tensor) else np.asarray(env_indices)
    if idx.ndim == 0:
        idx = idx.reshape(1)
    if idx.ndim != 1:
        raise ValueError(f"{fn}: env_indices must be 1-D, got shape {tuple(idx.shape)}; pass a flat list of row ids")
    if idx.size == 0:
        raise ValueError(f"{fn}: env_indices is empty; pass at least one row id or env_indices=None for all rows")
    if not np.issubdtype(idx.dtype, np.integer):
        raise ValueError(f"{fn}: env_indices must be integers, got dtype {idx.dtype}; pass int row ids")
    if np.unique(idx).size != idx.size:
        dup = sorted({int(i) for i in idx if (idx == i).sum() > 1})
        raise ValueError(f"{fn}: duplicate env_indices {dup}; list each row once")
    bad = [int(i) for i in idx if i < 0 or i >= num_envs]
    if bad:
        raise ValueError(f"{fn}: env_indices {bad} out of range [0, {num_envs}); use row ids 0..{num_envs - 1}")
    return torch.as_tensor(idx.astype(np.int64), device=device)


def _names(names: Any, what: str, fn: str) -> tuple[str, ...]:
    """Validate a joint-name list (a bare str counts as one name; no duplicates) -> tuple."""
    out = (names,) if isinstance(names, str) else tuple(names)
    if not all(isinstance(n, str) for n in out):
        raise ValueError(f"{fn}: {what} must be strings, got {out!r}; pass joint names such as 'leg_joint1'")
    dup = sorted({n for n in out if out.count(n) > 1})
    if dup:
        raise ValueError(f"{fn}: duplicate joint names in {what}: {dup}; list each joint once")
    return out


def _columns(joint_names: tuple[str, ...], action_joint_names: tuple[str, ...], fn: str) -> list[int]:
    """Column of each named joint in the action vector; unknown names raise."""
    pos = {n: i for i, n in enumerate(action_joint_names)}
    unknown = [n for n in joint_names if n not in pos]
    if unknown:
        raise ValueError(f"{fn}: unknown joint(s) {unknown}; valid action joints: {', '.join(action_joint_names)}")
    return [pos[n] for n in joint_names]


def _row_values(values: Any, n_joints: int, n_rows: int, what: str, device: torch.device, fn: str) -> torch.Tensor:
    """``values`` of shape (J,) broadcast, or (n_rows, J) -> float32 (n_rows, J)."""
    v = _as_float(values, device)
    if v.ndim == 0 and n_joints == 1:
        v = v.reshape(1)
    if v.ndim == 1 and v.shape[0] == n_joints:
        return v.unsqueeze(0).expand(n_rows, n_joints)
    if v.ndim == 2 and v.shape == (n_rows, n_joints):
        return v
    raise ValueError(
        f"{fn}: {what} has shape {tuple(v.shape)} but {n_joints} joint name(s) were given for {n_rows} row(s); "
        f"pass shape ({n_joints},) or ({n_rows}, {n_joints})"
    )


def _start(baseline: Any, current: Any, num_envs: int, n_act: int, device: torch.device, fn: str) -> torch.Tensor:
    """Initial (N, A) action: ``baseline`` ((A,) or (N, A)) if given, else ``current`` ((N, A)), else zeros."""
    if baseline is not None:
        b = _as_float(baseline, device)
        if b.shape == (n_act,):
            return b.unsqueeze(0).repeat(num_envs, 1)
        if b.shape == (num_envs, n_act):
            return b.clone()
        raise ValueError(
            f"{fn}: baseline has shape {tuple(b.shape)}; pass shape ({n_act},) or ({num_envs}, {n_act}) "
            f"matching action_joint_names and num_envs"
        )
    if current is not None:
        c = _as_float(current, device)
        if c.shape == (num_envs, n_act):
            return c.clone()
        raise ValueError(
            f"{fn}: current has shape {tuple(c.shape)}; pass shape ({num_envs}, {n_act}) "
            f"(num_envs x len(action_joint_names))"
        )
    return torch.zeros(num_envs, n_act, dtype=DTYPE, device=device)


# ---------------------------------------------------------------- base: twist <-> wheels
def base_twist_to_wheel_velocities(
    vx: Any = 0.0,
    vy: Any = 0.0,
    wz: Any = 0.0,
    *,
    num_envs: int | None = None,
    env_indices: Any = None,
    lin_scale: float = 1.0,
    ang_scale: float = 1.0,
    device: Any = None,
) -> torch.Tensor:
    """Base twist -> wheel velocities, float32 (N, 4) in order wheel1..wheel4 [rad/s].

    ``vx``, ``vy`` [m/s] (base frame) and ``wz`` [rad/s] are scalars or per-row 1-D values of length
    ``len(env_indices)`` (when given) else ``num_envs``. ``N`` is ``num_envs``, else the per-row
    length, else 1. With ``env_indices`` only those rows get the twist; other rows are 0.
    """
    fn = "base_twist_to_wheel_velocities"
    dev = _device_of(device, vx, vy, wz)
    parts = [_as_float(x, dev) for x in (vx, vy, wz)]
    for name, p in zip(("vx", "vy", "wz"), parts):
        if p.ndim > 1:
            raise ValueError(f"{fn}: {name} has shape {tuple(p.shape)}; pass a scalar or a 1-D per-row tensor")
    lengths = {p.shape[0] for p in parts if p.ndim == 1}
    if len(lengths) > 1:
        raise ValueError(f"{fn}: vx/vy/wz lengths differ {sorted(lengths)}; pass scalars or equal-length 1-D values")
    if num_envs is None:
        if env_indices is not None:
            raise ValueError(f"{fn}: env_indices needs num_envs to size the output; pass num_envs=N")
        num_envs = lengths.pop() if lengths else 1
    n = _check_num_envs(num_envs, fn)
    rows = _env_rows(env_indices, n, dev, fn)
    m = n if rows is None else int(rows.shape[0])
    if lengths and lengths != {m}:
        raise ValueError(
            f"{fn}: per-row twist length {lengths.pop()} != {m} selected row(s); "
            f"pass scalars or length len(env_indices) (or num_envs when env_indices is None)"
        )
    twist = torch.stack([p.expand(m) for p in parts], dim=-1)
    wheels = twist_to_wheels_torch(twist, lin_scale=lin_scale, ang_scale=ang_scale)
    if rows is None:
        return wheels
    out = torch.zeros(n, 4, dtype=DTYPE, device=dev)
    out[rows] = wheels
    return out


def wheel_velocities_to_base_twist(
    wheels: Any, *, lin_scale: float = 1.0, ang_scale: float = 1.0
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Wheel velocities (..., 4) [rad/s], order wheel1..wheel4 -> ``(vx, vy, wz)`` of shape (...).

    Exact (least-squares) inverse of :func:`base_twist_to_wheel_velocities` (``mecanum.wheels_to_twist``);
    vx, vy [m/s], wz [rad/s].
    """
    fn = "wheel_velocities_to_base_twist"
    w = _as_float(wheels, _device_of(None, wheels))
    if w.ndim == 0 or w.shape[-1] != 4:
        raise ValueError(f"{fn}: wheels has shape {tuple(w.shape)}; pass shape (4,) or (N, 4) ordered wheel1..wheel4")
    if lin_scale == 0 or ang_scale == 0:
        raise ValueError(f"{fn}: lin_scale/ang_scale must be non-zero to invert; pass the scales used to pack")
    twist = wheels_to_twist_torch(w.reshape(-1, 4), lin_scale=lin_scale, ang_scale=ang_scale)
    vx, vy, wz = twist.reshape(*w.shape[:-1], 3).unbind(-1)
    return vx, vy, wz


# ---------------------------------------------------------------- named joints
def pack_joint_positions(
    joint_names: Sequence[str] | str,
    values: Any,
    *,
    action_joint_names: Sequence[str],
    num_envs: int,
    baseline: Any = None,
    current: Any = None,
    env_indices: Any = None,
    device: Any = None,
) -> torch.Tensor:
    """Absolute named-joint targets [rad] -> float32 (num_envs, len(action_joint_names)).

    ``values``: (len(joint_names),) broadcast to the written rows, or (rows, len(joint_names)) with
    rows = len(env_indices) if given else num_envs. Unnamed joints (and rows not in ``env_indices``)
    keep ``baseline`` ((A,) or (N, A)) if given, else ``current`` ((N, A)), else 0.
    """
    fn = "pack_joint_positions"
    dev = _device_of(device, baseline, current, values)
    names = _names(joint_names, "joint_names", fn)
    act = _names(action_joint_names, "action_joint_names", fn)
    cols = _columns(names, act, fn)
    n = _check_num_envs(num_envs, fn)
    rows = _env_rows(env_indices, n, dev, fn)
    m = n if rows is None else int(rows.shape[0])
    vals = _row_values(values, len(names), m, "values", dev, fn)
    out = _start(baseline, current, n, len(act), dev, fn)
    if not cols:
        return out
    col_t = torch.as_tensor(cols, dtype=torch.long, device=dev)
    row_t = torch.arange(n, device=dev) if rows is None else rows
    out[row_t.unsqueeze(1), col_t.unsqueeze(0)] = vals
    return out


def pack_relative_joint_positions(
    joint_names: Sequence[str] | str,
    deltas: Any,
    *,
    action_joint_names: Sequence[str],
    num_envs: int,
    env_indices: Any = None,
    scale: float = 0.05,
    device: Any = None,
) -> torch.Tensor:
    """Relative named-joint deltas -> float32 (num_envs, A) holding ``scale * delta`` [rad].

    ``deltas`` follows the ``values`` shape rules of :func:`pack_joint_positions`; unnamed joints and
    rows not in ``env_indices`` get 0 delta. ``scale`` is [rad] per unit delta.
    """
    fn = "pack_relative_joint_positions"
    dev = _device_of(device, deltas)
    names = _names(joint_names, "joint_names", fn)
    act = _names(action_joint_names, "action_joint_names", fn)
    cols = _columns(names, act, fn)
    n = _check_num_envs(num_envs, fn)
    rows = _env_rows(env_indices, n, dev, fn)
    m = n if rows is None else int(rows.shape[0])
    vals = _row_values(deltas, len(names), m, "deltas", dev, fn)
    out = torch.zeros(n, len(act), dtype=DTYPE, device=dev)
    if not cols:
        return out
    col_t = torch.as_tensor(cols, dtype=torch.long, device=dev)
    row_t = torch.arange(n, device=dev) if rows is None else rows
    out[row_t.unsqueeze(1), col_t.unsqueeze(0)] = float(scale) * vals
    return out


# ---------------------------------------------------------------- grippers
def gripper_binary(
    open_flags: Any,
    *,
    num_envs: int | None = None,
    env_indices: Any = None,
    baseline: Any = None,
    device: Any = None,
) -> torch.Tensor:
    """Open flags -> gripper master targets [rad]: True -> GRIPPER_OPEN (0.0), False -> GRIPPER_CLOSED (1.2).

    Accepts bool, list, numpy or torch (bool or 0/1). Shapes: scalar -> (1, 1); (R,) -> (R, 1), one gripper over
    R rows; (R, G) -> (R, G), one column per gripper. Like the joint packers, the flags can go to some rows of N:
    ``env_indices`` picks them (R = len(env_indices); a scalar or one row of flags is broadcast) and every other
    row keeps ``baseline`` ((G,) or (N, G) [rad], e.g. the env's current gripper targets; needed with
    ``env_indices``). N is ``num_envs``, else the rows of a (N, G) ``baseline``, else R.
    """
    fn = "gripper_binary"
    dev = _device_of(device, open_flags, baseline)
    flags = _open_flags(open_flags, fn)
    targets = torch.where(
        torch.as_tensor(flags, device=dev),
        torch.tensor(spec.GRIPPER_OPEN, dtype=DTYPE, device=dev),
        torch.tensor(spec.GRIPPER_CLOSED, dtype=DTYPE, device=dev),
    )
    if num_envs is None and env_indices is None and baseline is None:
        return targets
    if env_indices is not None and baseline is None:
        raise ValueError(f"{fn}: env_indices needs baseline, the targets the other rows keep; pass "
                         "baseline=<(G,) or (N, G) current gripper targets>")
    base = None if baseline is None else _as_float(baseline, dev)
    if base is not None and base.ndim not in (1, 2):
        raise ValueError(f"{fn}: baseline has shape {tuple(base.shape)}; pass shape (G,) or (N, G)")
    if num_envs is None:
        num_envs = base.shape[0] if base is not None and base.ndim == 2 else targets.shape[0]
    n = _check_num_envs(num_envs, fn)
    rows = _env_rows(env_indices, n, dev, fn)
    m = n if rows is None else int(rows.shape[0])
    width = targets.shape[1] if base is None else base.shape[-1]
    if targets.shape[0] not in (1, m) or targets.shape[1] not in (1, width):
        raise ValueError(f"{fn}: open_flags has shape {tuple(targets.shape)} for {m} row(s) of {width} gripper(s); "
                         f"pass a bool, ({m},) or ({m}, {width}) flags")
    out = _start(base, None, n, width, dev, fn)
    out[torch.arange(n, device=dev) if rows is None else rows] = targets.expand(m, width)
    return out


def _open_flags(open_flags: Any, fn: str) -> np.ndarray:
    """Validated open flags as a bool (R, G) array."""
    if isinstance(open_flags, torch.Tensor):
        flags = open_flags.detach().cpu().numpy()
    else:
        flags = np.asarray(open_flags)
    if flags.dtype != np.bool_:
        if flags.dtype == object or not np.isin(flags, (0, 1)).all():
            raise ValueError(f"{fn}: open_flags must be booleans (True=open), got {flags.tolist()!r}; pass bool or 0/1")
        flags = flags.astype(bool)
    if flags.ndim > 2:
        raise ValueError(f"{fn}: open_flags has shape {flags.shape}; pass a bool, (N,) or (N, G)")
    return flags.reshape(-1, 1) if flags.ndim < 2 else flags


# ---------------------------------------------------------------- dispatcher
def g1_action(group: str, type: str = "absolute", **kw: Any) -> torch.Tensor:  # noqa: A002 (reference API name)
    """Per-group convenience packer; returns a float32 (N, group width) tensor.

    * ``("base", "velocity")`` -> :func:`base_twist_to_wheel_velocities` (N, 4) [rad/s];
    * ``("legs" | "left_arm" | "right_arm", "absolute" | "relative")`` -> :func:`pack_joint_positions` /
      :func:`pack_relative_joint_positions` with ``action_joint_names`` = that group's joints
      (``joint_names`` defaults to all of them);
    * ``("left_gripper" | "right_gripper", "binary")`` -> :func:`gripper_binary` [rad].
    """
    valid = "; ".join(f"{g}: {'|'.join(ts)}" for g, ts in G1_ACTION_TYPES.items())
    if group not in G1_ACTION_TYPES:
        raise ValueError(f"g1_action: unknown group {group!r}; valid groups and types: {valid}")
    if type not in G1_ACTION_TYPES[group]:
        raise ValueError(
            f"g1_action: type {type!r} not valid for group {group!r}; use {'|'.join(G1_ACTION_TYPES[group])}"
        )
    if type == "velocity":
        return base_twist_to_wheel_velocities(**kw)
    if type == "binary":
        return gripper_binary(**kw)
    if "action_joint_names" in kw:
        raise ValueError(
            f"g1_action: action_joint_names is fixed to group {group!r}; drop it or call the packer directly"
        )
    joints = spec.JOINT_GROUPS[group]
    kw.setdefault("joint_names", joints)
    packer = pack_joint_positions if type == "absolute" else pack_relative_joint_positions
    return packer(action_joint_names=joints, **kw)
