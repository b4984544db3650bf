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
from collections.abc import Callable
from dataclasses import dataclass

import warp as wp
from newton_lab.kernels.context import TaskContext, base_pose2d, entity_pos, gripper_q, tcp_distance, wrap_angle

from newton_lab.task_api.cfg import RewardTermCfg
from newton_lab.task_api.terms import bind, term_factory

from .terminations import all_of, base_at, grasped, holding, lifted, posture_error, posture_vectors

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
def gripper_openness(ctx: TaskContext, w: int) -> float:
    """1 - |gripper - open| / |closed - open| (the robot's range, ``ctx.gripper_open`` .. ``gripper_closed``),
    clamped to [0, 1]: 1 open, ~0.44 closed on a 5 cm object (the G1), 0 fully closed."""
    span = wp.abs(ctx.gripper_closed - ctx.gripper_open)
    return 1.0 - wp.clamp(wp.abs(gripper_q(ctx, w) - ctx.gripper_open) / span, 0.0, 1.0)


@wp.func
def arm_home_error(ctx: TaskContext, w: int) -> float:
    """Euclidean distance of the controlled arm's joints from ``ctx.arm_home`` [rad]."""
    s = float(0.0)
    for j in range(ctx.arm_coords.shape[0]):
        d = ctx.joint_q[w * ctx.coords_per_world + ctx.arm_coords[j]] - ctx.arm_home[j]
        s += d * d
    return wp.sqrt(s)


@wp.func
def no_shaping(ctx: TaskContext, w: int) -> float:
    """0: a stage that is either done or not (e.g. grasped)."""
    return 0.0


@term_factory()
def indicator(*, term: Callable):
    """1 while the predicate ``term`` holds, else 0 (a bonus term)."""

    @wp.func
    def holds(ctx: TaskContext, w: int) -> float:
        return wp.where(term(ctx, w), 1.0, 0.0)

    return holds


# ---------------------------------------------------------------- staged dense reward
@dataclass(frozen=True)
class Stage:
    """One stage of a staged dense reward (see the module docstring)."""

    name: str
    """Reward term name."""
    done: Callable
    """``@wp.func (ctx, w) -> bool`` or a bound generic term: the stage is accomplished (stateless)."""
    shaping: Callable = no_shaping
    """``@wp.func (ctx, w) -> float`` in [0, 1] or a bound generic term: progress toward ``done``, counted once
    the stage before is done."""


@term_factory()
def stage_reward(*, index: int, dones: tuple, shaping: Callable):
    """Stage ``index``'s term: 1 if stage ``index`` or a later one is done, its shaping if stage ``index - 1`` is
    the last done, else 0 (only stages ``index - 1 ..`` are evaluated)."""
    i = int(index)
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
    return {
        s.name: RewardTermCfg(func=stage_reward(index=i, dones=dones, shaping=s.shaping), weight=weight)
        for i, s in enumerate(stages)
    }


def gated(after: Callable, stages: list[Stage]) -> list[Stage]:
    """``stages`` whose ``done`` also needs ``after`` (a predicate term): a later subtask's stages count only
    while an earlier subtask's result holds (e.g. cube_3's while cube_2 stays stacked)."""
    return [dataclasses.replace(s, done=all_of(terms=(after, s.done))) for s in stages]


@term_factory()
def phase_gated(*, phase: int | tuple[int, ...], term: Callable):
    """``term``'s value while the row is in phase ``phase`` (or in any of a tuple of phases), else 0."""
    phases = (int(phase),) if isinstance(phase, int) else tuple(int(p) for p in phase)
    n = len(phases)

    @wp.func
    def in_phase(ctx: TaskContext, w: int) -> float:
        hit = bool(False)
        for i in range(wp.static(n)):
            if ctx.phase[w] == wp.static(phases[i]):
                hit = True
        r = float(0.0)
        if hit:
            r = wp.static(term)(ctx, w)
        return r

    return in_phase


@wp.func
def phase_index(ctx: TaskContext, w: int) -> float:
    """The row's phase index (0, 1, ...): completed phases."""
    return float(ctx.phase[w])


