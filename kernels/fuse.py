"""Fuse a task's declared terms into single Warp kernels.

A task declares its logic as ``@wp.func`` terms (see ``newton_lab.task_api.cfg``); this module turns them
into four kernels per task id, each launched once per env step / reset (the signal kernel twice):

* ``task_step``: phase advance, latched success, failure terminations, time-out, reward, and the divergence
  guard: it takes ``divergence = (max body distance [m], linear speed [m/s], angular speed [rad/s])``
  (``TaskCfg.divergence_bounds``); a row whose state breaks them or is non-finite (``context.row_diverged``)
  terminates with ``REASON_DIVERGED`` (over any other reason), no success and zero reward, and is reset
  like any finished row;
* ``observe``: every observation term written into one (num_envs, obs_dim) buffer;
* ``step_signals``: the stateless subtask signals as 0 / 1, on the state the step reached and again on the
  observed (post-reset) state, so a recorded frame's signals describe its observation;
* ``reset``: masked reset of the selected rows to their defaults, then the task's reset events
  (seeded per row and episode).

The term lists are unrolled at code-generation time with ``wp.static``, so there is no Python loop and
no per-term launch at run time.
"""

from __future__ import annotations

import warp as wp

from .context import TaskContext, row_diverged

# Termination reason codes the task kernel writes; ``TaskCfg.termination_reasons`` names them in this order
# (``BUILTIN_TERMINATION_REASONS``, then the task's failure terms).
REASON_NONE = 0
REASON_SUCCESS = 1
REASON_TIME_OUT = 2
REASON_DIVERGED = 3
"""The row's body state went non-finite or absurd (``row_diverged``); wins over every other reason."""
FIRST_FAILURE_REASON = 4


def _phase_passed(phase_fns: tuple):
    """``func(ctx, w, phase) -> bool``: the success predicate of ``phase`` (one per phase in ``phase_fns``).

    A predicate several phases share (SortToShelf-All runs its four kinds' predicates in 15 phases) is inlined
    once: the row's phase picks its slot among the distinct ones. Inlining it per phase made SortToShelf-All's
    kernel a 570 kB source that NVRTC compiled for 7 minutes."""
    distinct: list = []
    for f in phase_fns:
        if not any(f is g for g in distinct):
            distinct.append(f)
    slots = tuple(next(i for i, g in enumerate(distinct) if g is f) for f in phase_fns)
    fns, n_phase, n_distinct = tuple(distinct), len(phase_fns), len(distinct)

    @wp.func
    def phase_passed(ctx: TaskContext, w: int, ph: int) -> bool:
        slot = int(-1)
        for p in range(wp.static(n_phase)):
            if ph == p:
                slot = wp.static(slots[p])
        passed = bool(False)
        for d in range(wp.static(n_distinct)):
            if slot == d:
                passed = wp.static(fns[d])(ctx, w)
        return passed

    return phase_passed


def build_task_kernel(*, phase_success, terminations, rewards, terminate_on_success=True):
    """Return the fused per-step task kernel.

    Args:
        phase_success: one ``func(ctx, w) -> bool`` per phase; a phase's success advances that row to
            the next phase, the last phase's success is episode success.
        terminations: ``(func(ctx, w) -> bool, phase)`` failure terms, evaluated while the row is in
            ``phase`` (``-1``: every phase); term ``i`` reports reason ``FIRST_FAILURE_REASON + i``.
        rewards: ``(func(ctx, w) -> float, weight)`` pairs, summed.
        terminate_on_success: end the episode when the last phase succeeds.
    """
    phase_fns, end_on_success = tuple(phase_success), bool(terminate_on_success)
    phase_passed = _phase_passed(phase_fns)
    term_fns, term_phase = tuple(f for f, _ in terminations), tuple(int(p) for _, p in terminations)
    reward_fns, reward_w = tuple(f for f, _ in rewards), tuple(float(w) for _, w in rewards)
    n_phase, n_term, n_reward = len(phase_fns), len(term_fns), len(reward_fns)

    @wp.kernel(module="unique")
    def task_step(
        ctx: TaskContext,
        max_episode_steps: int,
        divergence: wp.vec3,
        reward: wp.array(dtype=float),
        terminated: wp.array(dtype=bool),
        truncated: wp.array(dtype=bool),
        done: wp.array(dtype=bool),
        success: wp.array(dtype=bool),
        success_latched: wp.array(dtype=bool),
        reason: wp.array(dtype=int),
        episode_length: wp.array(dtype=int),
    ):
        w = wp.tid()
        step = ctx.episode_step[w] + 1
        ctx.episode_step[w] = step
        ph = ctx.phase[w]
        succ = bool(False)
        if wp.static(phase_passed)(ctx, w, ph):
            if ph == wp.static(n_phase - 1):
                succ = True
            else:
                ctx.phase[w] = ph + 1
                for j in range(ctx.hold.shape[1]):  # hold counters restart in the new phase
                    ctx.hold[w, j] = 0
        diverged = row_diverged(ctx, w, divergence[0], divergence[1], divergence[2])
        succ = succ and not diverged  # diverged wins over success
        if succ:
            success_latched[w] = True
        code = int(REASON_NONE)
        for k in range(wp.static(n_term)):
            if wp.static(term_phase[k]) < 0 or ph == wp.static(term_phase[k]):
                if wp.static(term_fns[k])(ctx, w):
                    if code == REASON_NONE:
                        code = FIRST_FAILURE_REASON + k
        term = code != REASON_NONE
        if succ and wp.static(end_on_success):
            term = True
            code = REASON_SUCCESS
        term = term or diverged
        code = wp.where(diverged, REASON_DIVERGED, code)
        trunc = bool(False)
        if not term and step >= max_episode_steps:
            trunc = True
            code = REASON_TIME_OUT
        r = float(0.0)
        for k in range(wp.static(n_reward)):
            r += wp.static(reward_w[k]) * wp.static(reward_fns[k])(ctx, w)
        for j in range(ctx.actions.shape[1]):
            ctx.prev_actions[w, j] = ctx.actions[w, j]
        reward[w] = wp.where(diverged, 0.0, r)
        terminated[w] = term
        truncated[w] = trunc
        done[w] = term or trunc
        success[w] = succ
        reason[w] = code
        episode_length[w] = step

    return task_step


