"""Episode loops over a batched env: ``collect`` (record to HDF5 / zarr) and ``evaluate``.

Rows run episodes independently; a row's episode ends when the task terminates or truncates it (the env
resets it inside the step) or when it reaches ``max_steps`` (reset here). ``collect`` copies the episodes that
end in one step to the host together and hands them to a background writer (``envs.saver``). A row whose
physics diverged ends with reason ``diverged`` (the env's divergence guard); ``collect`` never writes such an
episode, nor any episode holding a non-finite value, and both summaries count them (``diverged``).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm import tqdm

from ..datasets import DatasetRef, open_writer
from ..datasets.writers import process as writer_process
from ..datasets.writers.background_thread import BackgroundWriter
from ..datasets.writers.interrupts import Interrupted, stop_requests
from ..datasets.zarr.inodes import check_room
from ..task_api.cfg import DIVERGED
from .checks import check_agent, check_collect, check_counts, option_defaults
from .recorder import EpisodeRecorder, env_args
from .saver import EpisodeSaver, WrappedWriter, all_finite  # noqa: F401 - all_finite: re-exported (tests, callers)
from .scenario import capture_scenario

REASON_MAX_STEPS = "max_steps"
LOG_EVERY_S = 30.0
"""Seconds between the plain progress lines of a rollout whose stderr is not a terminal."""
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
)
"""The evaluation summary fields the CLI, examples and the Prefect evaluate stage report."""


def _same(fn: Callable) -> Callable:
    return fn


@dataclass(frozen=True)
class Timers:
    """Wrappers a rollout puts around its calls, to time them (``newton_lab.bench``'s collection split): each is
    given the callable and returns the one to call in its place."""

    step: Callable[[Callable], Callable] = _same
    """Wraps ``env.step``."""
    act: Callable[[Callable], Callable] = _same
    """Wraps ``agent.act``."""
    write: Callable[[Callable], Callable] = _same
    """Wraps the dataset writer's batch write (``EpisodeWriter.append_prepared``, called on the writer's thread)."""
    hand_over: Callable[[Callable], Callable] = _same
    """Wraps the loop's hand-over of ended episodes (``EpisodeSaver.fetch``: their gather and finite check on the
    device; ``EpisodeSaver.submit``: the copy off the device, the trees for a writer thread, and the queueing, waiting
    while the writer's queue is full)."""
    drain: Callable[[Callable], Callable] = _same
    """Wraps the wait for the writer after the loop (``EpisodeSaver.close``)."""


class _Episodes:
    """Per-row bookkeeping of the loop: step counts, returns, latched success and subtask signals (on the
    device until an episode ends), finished records, and which rows may still start an episode."""

    def __init__(self, env, *, episodes: int, until_successes: bool, max_attempts: int | None):
        n, dev = env.num_envs, env.torch_device
        self.env, self.episodes, self.until_successes, self.max_attempts = env, episodes, until_successes, max_attempts
        self.quota = max_attempts if until_successes and max_attempts else (None if until_successes else episodes)
        self.active = np.arange(n) < (self.quota if self.quota is not None else n)
        self.launched = int(self.active.sum())
        self.step_in_ep = torch.zeros(n, dtype=torch.long, device=dev)
        self.reward_total = torch.zeros(n, device=dev)
        self.latched = np.zeros(n, dtype=bool)
        self.reached = torch.zeros((n, len(env.task.signal_names)), dtype=torch.bool, device=dev)
        self.phase = torch.zeros(n, dtype=torch.long, device=dev)
        """The furthest phase each row's episode has reached (a coherent task's rows reset to phase 0)."""
        self.records: list[dict[str, Any]] = []
        self.successes = 0
        self.host: dict[str, np.ndarray] = {}

    def enough(self) -> bool:
        if self.until_successes:
            return self.successes >= self.episodes or (
                self.max_attempts is not None and len(self.records) >= self.max_attempts
            )
        return len(self.records) >= self.episodes

    def add_step(self, reward, info, ended) -> None:
        """Count the step; ``ended`` (rows whose episode ended in it) keep the phase they had reached: their
        ``info["phase"]`` is already the next episode's."""
        self.step_in_ep += 1
        self.reward_total += reward
        self.latched |= info["success"].cpu().numpy()
        self.reached |= info["step_signals"] > 0.5
        self.phase = torch.where(ended, self.phase, torch.maximum(self.phase, info["phase"].long()))

    def snapshot(self) -> None:
        """Host copies of the per-row counters, read by :meth:`record` (call once per step, before it)."""
        self.host = {
            "length": self.step_in_ep.cpu().numpy(),
            "reward": self.reward_total.cpu().numpy(),
            "reached": self.reached.cpu().numpy(),
            "phase": self.phase.cpu().numpy(),
        }

    def record(self, row: int, reason: str) -> dict[str, Any]:
        """The finished episode of ``row`` (from the step's :meth:`snapshot`); frees or retires the row."""
        h = self.host
        rec = {
            "env_index": int(row),
            "length": int(h["length"][row]),
            "success": bool(self.latched[row]) and reason != DIVERGED,
            "reward_total": float(h["reward"][row]),
            "termination_reason": reason,
            "signals_reached": [
                name for name, hit in zip(self.env.task.signal_names, h["reached"][row].tolist()) if hit
            ],
            "phase": self.env.cfg.phase_names[int(h["phase"][row])],
        }
        if self.quota is None or self.launched < self.quota:
            self.launched += 1
        else:
            self.active[row] = False
        return rec

    def clear(self, finished: np.ndarray) -> None:
        if finished.any():
            idx = torch.as_tensor(np.nonzero(finished)[0], device=self.env.torch_device)
            self.step_in_ep[idx] = 0
            self.reward_total[idx] = 0.0
            self.latched[finished] = False
            self.reached[idx] = False
            self.phase[idx] = 0


