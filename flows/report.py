"""The lines ``newton-lab pipeline`` (``make demo``) ends with: what each stage achieved, and where to look."""

from __future__ import annotations

import os
import shlex
import sys
from pathlib import Path
from typing import Any

PREFECT_UI_URL = "http://127.0.0.1:4200"


def _pct(value: Any) -> str:
    return f"{value:.0%}" if isinstance(value, (int, float)) else "n/a"


def recording_path(summary: dict[str, Any]) -> str | None:
    """The .rrd of evaluation episodes, if the evaluate stage recorded one."""
    evaluation = summary.get("evaluation", {})
    rec = evaluation.get("recording") or summary.get("artifacts", {}).get("recording")
    if isinstance(rec, dict):
        rec = rec.get("path")
    return str(rec) if rec else None


def prefect_ui_command(prefect_home: str | os.PathLike | None = None) -> str:
    """Shell command that serves the Prefect UI over this pipeline's state (``PREFECT_HOME``)."""
    home = Path(prefect_home or os.environ.get("PREFECT_HOME", "outputs/.prefect")).resolve()
    prefect = Path(sys.executable).with_name("prefect")
    exe = str(prefect) if prefect.exists() else "prefect"
    return (
        f"PREFECT_HOME={shlex.quote(str(home))} PREFECT_SERVER_UI_ENABLED=true {shlex.quote(exe)} server start "
        f"(then open {PREFECT_UI_URL})"
    )


def summary_lines(summary: dict[str, Any], out_dir: str | os.PathLike, recipe: str | None = None) -> list[str]:
    """Human-readable end of a pipeline run: expert success, Mimic rate, training time and final loss, policy
    success with its episode count, then the metrics, checkpoint and recording paths and the Prefect UI command.
    A user's own Prefect server (``PREFECT_API_URL``) is named instead of the local UI command."""
    arts = summary["artifacts"]
    demos, gen, ckpt = (arts[k].get("metrics", {}) for k in ("demos", "mimic", "checkpoint"))
    ev = summary["evaluation"]
    attempts = gen.get("attempts")
    mimic_rate = gen.get("generation_success_rate")
    train_s, loss, steps = ckpt.get("wall_time_s"), ckpt.get("final_loss"), ckpt.get("steps")
    head = f"{summary['task']} pipeline" + (f" ({recipe} recipe)" if recipe else "")
    mimic = f"{gen.get('episodes')} demos generated" + (
        f" from {attempts} attempts ({_pct(mimic_rate)} success)" if attempts else ""
    )
    training = (
        (f"{steps} steps, " if steps else "")
        + (f"{train_s:.0f} s, " if isinstance(train_s, (int, float)) else "")
        + (f"final loss {loss:.4f}" if isinstance(loss, (int, float)) else "final loss n/a")
    )
    succeeded = ev.get("successes", round(ev["success_rate"] * ev["episodes"]))
    lines = [
        f"{head}:",
        f"  expert demos    {demos.get('episodes')} collected, {_pct(demos.get('success_rate'))} success",
        f"  Mimic           {mimic}",
        f"  training        {training}",
        (
            f"  policy          {ev['success_rate']:.1%} success over {ev['episodes']} held-out randomised "
            f"evaluation episodes ({succeeded} succeeded)"
        ),
        "where to look:",
        f"  metrics         {Path(out_dir).resolve() / 'metrics.json'}",
        f"  checkpoint      {arts['checkpoint']['path']}",
    ]
    rec = recording_path(summary)
    if rec:
        lines.append(f"  evaluation rrd  {rec} (open it with: rerun {shlex.quote(rec)})")
    if os.environ.get("PREFECT_API_URL"):
        lines.append(f"  Prefect UI      {os.environ['PREFECT_API_URL'].removesuffix('/api')} (your server)")
    else:
        lines.append(f"  Prefect UI      {prefect_ui_command()}")
    return lines
