"""A ``bench_collect`` result in a few lines for the terminal."""

from __future__ import annotations

from typing import Any

from ..records import stage_seconds


def summary(out: dict[str, Any]) -> str:
    """``bench_collect``'s result in a few lines: demos/s and per GPU-hour, the three stages in seconds and per vector
    step, the rest of the loop, whether physics bounds the run (agent + writer per step <= physics per step) and the
    step's share of the wall time."""
    steps = max(out.get("vector_steps") or 1, 1)
    stage = {name: out[f"{name}_s"] for name in ("physics", "agent", "writer")}
    lines = [
        f"{out['task']} on {out['device_name']}, {out['num_envs']} envs, {out['format']}: "
        f"{out['successful_demos']} demos in {out['wall_s']:.1f} s = {out['demos_per_s']:.0f} demos/s = "
        f"{out['demos_per_hour'] / 1e6:.2f} M demos per GPU-hour",
        f"stages over {steps} vector steps: "
        + ", ".join(f"{name} {s:.2f} s ({1e3 * s / steps:.2f} ms/step)" for name, s in stage.items())
        + (
            f"; writer files {out['writer_files_s']:.2f} s, sync {out['writer_sync_s']:.2f} s"
            if "writer_files_s" in out
            else ""
        ),
        f"loop besides physics and agent {out['loop_s']:.2f} s: hand-over {out['hand_over_s']:.2f} s"
        + (
            f" (into the writer's ring {out['hand_over_copy_s']:.2f} s, waiting for its room "
            f"{out['hand_over_ring_wait_s']:.2f} s)"
            if "hand_over_copy_s" in out
            else ""
        )
        + (
            f"; the writer process copied the bursts' low-dim arrays out of its ring {out['writer_copy_out_s']:.2f} s "
            f"and was blocked on its full write queue {out['writer_queue_wait_s']:.2f} s"
            if "writer_copy_out_s" in out
            else ""
        )
        + ", "
        f"drain after the last step {out['drain_s']:.2f} s, render and frames {out.get('record_s', 0):.2f} s; "
        f"{out['bytes_per_demo'] / 1e3:.1f} KB and "
        f"{out['inodes_per_demo']:.2f} files per demo, {out['writer_batches']} writer batches "
        f"({out.get('writer') or 'BackgroundWriter'})",
        f"physics-bound (agent + writer <= physics per step): {'yes' if out['physics_bound'] else 'no'} "
        f"({1e3 * (stage['agent'] + stage['writer']) / steps:.2f} vs {1e3 * stage['physics'] / steps:.2f} "
        f"ms/step; the step is {100 * out['physics_share']:.0f} % of the wall); largest stage: {_largest(out)}",
    ]
    return "\n".join(lines)


def _largest(out: dict[str, Any]) -> str:
    """The largest of :func:`stage_seconds`, then the others, in seconds."""
    ranked = sorted(stage_seconds(out).items(), key=lambda kv: -kv[1])
    return f"{ranked[0][0]} {ranked[0][1]:.2f} s (" + ", ".join(f"{k} {v:.2f} s" for k, v in ranked[1:]) + ")"