def phased_rewards(phases: list[tuple[str, dict[str, RewardTermCfg]]]) -> dict[str, RewardTermCfg]:
    """A coherent task's dense reward from its phases' dense rewards (each in [0, 1]):
    ``(phase + r_phase) / n_phases``, so it stays in [0, 1], rises across phase boundaries and is 1 when the
    last phase's reward is. ``phases`` are ``(phase name, its reward terms)``; terms become ``<phase>/<term>``.
    Phases given under one name with the same terms (the same dict: SortToShelf-All's four picks, each
    ``("pick", ...)``) share each term, gated on all of them, so the task kernel inlines it once."""
    n = len(phases)
    for name, terms in phases:
        total = sum(t.weight for t in terms.values())
        if any(t.weight < 0 for t in terms.values()) or abs(total - DENSE_REWARD_MAX) > 1e-6:
            raise ValueError(
                f"phase {name!r}: phased_rewards needs a dense reward with weights >= 0 summing to "
                f"{DENSE_REWARD_MAX}, got {total}; build it with staged_rewards"
            )
    groups: dict[str, tuple[dict[str, RewardTermCfg], list[int]]] = {}
    for i, (name, terms) in enumerate(phases):
        if name in groups and groups[name][0] is not terms:
            raise ValueError(f"phases named {name!r} must share one reward dict; name the phases apart")
        groups.setdefault(name, (terms, []))[1].append(i)
    out = {"phase": RewardTermCfg(func=phase_index, weight=DENSE_REWARD_MAX / n)}
    for name, (terms, indices) in groups.items():
        gate = indices[0] if len(indices) == 1 else tuple(indices)
        for term_name, t in terms.items():
            out[f"{name}/{term_name}"] = RewardTermCfg(
                func=phase_gated(phase=gate, term=bind(t.func, t.params)), weight=t.weight / n
            )
    return out


# ---------------------------------------------------------------- stage builders shared by the tasks
@term_factory(entities=("entity",))
def tcp_near(*, entity: int, max_dist: float = REACH_DONE_DIST):
    """TCP within ``max_dist`` [m] of ``entity``'s centre."""
    max_dist = float(max_dist)

    @wp.func
    def tcp_near_entity(ctx: TaskContext, w: int) -> bool:
        return tcp_distance(ctx, w, entity) < max_dist

    return tcp_near_entity


@term_factory(entities=("entity",))
def reach_shaping(*, entity: int):
    """``1 - tanh(5 |TCP - entity|)`` [m -> 0..1]."""

    @wp.func
    def reach_entity_shaping(ctx: TaskContext, w: int) -> float:
        return closeness(tcp_distance(ctx, w, entity))

    return reach_entity_shaping


@term_factory(entities=("entity", "target"))
def place_shaping(*, entity: int, target: int, offset: tuple[float, float, float]):
    """``1 - tanh(5 |entity - (target + offset)|)``: closeness of ``entity`` to its resting pose on ``target``
    (``offset`` from ``target``'s centre, world axes [m])."""
    off = wp.vec3(*(float(v) for v in offset))

    @wp.func
    def place_on_target_shaping(ctx: TaskContext, w: int) -> float:
        return closeness(wp.length(entity_pos(ctx, w, entity) - entity_pos(ctx, w, target) - off))

    return place_on_target_shaping


@term_factory(entities=("entity",))
def point_shaping(*, entity: int, point: tuple[float, float, float]):
    """``1 - tanh(5 |entity - point|)``: closeness of ``entity``'s centre to a world ``point`` [m -> 0..1]."""
    p = wp.vec3(*(float(v) for v in point))

    @wp.func
    def entity_point_shaping(ctx: TaskContext, w: int) -> float:
        return closeness(wp.length(entity_pos(ctx, w, entity) - p))

    return entity_point_shaping