def _run(
    env,
    *,
    agent,
    episodes: int,
    max_steps: int,
    progress: bool,
    recorder=None,
    saver=None,
    until_successes: bool = False,
    max_attempts: int | None = None,
    end_when_agent_done: bool = False,
    on_step=None,
    timers: Timers | None = None,
    stop=None,
):
    """Shared loop; returns per-episode records, vector steps and wall time.

    Stops after ``episodes`` finished episodes, or with ``until_successes`` after ``episodes`` successful
    ones (at most ``max_attempts`` episodes). ``end_when_agent_done`` ends a row's episode as soon as the
    agent reports it has nothing more to do (Mimic generation), with reason ``agent.done_reason`` (default
    ``agent_done``; a teleop operator's ``done`` is ``user_exit``).
    ``on_step(reward, info)`` is called after every env step (e.g. a rerun logger). ``saver``
    (``envs.saver.EpisodeSaver``, with ``recorder``) gets the episodes that end in a step as one batch.
    ``timers`` wrap ``env.step`` and ``agent.act`` (see ``Timers``). ``stop`` (a ``writers.interrupts.StopRequest``):
    once set, the loop ends after the step in flight (its ended episodes are handed over; the others are dropped).
    """
    check_counts(episodes=episodes, max_steps=max_steps)
    n = env.num_envs
    timers = timers or Timers()
    step, act = timers.step(env.step), timers.act(agent.act)
    env.reset()
    agent.reset()
    eps = _Episodes(env, episodes=episodes, until_successes=until_successes, max_attempts=max_attempts)
    vector_steps = 0
    bar = tqdm(
        total=episodes,
        desc=f"{env.task_id} {'successes' if until_successes else 'episodes'}",
        unit="ep",
        disable=None if progress else True,
        leave=False,
    )  # None: a terminal only
    t0 = time.perf_counter()
    lines, last_line = progress and bar.disable, t0  # not a terminal (a log, Prefect): a line every LOG_EVERY_S
    try:
        while not eps.enough():
            actions = act(env)
            held = agent.holding()  # rows waiting for a plan (PlannerAgent): their episode starts later
            if recorder is not None:
                recorder.record(eps.step_in_ep, actions)
            _, reward, terminated, truncated, info = step(actions)
            vector_steps += 1
            if recorder is not None:
                recorder.record_outcome(eps.step_in_ep, reward)
            if on_step is not None:
                on_step(reward, info)
            eps.add_step(reward, info, terminated | truncated)
            done = (terminated | truncated).cpu().numpy()
            cut = (eps.step_in_ep >= max_steps).cpu().numpy() & ~done
            agent_done = np.zeros(n, dtype=bool)
            if end_when_agent_done:
                agent_done = agent.done(env).cpu().numpy() & ~done & ~cut
            ended = np.nonzero((done | cut | agent_done) & eps.active)[0]
            reasons = info["termination_reason"].cpu().numpy()
            if (cut | agent_done).any():
                env.reset(np.nonzero(cut | agent_done)[0])
            if len(ended):
                eps.snapshot()  # one device->host copy of the per-row counters
            if saver is not None and len(ended):
                keep = ended[eps.latched[ended]] if until_successes else ended
                saver.fetch(keep, eps.host["length"][keep])
            for row in ended:
                reason = (
                    REASON_MAX_STEPS
                    if cut[row]
                    else agent.done_reason
                    if agent_done[row]
                    else env.task.termination_reasons[reasons[row]]
                )
                rec = eps.record(row, reason)
                if saver is not None:
                    rec.update(saver.save(row, rec))
                eps.records.append(rec)
                eps.successes += rec["success"]
                bar.update(1 if not until_successes else int(rec["success"]))
                bar.set_postfix(success=f"{eps.successes}/{len(eps.records)}")
                if eps.enough():
                    break
            if saver is not None:
                saver.submit()
            restarted = done | cut | agent_done
            eps.clear(restarted if held is None else restarted | held)
            if stop:
                break
            if lines and time.perf_counter() - last_line >= LOG_EVERY_S:
                last_line = time.perf_counter()
                print(
                    f"{env.task_id}: step {vector_steps}, {len(eps.records)} episodes ended, {eps.successes} "
                    f"successes, {last_line - t0:.0f} s",
                    file=sys.stderr,
                    flush=True,
                )
    finally:
        bar.close()
    return eps.records, vector_steps, time.perf_counter() - t0


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
    args = env_args(env)
    args["env_name"] = task_id
    recorder = EpisodeRecorder(env, max_steps)
    check_room(path, episodes, recorder.episode(0, 1), batch=min(env.num_envs, episodes))  # zarr: inodes enough?
    store = open_writer(Path(path), task_id=task_id, env_args=args, option_defaults=option_defaults(env.task_id))
    batching = {
        "max_queued": max(256, env.num_envs) if max_queued is None else max_queued,
        "min_batch": WRITE_MIN_BATCH if env.num_envs >= WRITE_MIN_BATCH else 1,
        "max_wait_s": WRITE_MAX_WAIT_S,
    }
    if _writer_kind(writer, env.num_envs) == "process":
        writer = writer_process.ProcessWriter(store.path, task_id=task_id, layout=recorder.layout, **batching)
    else:
        writer = BackgroundWriter(store if timers is None else WrappedWriter(store, timers.write), **batching)
    saver = EpisodeSaver(writer, recorder, seed=env.seed, only_successes=only_successes)
    timers = timers or Timers()
    saver.fetch, saver.submit = timers.hand_over(saver.fetch), timers.hand_over(saver.submit)
    try:
        with stop_requests() as stop:  # Ctrl-C / SIGTERM: the loop ends between two steps
            records, steps, wall = _run(
                env,
                agent=agent,
                episodes=episodes,
                max_steps=max_steps,
                progress=progress,
                recorder=saver.recorder,
                saver=saver,
                until_successes=only_successes,
                max_attempts=max_attempts,
                end_when_agent_done=end_when_agent_done,
                on_step=on_step,
                timers=timers,
                stop=stop,
            )
    finally:
        timers.drain(saver.close)()  # waits for the writer: what finished is written, also on Ctrl-C or an error
    if stop:
        kept = len(saver.saved_ids())
        raise Interrupted(
            f"interrupted: {kept} finished episode{'s' * (kept != 1)} of this run kept in {path} (the "
            "episodes in flight were dropped); run again to append more",
            stop.signum,
        )
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
    if save_end_scenario is not None:
        summary["saved_end_scenario_path"] = str(capture_scenario(env, 0, terminal=True).save(save_end_scenario))
    ref = DatasetRef(Path(path), task_id=task_id, metadata=summary)
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
    """Run ``agent`` for ``episodes`` episodes; success is latched per episode."""
    check_agent(agent)
    records, steps, wall = _run(
        env, agent=agent, episodes=episodes, max_steps=max_steps, progress=progress, on_step=on_step
    )
    summary = _summary(env, records, steps, wall)
    summary["success_masks"] = [r["success"] for r in records]
    return summary
