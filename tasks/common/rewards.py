"""Reward terms shared by the G1 tasks: ``func(ctx, w) -> float``, and the staged dense reward.

Manipulation tasks declare a *staged* dense reward in the style of ManiSkill's PickCube-v1 (reach:
``1 - tanh(5 d)``, grasped bonus, place: ``1 - tanh(5 d)`` while grasped, release / static bonus, success):
an ordered list of ``Stage``s, each with a ``done`` predicate and a ``shaping`` value in [0, 1] that leads
to it. With ``k`` the last stage whose ``done`` holds (-1 if none), stage ``i``'s term is 1 for ``i <= k``,
its shaping for ``i = k + 1`` and 0 after, so the reward climbs one stage at a time and never rewards a later
stage's shaping before the earlier stages are met. Every term has weight ``1 / len(stages)``: the step reward
is in [0, 1] (``DENSE_REWARD_MAX``), 1 exactly when the last stage is done (the task's success condition).

Rewards are evaluated after the step's phase advance and must not change state (no ``held_for``): stages use
stateless versions of the task's predicates.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable

import warp as wp

from newton_lab.kernels.context import TaskContext, base_pose2d, entity_pos, gripper_q, tcp_pos, wrap_angle
from newton_lab.robots.g1 import spec
from newton_lab.task_api.cfg import RewardTermCfg

DENSE_REWARD_MAX = 1.0
"""Upper bound of a staged dense reward (sum of its terms); its lower bound is 0."""
TANH_SCALE = 5.0
"""Distance shaping ``1 - tanh(TANH_SCALE * d)`` for table-top distances [1/m] (ManiSkill's 5)."""
NAV_TANH_SCALE = 1.0
"""Distance shaping scale for base navigation (metres to go) [1/m]."""
POSTURE_TANH_SCALE = 1.0
"""Joint-space shaping ``1 - tanh(POSTURE_TANH_SCALE * |dq|)`` [1/rad]."""
REACH_DONE_DIST = 0.06
"""The reaching stage is done with the TCP this close to the object's centre (the grasp distance) [m]."""
GRIPPER_FULL_CLOSE = wp.constant(float(spec.GRIPPER_CLOSED))
"""Gripper master target when fully closed [rad] (0 = open)."""

vec5 = wp.types.vector(length=5, dtype=float)
vec7 = wp.types.vector(length=7, dtype=float)


@wp.func
def action_rate(ctx: TaskContext, w: int) -> float:
    """Sum of squared action changes since the last step [action units^2]."""
    s = float(0.0)
    for j in range(ctx.actions.shape[1]):
        d = ctx.actions[w, j] - ctx.prev_actions[w, j]
        s += d * d
    return s


# ---------------------------------------------------------------- shaping pieces
@wp.func
def closeness(d: float) -> float:
    """``1 - tanh(5 d)`` for a distance ``d`` [m]: 1 at 0, 0.54 at 10 cm, 0.01 at 50 cm."""
    return 1.0 - wp.tanh(TANH_SCALE * d)


@wp.func
def nav_closeness(d: float) -> float:
    """``1 - tanh(d)`` for a base distance ``d`` [m]: 1 at the goal, 0.24 at 1 m, 0.04 at 2 m."""
    return 1.0 - wp.tanh(NAV_TANH_SCALE * d)


@wp.func
def posture_closeness(d: float) -> float:
    """``1 - tanh(d)`` for a joint-space distance ``d`` [rad]."""
    return 1.0 - wp.tanh(POSTURE_TANH_SCALE * d)


@wp.func
def tcp_distance(ctx: TaskContext, w: int, k: int) -> float:
    """|TCP - centre of entity ``k``| [m]."""
    return wp.length(entity_pos(ctx, w, k) - tcp_pos(ctx, w))


@wp.func
def gripper_openness(ctx: TaskContext, w: int) -> float:
    """1 - gripper / 1.2, clamped to [0, 1]: 1 open, ~0.44 closed on a 5 cm object, 0 fully closed."""
    return 1.0 - wp.clamp(wp.abs(gripper_q(ctx, w)) / GRIPPER_FULL_CLOSE, 0.0, 1.0)


@wp.func
def arm_home_error(ctx: TaskContext, w: int) -> float:
    """Euclidean distance of the controlled arm's 7 joints from ``ctx.arm_home`` [rad]."""
    s = float(0.0)
    for j in range(7):
        d = ctx.joint_q[w * ctx.coords_per_world + ctx.arm_coords[j]] - ctx.arm_home[j]
        s += d * d
    return wp.sqrt(s)


@wp.func
def no_shaping(ctx: TaskContext, w: int) -> float:
    """0: a stage that is either done or not (e.g. grasped)."""
    return 0.0


# ---------------------------------------------------------------- staged dense reward
@dataclass(frozen=True)
class Stage:
    """One stage of a staged dense reward (see the module docstring)."""

    name: str
    """Reward term name."""
    done: Callable
    """``@wp.func (ctx, w) -> bool``: the stage is accomplished (stateless)."""
    shaping: Callable = no_shaping
    """``@wp.func (ctx, w) -> float`` in [0, 1]: progress toward ``done``, counted once the stage before is done."""


def _stage_term(i: int, dones: tuple, shaping: Callable):
    """Stage ``i``'s term: 1 if stage ``i`` or a later one is done, its shaping if stage ``i - 1`` is the last
    done, else 0 (only stages ``i - 1 ..`` are evaluated)."""
    lo, n = max(i - 1, 0), len(dones)

    @wp.func
    def stage_term(ctx: TaskContext, w: int) -> float:
        last = int(-1)
        for j in range(wp.static(lo), wp.static(n)):
            if wp.static(dones[j])(ctx, w):
                last = j
        r = float(0.0)
        if last >= wp.static(i):
            r = 1.0
        elif last == wp.static(i - 1):
            r = wp.clamp(wp.static(shaping)(ctx, w), 0.0, 1.0)
        return r

    return stage_term


def staged_rewards(*stages: Stage) -> dict[str, RewardTermCfg]:
    """The reward terms of ``stages`` (in order), each weighted ``1 / len(stages)``: sum in [0, 1]."""
    names = [s.name for s in stages]
    if not stages or len(set(names)) != len(names):
        raise ValueError(f"staged_rewards needs at least one stage and unique stage names, got {names}")
    dones = tuple(s.done for s in stages)
    weight = DENSE_REWARD_MAX / len(stages)
    return {s.name: RewardTermCfg(func=_stage_term(i, dones, s.shaping), weight=weight) for i, s in enumerate(stages)}


def _both(first: Callable, second: Callable):
    @wp.func
    def both(ctx: TaskContext, w: int) -> bool:
        return first(ctx, w) and second(ctx, w)

    return both


def gated(after: Callable, stages: list[Stage]) -> list[Stage]:
    """``stages`` whose ``done`` also needs ``after`` (``@wp.func (ctx, w) -> bool``): a later subtask's stages
    count only while an earlier subtask's result holds (e.g. cube_3's while cube_2 stays stacked)."""
    return [dataclasses.replace(s, done=_both(after, s.done)) for s in stages]


def _phase_gated(phase: int, func: Callable):
    @wp.func
    def in_phase(ctx: TaskContext, w: int) -> float:
        r = float(0.0)
        if ctx.phase[w] == wp.static(phase):
            r = wp.static(func)(ctx, w)
        return r

    return in_phase


@wp.func
def phase_index(ctx: TaskContext, w: int) -> float:
    """The row's phase index (0, 1, ...): completed phases."""
    return float(ctx.phase[w])


def phased_rewards(phases: list[tuple[str, dict[str, RewardTermCfg]]]) -> dict[str, RewardTermCfg]:
    """A coherent task's dense reward from its phases' dense rewards (each in [0, 1]):
    ``(phase + r_phase) / n_phases``, so it stays in [0, 1], rises across phase boundaries and is 1 when the
    last phase's reward is. ``phases`` are ``(phase name, its reward terms)``; terms become ``<phase>/<term>``."""
    n = len(phases)
    for name, terms in phases:
        total = sum(t.weight for t in terms.values())
        if any(t.weight < 0 for t in terms.values()) or abs(total - DENSE_REWARD_MAX) > 1e-6:
            raise ValueError(f"phase {name!r}: phased_rewards needs a dense reward with weights >= 0 summing to "
                             f"{DENSE_REWARD_MAX}, got {total}; build it with staged_rewards")
    out = {"phase": RewardTermCfg(func=phase_index, weight=DENSE_REWARD_MAX / n)}
    for i, (name, terms) in enumerate(phases):
        for term_name, t in terms.items():
            out[f"{name}/{term_name}"] = RewardTermCfg(func=_phase_gated(i, t.func), weight=t.weight / n)
    return out


# ---------------------------------------------------------------- stage builders shared by the tasks
def reach_stage(obj: int, name: str = "reaching") -> Stage:
    """TCP within ``REACH_DONE_DIST`` [m] of entity ``obj``'s centre; shaping ``1 - tanh(5 |TCP - obj|)``."""
    k = int(obj)

    @wp.func
    def near(ctx: TaskContext, w: int) -> bool:
        return tcp_distance(ctx, w, k) < REACH_DONE_DIST

    @wp.func
    def reach_shaping(ctx: TaskContext, w: int) -> float:
        return closeness(tcp_distance(ctx, w, k))

    return Stage(name, near, reach_shaping)


def pick_to_carry_stages(*, obj: int, grasped: Callable, lift_z: float, at_carry: Callable) -> list[Stage]:
    """Reach, grasp (``grasped``), lift entity ``obj`` to centre height ``lift_z`` [m] (shaping ``1 - tanh(5 dz)``)
    while grasped, bring the arm to ``ctx.arm_home`` (``at_carry``: the task's stateless success predicate;
    shaping ``1 - tanh(|q_arm - home|)``, rad). Shared by the PickToShelf / SortToShelf Pick tasks."""
    k, z_min = int(obj), float(lift_z)

    @wp.func
    def lifted(ctx: TaskContext, w: int) -> bool:
        return grasped(ctx, w) and entity_pos(ctx, w, k)[2] >= z_min

    @wp.func
    def lift_shaping(ctx: TaskContext, w: int) -> float:
        return closeness(wp.max(z_min - entity_pos(ctx, w, k)[2], 0.0))

    @wp.func
    def carry_shaping(ctx: TaskContext, w: int) -> float:
        return posture_closeness(arm_home_error(ctx, w))

    return [reach_stage(k), Stage("grasping", grasped), Stage("lifting", lifted, lift_shaping),
            Stage("carrying", at_carry, carry_shaping)]


def drive_stage(*, goal_xy: tuple[float, float], goal_yaw: float, radius: float, yaw_tol: float) -> Stage:
    """Base within ``radius`` [m] of ``goal_xy`` and within ``yaw_tol`` [rad] of ``goal_yaw``; shaping: the mean of
    ``1 - tanh(d)`` (d [m]) and ``1 - tanh(|yaw error|)`` (rad)."""
    gx, gy, gyaw, r, ytol = float(goal_xy[0]), float(goal_xy[1]), float(goal_yaw), float(radius), float(yaw_tol)

    @wp.func
    def arrived(ctx: TaskContext, w: int) -> bool:
        b = base_pose2d(ctx, w)
        return wp.length(wp.vec2(b[0] - gx, b[1] - gy)) <= r and wp.abs(wrap_angle(b[2] - gyaw)) <= ytol

    @wp.func
    def drive_shaping(ctx: TaskContext, w: int) -> float:
        b = base_pose2d(ctx, w)
        d = wp.length(wp.vec2(b[0] - gx, b[1] - gy))
        return 0.5 * (nav_closeness(d) + posture_closeness(wp.abs(wrap_angle(b[2] - gyaw))))

    return Stage("driving", arrived, drive_shaping)