@term_factory(entities=("entity",))
def lift_shaping(*, entity: int, from_z: float, min_z: float):
    """The fraction of the lift done: ``(z - from_z) / (min_z - from_z)`` in [0, 1], z = ``entity``'s centre
    height, ``from_z`` its resting height, ``min_z`` the lift's goal [m]. Linear, not ``1 - tanh(5 dz)``: that
    paid 0.54 of the stage for a cube still on the table and 0.90 at 8 cm of 10, and PPO on LiftCube (4096 envs,
    H200, 700 iterations) ended holding the cube 8 cm up, where the three-stage reward was 0.97 of its maximum."""
    from_z, min_z = float(from_z), float(min_z)
    if min_z <= from_z:
        raise ValueError(f"lift_shaping needs min_z above from_z, got from_z={from_z} m, min_z={min_z} m")
    span = min_z - from_z

    @wp.func
    def lift_entity_shaping(ctx: TaskContext, w: int) -> float:
        return wp.clamp((entity_pos(ctx, w, entity)[2] - from_z) / span, 0.0, 1.0)

    return lift_entity_shaping


@wp.func
def carry_shaping(ctx: TaskContext, w: int) -> float:
    """``1 - tanh(|q_arm - arm_home|)`` [rad -> 0..1]."""
    return posture_closeness(arm_home_error(ctx, w))


@term_factory()
def posture_shaping(*, arm: tuple[float, ...], legs: tuple[float, ...] | None = None):
    """``1 - tanh(|q - posture|)`` over the controlled arm and, when given, the lift joints [rad -> 0..1]."""
    arm_q, legs_q, check_legs = posture_vectors(arm, legs)

    @wp.func
    def to_posture_shaping(ctx: TaskContext, w: int) -> float:
        return posture_closeness(posture_error(ctx, w, legs_q, arm_q, check_legs)[0])

    return to_posture_shaping


def reach_stage(entity: str, name: str = "reaching") -> Stage:
    """TCP within ``REACH_DONE_DIST`` [m] of ``entity``'s centre; shaping ``1 - tanh(5 |TCP - entity|)``."""
    return Stage(name, tcp_near(entity=entity), reach_shaping(entity=entity))


def pick_to_carry_stages(*, entity: str, rest_z: float, lift_z: float, at_carry: Callable) -> list[Stage]:
    """Reach, grasp (``holding``: the fingers closed on something), lift ``entity`` from its resting centre height
    ``rest_z`` to ``lift_z`` [m] (shaping: the fraction of that lift done) while grasped, bring the arm to
    ``ctx.arm_home`` (``at_carry``: the task's stateless success predicate; shaping ``1 - tanh(|q_arm - home|)``,
    rad). Shared by the PickToShelf / SortToShelf Pick tasks."""
    lifted_and_grasped = all_of(terms=(grasped(entity=entity), lifted(entity=entity, min_z=lift_z)))
    return [
        reach_stage(entity),
        Stage("grasping", holding(entity=entity)),
        Stage("lifting", lifted_and_grasped, lift_shaping(entity=entity, from_z=rest_z, min_z=lift_z)),
        Stage("carrying", at_carry, carry_shaping),
    ]


@term_factory()
def drive_shaping(*, goal_xy: tuple[float, float], goal_yaw: float):
    """The mean of ``1 - tanh(d)`` (d: base distance to ``goal_xy`` [m]) and ``1 - tanh(|yaw error|)`` [rad]."""
    gx, gy = (float(v) for v in goal_xy)
    gyaw = float(goal_yaw)

    @wp.func
    def drive_to_goal_shaping(ctx: TaskContext, w: int) -> float:
        b = base_pose2d(ctx, w)
        d = wp.length(wp.vec2(b[0] - gx, b[1] - gy))
        return 0.5 * (nav_closeness(d) + posture_closeness(wp.abs(wrap_angle(b[2] - gyaw))))

    return drive_to_goal_shaping


def drive_stage(*, goal_xy: tuple[float, float], goal_yaw: float, radius: float, yaw_tol: float) -> Stage:
    """Base within ``radius`` [m] of ``goal_xy`` and within ``yaw_tol`` [rad] of ``goal_yaw``; shaping: the mean of
    ``1 - tanh(d)`` (d [m]) and ``1 - tanh(|yaw error|)`` (rad)."""
    return Stage(
        "driving",
        base_at(goal_xy=goal_xy, radius=radius, goal_yaw=goal_yaw, yaw_tol=yaw_tol),
        drive_shaping(goal_xy=goal_xy, goal_yaw=goal_yaw),
    )
