"""Episode loops over a batched env: ``collect`` (record to HDF5 / zarr) and ``evaluate``.

Rows run episodes independently; a row's episode ends when the task terminates or truncates it (the env
resets it inside the step) or when it reaches ``max_steps`` (reset here). ``collect`` copies the episodes that
end in one step to the host together and hands them to a background writer (``envs.saver``). A row whose
physics diverged ends with reason ``diverged`` (the env's divergence guard); ``collect`` never writes such an
episode, nor any episode holding a non-finite value, and both summaries count them (``diverged``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..datasets import DatasetRef, open_writer
from ..datasets.writers import process as writer_process
from ..datasets.writers.background_thread import BackgroundWriter
from ..datasets.writers.interrupts import Interrupted, stop_requests
from ..datasets.zarr.inodes import check_room
from ..task_api.cfg import DIVERGED
from .checks import check_agent, check_collect, option_defaults
from .recorder import EpisodeRecorder, env_args
from .rollout_loop import REASON_MAX_STEPS, StepClock, Timers, run_episodes  # noqa: F401 - Timers, REASON_MAX_STEPS: re-exported
from .saver import EpisodeSaver, WrappedWriter, all_finite  # noqa: F401 - all_finite: re-exported (tests, callers)
from .scenario import capture_scenario

WRITE_MIN_BATCH = 256
"""Episodes the background writer gathers before it writes a batch (or ``WRITE_MAX_WAIT_S`` after the oldest came):
each batch costs a lock, a ``syncfs`` and a commit, and a zarr batch of 32 demos or more is packed into a few
files (below that, ~80 files a PickCube demo); a writer faster than the simulation that took whatever was queued
would write what one step ended, about 4096 / 170 = 24 demos at 4096 rows of ~170-step PickCube episodes. Only
with at least this many rows: fewer (a CPU run) end too few episodes a second to fill a pack, and gathering them
only made the writer's bursts (and the wait for the last batch) longer (bench-collect, 4 rows on the 2-core CPU,
one torch thread: 4.7-5.1 demos/s gathering against 5.3-5.9 writing each as it ends)."""
WRITE_MAX_WAIT_S = 1.0
"""Seconds an ended episode waits at most for its batch to fill (``WRITE_MIN_BATCH``)."""
EVAL_REPORT_KEYS = (
    "task",
    "episodes",
    "successes",
    "success_rate",
    "average_length",
    "termination_reasons",
    "diverged",
    "subtask_signals",
    "phases",
    "phase_targets",
)
"""The evaluation summary fields the CLI, examples and the Prefect evaluate stage report."""


def _overflow_worlds(env) -> int:
    overflow = getattr(getattr(env.solver, "mjw_data", None), "overflow", None)
    return int((overflow.numpy() != 0).sum()) if overflow is not None else 0


def phase_summary(names: list[str], records: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Per phase of a coherent task: episodes that ``reached`` it, that ``passed`` it (went on to the next phase, or
    succeeded in the last), and of those that ended in it unsuccessfully, why (``stalled``: reason -> episodes):
    where the rows of a composed policy stop."""
    out = {}
    for i, name in enumerate(names):
        ended_here = [r for r in records if r["phase"] == name]
        failed = [r for r in ended_here if not r["success"]]
        stalled: dict[str, int] = {}
        for r in failed:
            stalled[r["termination_reason"]] = stalled.get(r["termination_reason"], 0) + 1
        reached = sum(names.index(r["phase"]) >= i for r in records)
        out[name] = {"reached": reached, "passed": reached - len(failed), "stalled": stalled}
    return out


def phase_target_summary(cfg, records: list[dict[str, Any]]) -> dict[str, dict[str, dict[str, int]]]:
    """Per phase kind acting on a per-row target (SortToShelf-All's pick, nav, place: one per object), per target:
    the phases of that kind on it that episodes ``reached`` and ``passed``, summed over the kind's phases (where a
    composed policy stalls, per object); empty for a task without such phases."""
    names = cfg.phase_names
    kind_of = {p.name: p.kind or p.name for p in cfg.phases}
    out: dict[str, dict[str, dict[str, int]]] = {}
    for r in records:
        end = names.index(r["phase"])
        for name, value in r.get("targets", {}).items():
            cell = out.setdefault(kind_of[name], {}).setdefault(value, {"reached": 0, "passed": 0})
            cell["reached"] += 1
            cell["passed"] += int(names.index(name) < end or r["success"])
    return out