def build_observation_kernel(terms):
    """Return the fused observation kernel.

    ``terms`` are ``(func(ctx, w, out, col), col)`` pairs writing columns ``col..`` of row ``w``.
    """
    fns = tuple(f for f, _ in terms)
    cols = tuple(int(c) for _, c in terms)
    n = len(fns)

    @wp.kernel(module="unique")
    def observe(ctx: TaskContext, out: wp.array2d(dtype=float)):
        w = wp.tid()
        for k in range(wp.static(n)):
            wp.static(fns[k])(ctx, w, out, wp.static(cols[k]))

    return observe


def build_signal_kernel(signals):
    """Return a kernel writing the stateless subtask ``signals`` (``func(ctx, w) -> bool``, e.g. grasped)
    as 0 / 1 per row. The env launches it twice per step: on the state the step reached (before automatic
    resets, so a signal that holds only at the terminal step is seen) and on the observed state."""
    signal_fns = tuple(signals)
    n_signal = len(signal_fns)

    @wp.kernel(module="unique")
    def step_signals(ctx: TaskContext, signal_out: wp.array2d(dtype=float)):
        w = wp.tid()
        for k in range(wp.static(n_signal)):
            signal_out[w, k] = wp.where(wp.static(signal_fns[k])(ctx, w), 1.0, 0.0)

    return step_signals


def build_reset_kernel(events):
    """Return the fused masked reset kernel.

    ``events`` are ``func(ctx, w, seed, stream, randomize)`` reset events; each gets its own random
    stream derived from (seed, row, episode counter, event index), so a seed reproduces every episode.
    """
    fns = tuple(events)
    n = len(fns)

    @wp.kernel(module="unique")
    def reset(
        ctx: TaskContext,
        mask: wp.array(dtype=bool),
        default_q: wp.array(dtype=float),
        default_target_q: wp.array(dtype=float),
        seed: int,
        randomize: int,
        episode_count: wp.array(dtype=int),
        success_latched: wp.array(dtype=bool),
    ):
        w = wp.tid()
        if not mask[w]:
            return
        cpw = ctx.coords_per_world
        dpw = ctx.dofs_per_world
        for i in range(cpw):
            ctx.joint_q[w * cpw + i] = default_q[i]
            ctx.joint_target_q[w * cpw + i] = default_target_q[i]
        for i in range(dpw):
            ctx.joint_qd[w * dpw + i] = 0.0
            ctx.joint_target_qd[w * dpw + i] = 0.0
        for j in range(ctx.actions.shape[1]):
            ctx.prev_actions[w, j] = 0.0
        for j in range(ctx.hold.shape[1]):
            ctx.hold[w, j] = 0
        for j in range(ctx.command.shape[1]):
            ctx.command[w, j] = 0.0
        ctx.episode_step[w] = 0
        ctx.phase[w] = 0
        success_latched[w] = False
        count = episode_count[w] + 1
        episode_count[w] = count
        stream = (w * 1000003 + count) * 16
        for k in range(wp.static(n)):
            wp.static(fns[k])(ctx, w, seed, stream + k, randomize != 0)

    return reset


@wp.kernel
def keep_terminal_coords(
    done: wp.array(dtype=bool), joint_q: wp.array(dtype=float), terminal_q: wp.array2d(dtype=float)
):
    """Copy the finished rows' coordinates before their reset (scenario capture, final observations)."""
    w, i = wp.tid()
    if done[w]:
        terminal_q[w, i] = joint_q[w * terminal_q.shape[1] + i]


@wp.kernel
def world_to_articulation_mask(
    world_mask: wp.array(dtype=bool), articulation_world: wp.array(dtype=int), articulation_mask: wp.array(dtype=bool)
):
    """Select the articulations of the masked worlds (for a masked forward-kinematics pass)."""
    a = wp.tid()
    aw = articulation_world[a]
    articulation_mask[a] = aw >= 0 and world_mask[aw]


@wp.kernel
def clear_solver_warmstart(
    world_mask: wp.array(dtype=bool),
    qacc_warmstart: wp.array2d(dtype=float),
    qacc: wp.array2d(dtype=float),
    qvel: wp.array2d(dtype=float),
):
    """Zero the solver's per-world accelerations and velocities of reset worlds, launched over (worlds, nv).

    A stale warm start from the previous episode makes the first step after a reset converge badly (stacked
    cubes sink into each other), and a diverged world leaves NaN in them that must not reach its next episode
    (``qpos`` / ``qvel`` are pushed from the Newton state before every solver step; the rest of MuJoCo's data
    is recomputed from those)."""
    w, i = wp.tid()
    if world_mask[w]:
        qacc_warmstart[w, i] = 0.0
        qacc[w, i] = 0.0
        qvel[w, i] = 0.0
