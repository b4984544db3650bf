"""The episode loop shared by ``collect`` and ``evaluate`` (``run_episodes``): rows run episodes independently, each
step's ended episodes are recorded (``RowEpisodes``: per-row counters, latched success, signals, phase) and handed
to the saver, and the loop ends after enough episodes (or successes), or between two steps on a stop request."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from tqdm import tqdm

from ..task_api.cfg import DIVERGED
from ..task_api.compose import target_values
from .checks import check_counts

REASON_MAX_STEPS = "max_steps"
LOG_EVERY_S = 30.0
"""Seconds between the plain progress lines of a rollout whose stderr is not a terminal."""


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


class StepClock:
    """Seconds an evaluation spends in ``env.step`` and in ``agent.act``, each call waiting for the device at its end
    (so the work it queued is charged to it, not to the next call that waits): what the policy's inference costs
    against the env step it drives."""

    def __init__(self, device: torch.device) -> None:
        self.device = device
        self.seconds = {"env_step": 0.0, "agent": 0.0}

    def _wrap(self, name: str, fn: Callable) -> Callable:
        def timed(*args, **kwargs):
            t0 = time.perf_counter()
            out = fn(*args, **kwargs)
            if self.device.type == "cuda":
                torch.cuda.synchronize(self.device)
            self.seconds[name] += time.perf_counter() - t0
            return out

        return timed

    def timers(self) -> Timers:
        return Timers(step=lambda fn: self._wrap("env_step", fn), act=lambda fn: self._wrap("agent", fn))

    def figures(self, vector_steps: int) -> dict[str, float]:
        """Seconds in each, and milliseconds per vector step (all rows at once)."""
        steps = max(vector_steps, 1)
        return {
            "env_step_s": self.seconds["env_step"],
            "agent_s": self.seconds["agent"],
            "env_step_ms_per_step": 1e3 * self.seconds["env_step"] / steps,
            "agent_ms_per_step": 1e3 * self.seconds["agent"] / steps,
        }


class RowEpisodes:
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
        self.target_values, self._target_cols = phase_targets(env)
        self.targets = torch.full((n, max(len(env.cfg.phases), 1)), -1, dtype=torch.long, device=dev)
        self._rows = torch.arange(n, device=dev)
        """Per row and phase, the index of the target the row's phase acted on (-1: none, or not reached)."""
        self.records: list[dict[str, Any]] = []
        self.successes = 0
        self.host: dict[str, np.ndarray] = {}

    def active_rows(self) -> np.ndarray:
        """The rows that may still run an episode."""
        return np.nonzero(self.active)[0]

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
        if self._target_cols is not None:  # the obs of a row that ended is its next episode's
            now, rows = info["phase"].long(), self._rows
            value = self.env.obs[:, self._target_cols].argmax(dim=1)
            self.targets[rows, now] = torch.where(ended, self.targets[rows, now], value)

    def snapshot(self) -> None:
        """Host copies of the per-row counters, read by :meth:`record` (call once per step, before it)."""
        self.host = {
            "length": self.step_in_ep.cpu().numpy(),
            "reward": self.reward_total.cpu().numpy(),
            "reached": self.reached.cpu().numpy(),
            "phase": self.phase.cpu().numpy(),
            "targets": self.targets.cpu().numpy(),
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
        if self._target_cols is not None:  # phase -> the target it acted on, for the phases the episode reached
            rec["targets"] = {
                name: self.target_values[i][v]
                for i, (name, v) in enumerate(zip(self.env.cfg.phase_names, h["targets"][row].tolist()))
                if v >= 0 and self.target_values[i]
            }
        if self.quota is None or self.launched < self.quota:
            self.launched += 1
        else:
            self.active[row] = False
        return rec

    def finish(self, row: int, reason: str, saver=None) -> dict[str, Any]:
        """Record ``row``'s ended episode (saved by ``saver`` when given) and count it."""
        rec = self.record(row, reason)
        if saver is not None:
            rec.update(saver.save(row, rec))
        self.records.append(rec)
        self.successes += rec["success"]
        return rec

    def clear(self, finished: np.ndarray) -> None:
        if finished.any():
            idx = torch.as_tensor(np.nonzero(finished)[0], device=self.env.torch_device)
            self.step_in_ep[idx] = 0
            self.reward_total[idx] = 0.0
            self.latched[finished] = False
            self.reached[idx] = False
            self.phase[idx] = 0
            self.targets[idx] = -1


def phase_targets(env) -> tuple[list[tuple[str, ...]], slice | None]:
    """Per phase of a coherent task, the values of its per-row target (``PhaseCfg.target_option``; ``()`` for a
    phase without one), and the observation columns of that target's one-hot (``None`` when no phase has one, or
    the phases' targets are not one option)."""
    phases = env.cfg.phases
    options = {p.target_option for p in phases if p.target_option}
    if len(options) != 1 or next(iter(options)) not in env.task.obs_terms:
        return [() for _ in phases], None
    term = env.task.obs_terms[next(iter(options))]
    return [target_values(p) for p in phases], slice(term.start, term.stop)


class _Progress:
    """The loop's progress: a bar on a terminal, else (a log file, Prefect) a plain line every ``LOG_EVERY_S``."""

    def __init__(self, env, episodes: int, until_successes: bool, progress: bool) -> None:
        self.task_id, self.until_successes = env.task_id, until_successes
        self.bar = tqdm(
            total=episodes,
            desc=f"{env.task_id} {'successes' if until_successes else 'episodes'}",
            unit="ep",
            disable=None if progress else True,  # None: a terminal only
            leave=False,
        )
        self.t0 = self.last_line = time.perf_counter()
        self.lines = progress and self.bar.disable

    def count(self, rec: dict[str, Any]) -> None:
        self.bar.update(1 if not self.until_successes else int(rec["success"]))

    def tick(self, vector_steps: int, eps: RowEpisodes) -> None:
        self.bar.set_postfix(success=f"{eps.successes}/{len(eps.records)}")
        if self.lines and time.perf_counter() - self.last_line >= LOG_EVERY_S:
            self.last_line = time.perf_counter()
            print(
                f"{self.task_id}: step {vector_steps}, {len(eps.records)} episodes ended, {eps.successes} "
                f"successes, {self.last_line - self.t0:.0f} s",
                file=sys.stderr,
                flush=True,
            )

    def close(self) -> None:
        self.bar.close()


def _row_ends(env, agent, eps: RowEpisodes, finished, max_steps: int, end_when_agent_done: bool):
    """Host masks of the rows whose episode ended in the step: ``done`` by the task (terminated or truncated),
    ``cut`` at ``max_steps``, ``agent_done`` by the agent (only with ``end_when_agent_done``)."""
    done = finished.cpu().numpy()
    cut = (eps.step_in_ep >= max_steps).cpu().numpy() & ~done
    agent_done = np.zeros(env.num_envs, dtype=bool)
    if end_when_agent_done:
        agent_done = agent.done(env).cpu().numpy() & ~done & ~cut
    return done, cut, agent_done


def run_episodes(
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
    act_for_active_rows: bool = False,
):
    """Shared loop; returns per-episode records, vector steps and wall time.

    Stops after ``episodes`` finished episodes, or with ``until_successes`` after ``episodes`` successful ones (at
    most ``max_attempts`` episodes). ``end_when_agent_done`` ends a row's episode as soon as the agent reports it has
    nothing more to do (Mimic generation), with reason ``agent.done_reason`` (default ``agent_done``; a teleop
    operator's ``done`` is ``user_exit``).
    ``on_step(reward, info)`` is called after every env step (e.g. a rerun logger); ``saver`` (``EpisodeSaver``, with
    ``recorder``) gets the episodes that end in a step as one batch; ``timers`` wrap ``env.step`` and ``agent.act``.
    ``stop`` (a ``StopRequest``): once set, the loop ends after the step in flight (its ended episodes are handed
    over; the others are dropped). ``act_for_active_rows`` (evaluation): rows with no episode left get no plans.
    """
    check_counts(episodes=episodes, max_steps=max_steps)
    timers = timers or Timers()
    step, act = timers.step(env.step), timers.act(agent.act)
    env.reset()
    agent.reset()
    eps = RowEpisodes(env, episodes=episodes, until_successes=until_successes, max_attempts=max_attempts)
    vector_steps = 0
    shown = _Progress(env, episodes, until_successes, progress)
    try:
        while not eps.enough():
            actions = act(env) if not act_for_active_rows or eps.active.all() else act(env, eps.active_rows())
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
            done, cut, agent_done = _row_ends(env, agent, eps, terminated | truncated, max_steps, end_when_agent_done)
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
                shown.count(eps.finish(row, reason, saver))
                if eps.enough():
                    break
            if saver is not None:
                saver.submit()
            restarted = done | cut | agent_done
            eps.clear(restarted if held is None else restarted | held)
            if stop:
                break
            shown.tick(vector_steps, eps)
    finally:
        shown.close()
    return eps.records, vector_steps, time.perf_counter() - shown.t0