def _summary(env, records, vector_steps, wall) -> dict[str, Any]:
    successes = sum(r["success"] for r in records)
    reasons: dict[str, int] = {}
    for r in records:
        reasons[r["termination_reason"]] = reasons.get(r["termination_reason"], 0) + 1
    row_steps = sum(r["length"] for r in records)
    return {
        "task": env.task_id,
        "num_envs": env.num_envs,
        "episodes": len(records),
        "successes": successes,
        "success_rate": successes / max(len(records), 1),
        "episode_lengths": [r["length"] for r in records],
        "average_length": row_steps / max(len(records), 1),
        "reward_totals": [r["reward_total"] for r in records],
        "termination_reasons": reasons,
        "diverged": reasons.get(DIVERGED, 0),
        # per subtask signal: episodes in which it fired (where a failing policy gets stuck)
        "subtask_signals": {name: sum(name in r["signals_reached"] for r in records) for name in env.task.signal_names},
        # per phase (one, "task", for a single-phase task): episodes that reached / passed it, why others stopped
        "phases": phase_summary(env.cfg.phase_names, records),
        # per phase kind and target (a task whose phases act on a per-row target; else empty): reached / passed
        "phase_targets": phase_target_summary(env.cfg, records),
        "vector_steps": vector_steps,
        # worlds whose mujoco_warp overflow bitmask is set (buffer overflow or line-search cap; prints are off)
        "solver_overflow_worlds": _overflow_worlds(env),
        "row_steps": row_steps,
        "wall_time_s": wall,
        "env_steps_per_s": vector_steps * env.num_envs / max(wall, 1e-9),
    }


def collect(
    env,
    *,
    agent,
    episodes: int,
    path,
    max_steps: int = 1000,
    progress: bool = True,
    only_successes: bool = False,
    max_attempts: int | None = None,
    end_when_agent_done: bool = False,
    dataset_task_id: str | None = None,
    operation: str = "collect",
    config: dict | None = None,
    on_step=None,
    save_end_scenario=None,
    max_queued: int | None = None,
    timers: Timers | None = None,
    writer: str = "auto",
):
    """Run ``agent`` and append finished episodes to the dataset at ``path`` (``.hdf5``/``.h5`` robomimic
    layout or ``.zarr`` v3, same logical tree).

    The episodes that end in one step are copied to the host together and written by a background thread
    (``datasets.writers.background_thread``), many per write session, while the simulation goes on; ``collect`` waits
    for it before returning (also on Ctrl-C or an error, so every finished episode is written). An episode is
    durable once written: a run killed (SIGKILL) keeps every episode written before and loses at most the
    batch being written (all of it or none lands) and those queued behind it (at most ``max_queued``, by default
    256 or one per env row, whichever is more, and 1 GiB of arrays; the simulation waits while the queue is full;
    with ``WRITE_MIN_BATCH`` rows or more the writer gathers that many episodes, or waits ``WRITE_MAX_WAIT_S``,
    before it writes a batch).
    A queue that holds one episode per row lets the rows' next episodes run while the writer writes the ones that
    ended together (on a GPU thousands end within a few steps; a queue of 256 held the loop until they were written).

    ``timers`` wrap the loop's ``env.step`` and ``agent.act`` and the writer thread's batch writes (``Timers``; a
    writer process reports its own, ``writer_seconds`` in the summary).

    ``writer``: ``"thread"`` builds each episode's tree here and writes on a thread
    (``datasets.writers.background_thread``);
    ``"process"`` hands each step's ended episodes to a writer process as one block in shared memory
    (``datasets.writers.process``: joined, checked, packed and encoded on another interpreter); ``"auto"`` takes the
    process from ``WRITE_MIN_BATCH`` rows on (where episodes end in bursts of dozens a step), else the thread.

    ``save_end_scenario`` (one env, one episode): write the scene the episode ended in as a scenario YAML
    (``newton_lab.envs.scenario``) that a following component task can start from; the file must not exist.

    By default ``episodes`` episodes are run and all are written. With ``only_successes`` the loop runs
    until ``episodes`` successful ones are written (at most ``max_attempts`` attempts) and failures are
    counted but not written (Mimic generation). Diverged episodes (and any episode holding a non-finite value)
    are never written: they count as failed attempts, under ``diverged`` and ``termination_reasons``.
    Returns a ``DatasetRef`` whose ``metadata`` is the summary (episodes, successes, success_rate, lengths,
    termination reasons, diverged, saved_demo_ids, ...); ``ref["success_rate"]`` reads it.
    """
    task_id = dataset_task_id or env.task_id
    check_collect(env.num_envs, agent=agent, path=path, episodes=episodes, save_end_scenario=save_end_scenario)
    recorder, store = _open_store(env, path, task_id, episodes, max_steps)
    timers = timers or Timers()
    saver = _make_saver(env, store, task_id, recorder, writer, max_queued, timers, only_successes)
    records, steps, wall = _run_saving(
        env,
        path,
        saver,
        timers,
        agent=agent,
        episodes=episodes,
        max_steps=max_steps,
        progress=progress,
        until_successes=only_successes,
        max_attempts=max_attempts,
        end_when_agent_done=end_when_agent_done,
        on_step=on_step,
    )
    summary = _collect_summary(env, records, steps, wall, task_id, path, saver, save_end_scenario)
    return _recorded(
        env, agent, DatasetRef(Path(path), task_id=task_id, metadata=summary), operation, max_steps, config
    )


