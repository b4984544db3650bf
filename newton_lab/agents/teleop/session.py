"""The teleop review loop (as on the reference platform): the operator drives one episode, types ``done``, and answers
keep / drop / exit. Each episode is written by ``env.collect`` (so the crash-safety promise holds); drop removes
it again through ``DatasetRef.drop()``; exit drops the episode under review and stops; end of input is exit."""

from __future__ import annotations

import os
import sys
import time
from typing import Any, TextIO

from .agent import TeleopAgent

ANSWERS = {
    "keep": "keep",
    "k": "keep",
    "drop": "drop",
    "d": "drop",
    "exit": "exit",
    "e": "exit",
    "quit": "exit",
    "q": "exit",
}
STATUS_EVERY_S = 0.2
"""Wall time between two status-line updates [s]."""


def read_line(fd: int) -> str | None:
    """One line from ``fd``, read a byte at a time (nothing is read past it); ``None`` at end of input."""
    buf = bytearray()
    while True:
        b = os.read(fd, 1)
        if not b:
            return buf.decode(errors="replace") if buf else None
        if b in (b"\n", b"\r"):
            return buf.decode(errors="replace")
        if b == b"\x04":  # Ctrl-D in cbreak mode
            return None
        buf += b


def review_demo(fd: int, out: TextIO, summary: str = "") -> str:
    """Ask keep / drop / exit until one is given; ``exit`` at end of input."""
    while True:
        out.write(f"\n{summary}keep / drop / exit? ")
        out.flush()
        line = read_line(fd)
        if line is None:
            out.write("(end of input: exit)\n")
            return "exit"
        answer = ANSWERS.get(line.strip().lower())
        if answer is not None:
            return answer
        out.write(f"{line.strip()!r} is not an answer; type keep (k), drop (d) or exit (e)\n")


class StatusLine:
    """An ``on_step`` hook: paces the loop to the control rate (``realtime``) and redraws one status line."""

    def __init__(self, env, agent: TeleopAgent, out: TextIO, *, realtime: bool = True, chain=None):
        self.env, self.agent, self.out, self.realtime, self.chain = env, agent, out, realtime, chain
        self.dt = env.cfg.control_dt
        self.step = 0
        self._next = time.perf_counter()
        self._drawn = 0.0

    def __call__(self, reward, info) -> None:
        if self.chain is not None:
            self.chain(reward, info)
        self.step += 1
        now = time.perf_counter()
        if self.realtime:
            self._next = max(self._next + self.dt, now - self.dt)
            if self._next > now:
                time.sleep(self._next - now)
        if now - self._drawn >= STATUS_EVERY_S:
            self._drawn = now
            self.draw(bool(info["success"][0]))

    def draw(self, success: bool) -> None:
        tcp = self.env.buffers.tcp_pose[0, :3].tolist()
        frame, dev = self.agent.frame, self.agent.device
        gripper = "open" if frame is None or frame.gripper_open.get("left", True) else "closed"
        cmd = getattr(dev, "command", "")
        msg = getattr(dev, "message", "")
        self.out.write(
            f"\rstep {self.step:5d} | tcp {tcp[0]:+.3f} {tcp[1]:+.3f} {tcp[2]:+.3f} m | "
            f"ik err {self.agent.jog_error() * 1e3:4.1f} mm | gripper {gripper:6s} | "
            f"success {'yes' if success else 'no '} | > {cmd:<8s} {msg}\x1b[K"
        )
        self.out.flush()


def teleop_session(
    env,
    agent: TeleopAgent,
    *,
    path,
    max_steps: int = 6000,
    keep: int | None = None,
    realtime: bool = True,
    on_step=None,
    fd: int | None = None,
    out: TextIO | None = None,
) -> dict[str, Any]:
    """Drive episodes into the dataset at ``path`` until the operator answers exit (or ``keep`` demos are kept).
    ``fd`` is where answers are read (default stdin), ``out`` where the key map, status and prompt go."""
    fd = sys.stdin.fileno() if fd is None else fd
    out = sys.stdout if out is None else out
    out.write(agent.device.help() + "\n")
    kept, dropped, episodes = [], [], 0
    status = StatusLine(env, agent, out, realtime=realtime, chain=on_step)
    while keep is None or len(kept) < keep:
        status.step = 0
        ref = env.collect(
            agent=agent,
            episodes=1,
            path=path,
            max_steps=max_steps,
            end_when_agent_done=True,
            progress=False,
            on_step=status,
            operation="teleop",
            config={"device": agent.device.name, "contract": agent.contract},
        )
        agent.device.pause()
        episodes += 1
        m = ref.metadata
        ids = list(m["saved_demo_ids"])
        reason = next(iter(m["termination_reasons"]), "?")
        note = (
            f"episode {episodes}: {m['episode_lengths'][0]} steps, success {'yes' if m['successes'] else 'no'}, "
            f"ended by {reason}. "
        )
        answer = review_demo(fd, out, note)
        if answer == "keep":
            kept += ids
            out.write(f"kept demo {ids}\n")
        else:
            ref.drop()
            dropped += ids
            out.write(f"dropped demo {ids}\n")
        if answer == "exit":
            break
    out.flush()
    return {
        "kept_demo_ids": kept,
        "dropped_demo_ids": dropped,
        "episodes": episodes,
        "path": str(path),
        "latency": agent.latency(env.cfg.control_dt),
    }