def _open_store(env, path, task_id: str, episodes: int, max_steps: int):
    """The episode recorder of ``env`` and the dataset at ``path`` opened for appending (a zarr store is first
    checked for inodes enough)."""
    args = env_args(env)
    args["env_name"] = task_id
    recorder = EpisodeRecorder(env, max_steps)
    check_room(path, episodes, recorder.episode(0, 1), batch=min(env.num_envs, episodes))  # zarr: inodes enough?
    store = open_writer(Path(path), task_id=task_id, env_args=args, option_defaults=option_defaults(env.task_id))
    return recorder, store


def _make_saver(env, store, task_id, recorder, writer: str, max_queued, timers: Timers, only_successes: bool):
    """The saver of ``collect``: its background writer (``_make_writer``) behind the recorder, the hand-over timed."""
    writer = _make_writer(store, task_id, recorder, env.num_envs, writer, max_queued, timers)
    saver = EpisodeSaver(writer, recorder, seed=env.seed, only_successes=only_successes)
    saver.fetch, saver.submit = timers.hand_over(saver.fetch), timers.hand_over(saver.submit)
    return saver


def _run_saving(env, path, saver: EpisodeSaver, timers: Timers, **loop):
    """``run_episodes`` with ``saver`` taking the ended episodes; the writer is drained at the end, also on Ctrl-C or
    an error (what finished is written). A stop request (Ctrl-C / SIGTERM) ends the loop between two steps and
    raises ``Interrupted`` once the writer is drained."""
    try:
        with stop_requests() as stop:
            out = run_episodes(env, recorder=saver.recorder, saver=saver, timers=timers, stop=stop, **loop)
    finally:
        timers.drain(saver.close)()
    if stop:
        raise _interrupted(len(saver.saved_ids()), path, stop.signum)
    return out


def _interrupted(kept: int, path, signum) -> Interrupted:
    """The end of a collection stopped by Ctrl-C / SIGTERM: what it kept, where."""
    return Interrupted(
        f"interrupted: {kept} finished episode{'s' * (kept != 1)} of this run kept in {path} (the "
        "episodes in flight were dropped); run again to append more",
        signum,
    )


def _recorded(env, agent, ref: DatasetRef, operation: str, max_steps: int, config: dict | None) -> DatasetRef:
    """``ref`` with the collection's operation record (the env, the agent, the counts) appended to its dataset."""
    summary = ref.metadata
    cfg = {
        "num_envs": env.num_envs,
        "seed": env.seed,
        "randomize": env.task.randomize,
        "max_steps": max_steps,
        "agent": type(agent).__name__,
        "task_options": env.cfg.options,
        **(config or {}),
    }
    keys = ("episodes", "successes", "success_rate", "saved_demo_ids", "attempts", "diverged")
    return ref.record(operation, config=cfg, metadata={k: summary[k] for k in keys})


def _make_writer(
    store, task_id: str, recorder: EpisodeRecorder, num_envs: int, writer: str, max_queued: int | None, timers
):
    """``collect``'s background writer of ``store``: a writer process or a thread (``writer``, resolved by
    ``_writer_kind``), gathering batches as ``WRITE_MIN_BATCH`` and ``WRITE_MAX_WAIT_S`` say, at most ``max_queued``
    episodes queued (default 256 or one per row, whichever is more)."""
    batching = {
        "max_queued": max(256, num_envs) if max_queued is None else max_queued,
        "min_batch": WRITE_MIN_BATCH if num_envs >= WRITE_MIN_BATCH else 1,
        "max_wait_s": WRITE_MAX_WAIT_S,
    }
    if _writer_kind(writer, num_envs) == "process":
        return writer_process.ProcessWriter(store.path, task_id=task_id, layout=recorder.layout, **batching)
    else:
        return BackgroundWriter(store if timers is None else WrappedWriter(store, timers.write), **batching)


def _collect_summary(env, records, steps: int, wall: float, task_id: str, path, saver, save_end_scenario):
    """The evaluation summary of a collection, with what was written where: the saved demo ids, the attempts, the
    writer's batches (and a writer process's own seconds, and the collecting side's in handing bursts to it), the
    scenario the episode ended in when asked."""
    writer = saver.writer
    summary = _summary(env, records, steps, wall)
    summary.update(
        task=task_id,
        path=str(path),
        saved_demo_ids=saver.saved_ids(),
        attempts=len(records),
        writer_batches=writer.batches,
        writer=type(writer).__name__,
    )
    if isinstance(writer, writer_process.ProcessWriter):
        summary["writer_seconds"] = dict(writer.seconds)
        summary["hand_over_seconds"] = dict(writer.hand_over)
    if save_end_scenario is not None:
        summary["saved_end_scenario_path"] = str(capture_scenario(env, 0, terminal=True).save(save_end_scenario))
    return summary


WRITER_KINDS = ("auto", "thread", "process")


def _writer_kind(writer: str, num_envs: int) -> str:
    """``collect``'s ``writer`` resolved to ``"thread"`` or ``"process"``."""
    if writer not in WRITER_KINDS:
        raise ValueError(f"writer {writer!r} is not one of {', '.join(WRITER_KINDS)}")
    if writer == "process" and not writer_process.available():
        raise ValueError("writer 'process' needs os.memfd_create (Linux); use writer 'thread'")
    if writer == "auto":
        return "process" if num_envs >= WRITE_MIN_BATCH and writer_process.available() else "thread"
    return writer


def evaluate(
    env, *, agent, episodes: int, max_steps: int = 1000, progress: bool = True, on_step=None
) -> dict[str, Any]:
    """Run ``agent`` for ``episodes`` episodes; success is latched per episode. ``timing``: the seconds in the env
    step and in the agent's act (``StepClock``)."""
    check_agent(agent)
    clock = StepClock(env.torch_device)
    records, steps, wall = run_episodes(
        env,
        agent=agent,
        episodes=episodes,
        max_steps=max_steps,
        progress=progress,
        on_step=on_step,
        timers=clock.timers(),
        act_for_active_rows=True,
    )
    summary = _summary(env, records, steps, wall)
    summary["success_masks"] = [r["success"] for r in records]
    summary["timing"] = clock.figures(steps)
    return summary
