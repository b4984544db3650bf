"""What the pipeline tells Prefect: stage log lines (run logger), one artifact per stage, a quiet console,
and a stage-start hook for tests.

Artifacts (keys; the Artifacts tab of the pipeline run and Prefect's artifact pages):

- ``collect-dataset``, ``mimic-dataset``: dataset summary (path, episodes, successes, samples, hash);
  the Mimic one adds the generation rate (successes / attempts).
- ``train-loss-curve``: the epoch loss curve (epoch, steps, mean loss, learning rate).
- ``evaluation``: success rate, episodes, mean length, termination reasons and subtask signals.
- ``evaluation-phases`` (a coherent task): per phase, the rows that reached it, passed it, and why the others
  stopped.
- ``newton-lab-pipeline``: the markdown summary of the whole run.
"""

from __future__ import annotations

import logging
import signal
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from prefect.artifacts import create_markdown_artifact, create_table_artifact

ARTIFACT_KEYS = {
    "collect": "collect-dataset",
    "mimic": "mimic-dataset",
    "train": "train-loss-curve",
    "evaluate": "evaluation",
    "pipeline": "newton-lab-pipeline",
}
"""Artifact key of each stage (and of the pipeline summary)."""
PHASES_ARTIFACT_KEY = "evaluation-phases"
"""A coherent task's evaluation per phase: one row per phase (reached, passed, where the others stopped)."""

LOSS_ROWS = 100
"""Most rows of the loss-curve artifact (longer curves are subsampled, the last epoch kept)."""


# ----------------------------------------------------------------------------- stage log lines
def describe_inputs(kwargs: dict[str, Any]) -> str:
    """One line naming what a stage was asked to do (from its keyword arguments)."""
    args = kwargs.get("args")
    if args is not None:
        fields = ("task", "episodes", "num_envs", "seed", "device", "dataset_path", "output_path", "checkpoint")
        return ", ".join(f"{k} {getattr(args, k)}" for k in fields if getattr(args, k, None) is not None)
    if "source" in kwargs and "dataset" not in kwargs:  # split
        return f"source {kwargs['source']['path']} -> {kwargs.get('out_dir')}"
    if "ppo" in kwargs:  # train-rl
        ppo = kwargs["ppo"]
        return (
            f"task {kwargs['task_id']}, {ppo.get('iterations')} PPO iterations on {ppo.get('num_envs')} rows, "
            f"device {ppo.get('device')} -> {kwargs.get('out_dir')}"
        )
    cfg = kwargs.get("train_cfg") or {}
    return (
        f"dataset {kwargs['dataset']['path']}, {cfg.get('max_steps')} steps, batch {cfg.get('batch_size')}, "
        f"device {cfg.get('device')} -> {kwargs.get('out_dir')}"
    )


def describe_result(result: dict[str, Any], seconds: float) -> list[str]:
    """Log lines for a finished stage: its figures, then (training) the loss curve."""
    m = result.get("metrics", result)
    figures = ", ".join(f"{k} {_fmt(v)}" for k, v in m.items() if not isinstance(v, (list, dict)))
    lines = [f"done in {seconds:.1f} s: {figures}"]
    if "path" in result:
        lines.append(f"artifact {result['path']} (sha256 {result['sha256'][:12]})")
    curve = m.get("loss_curve") or []
    step = max(1, len(curve) // 10)
    lines += [f"epoch {r['epoch']}: step {r['steps']}, loss {r['loss']:.5f}" for r in curve[::step]]
    return lines


def _fmt(v: Any) -> str:
    return f"{v:.4g}" if isinstance(v, float) else str(v)


# ----------------------------------------------------------------------------- artifacts
def publish_dataset(stage: str, art: dict[str, Any], shards: int) -> None:
    """``collect-dataset`` / ``mimic-dataset``: the stage's dataset summary as a table."""
    m = art["metrics"]
    rows = [
        ("path", art["path"]),
        ("episodes", m.get("episodes")),
        ("successes", m.get("successes")),
        ("samples", m.get("samples")),
        ("shards", shards),
        ("sha256", art["sha256"][:12]),
    ]
    if stage == "mimic":
        rate = m.get("generation_success_rate", m.get("successes", 0) / max(m.get("attempts") or 1, 1))
        rows += [("attempts", m.get("attempts")), ("generation rate", f"{rate:.1%}")]
    else:
        rows.append(("success rate", f"{m.get('success_rate', 1.0):.1%}"))
    create_table_artifact(
        table=[{"field": k, "value": _fmt(v)} for k, v in rows if v is not None],
        key=ARTIFACT_KEYS[stage],
        description=f"{stage} stage: dataset {Path(art['path']).name}",
    )


def publish_loss_curve(ckpt: dict[str, Any]) -> None:
    """``train-loss-curve``: mean loss per epoch (at most ``LOSS_ROWS`` rows)."""
    curve = ckpt["metrics"].get("loss_curve") or []
    step = max(1, -(-len(curve) // LOSS_ROWS))
    rows = curve[::step] + ([curve[-1]] if curve and (len(curve) - 1) % step else [])
    create_table_artifact(
        table=[{k: r[k] for k in ("epoch", "steps", "loss", "lr")} for r in rows],
        key=ARTIFACT_KEYS["train"],
        description=f"train stage: final loss {_fmt(ckpt['metrics'].get('final_loss'))}, checkpoint {ckpt['path']}",
    )


def publish_evaluation(metrics: dict[str, Any]) -> None:
    """``evaluation``: success rate, mean length, termination reasons and subtask signals."""
    rows = [
        ("success rate", f"{metrics['success_rate']:.1%}"),
        ("episodes", metrics["episodes"]),
        ("successes", metrics["successes"]),
        ("average length", f"{metrics['average_length']:.1f} steps"),
    ]
    rows += [(f"termination: {k}", v) for k, v in sorted(metrics["termination_reasons"].items())]
    rows += [(f"subtask: {k}", v) for k, v in sorted(metrics.get("subtask_signals", {}).items())]
    phases = metrics.get("phases", {})
    if len(phases) > 1:  # a coherent task: where its rows stop
        rows += [(f"phase {k}: passed / reached", f"{v['passed']} / {v['reached']}") for k, v in phases.items()]
    create_table_artifact(
        table=[{"metric": k, "value": str(v)} for k, v in rows],
        key=ARTIFACT_KEYS["evaluate"],
        description=f"evaluate stage: {metrics['successes']}/{metrics['episodes']} successes",
    )
    if len(phases) > 1:
        create_table_artifact(
            table=[
                {
                    "phase": k,
                    "reached": v["reached"],
                    "passed": v["passed"],
                    "stopped": ", ".join(f"{r} {n}" for r, n in v["stalled"].items()) or "none",
                }
                for k, v in phases.items()
            ],
            key=PHASES_ARTIFACT_KEY,
            description="evaluate stage: where the composed task's rows stopped, per phase",
        )


def publish_summary(task_id: str, demos, gen, ckpt, metrics, out: Path) -> None:
    """``newton-lab-pipeline``: the run's metrics table and artifact paths as markdown."""
    g = gen["metrics"]
    rows = [
        (
            "expert demos",
            f"{demos['metrics'].get('episodes')} ({demos['metrics'].get('success_rate', 1.0):.0%} success)",
        ),
        (
            "mimic demos",
            f"{g.get('episodes')} (generation rate "
            f"{g.get('generation_success_rate', g.get('successes', 0) / max(g.get('attempts', 1), 1)):.0%})",
        ),
        ("final training loss", f"{ckpt['metrics'].get('final_loss')}"),
        ("evaluation success rate", f"{metrics['success_rate']:.1%} of {metrics['episodes']} episodes"),
    ]
    table = "\n".join(f"| {k} | {v} |" for k, v in rows)
    paths = "\n".join(
        f"- {k}: `{a['path']}` (sha256 {a['sha256'][:12]})"
        for k, a in (("demos", demos), ("mimic", gen), ("checkpoint", ckpt))
    )
    create_markdown_artifact(
        markdown=f"# newton_lab pipeline: {task_id}\n\n| metric | value |\n|---|---|\n{table}\n\n{paths}\n"
        f"- metrics: `{out / 'metrics.json'}`\n"
        + (
            f"- evaluation recording: `{metrics['recording']}` (open it with `rerun`)\n"
            if metrics.get("recording")
            else ""
        ),
        key=ARTIFACT_KEYS["pipeline"],
        description=f"newton_lab pipeline metrics for {task_id}",
    )


# ----------------------------------------------------------------------------- console
class CallerReports(logging.Filter):
    """Console filter for Prefect's run loggers: a failure's tracebacks are left to whoever called the flow
    (the CLI prints one line for an input error; Python prints other errors' tracebacks once) and so are the
    'Finished in state Failed' lines. A stage's own traceback stays unless the error is ``input_errors``.
    The API handler (the UI's logs) still gets every record."""

    def __init__(self, input_errors: tuple[type[BaseException], ...]):
        super().__init__()
        self.input_errors = input_errors

    def filter(self, record: logging.LogRecord) -> bool:
        if not record.name.startswith(("prefect.flow_runs", "prefect.task_runs")):
            return True
        if record.exc_info and record.exc_info[1] is not None:
            return record.name.startswith("prefect.task_runs") and not isinstance(record.exc_info[1], self.input_errors)
        return not record.getMessage().startswith("Finished in state Failed")


def quiet_console(input_errors: tuple[type[BaseException], ...]) -> None:
    """Add ``CallerReports`` to the console handlers of this process (once)."""
    from prefect.logging.handlers import PrefectConsoleHandler  # deferred: only where Prefect set up logging

    for handler in logging.getLogger().handlers:
        if isinstance(handler, PrefectConsoleHandler) and not any(
            isinstance(f, CallerReports) for f in handler.filters
        ):
            handler.addFilter(CallerReports(input_errors))


_caller_sigterm: Any = None
"""The SIGTERM handler of whoever started the flow (``note_caller_sigterm``)."""


def note_caller_sigterm() -> None:
    """Remember the SIGTERM handler of the caller (before the flow starts; only the main thread has one)."""
    global _caller_sigterm
    main = threading.current_thread() is threading.main_thread()
    _caller_sigterm = signal.getsignal(signal.SIGTERM) if main else None


def restore_caller_sigterm() -> None:
    """In a flow's body: put back the caller's own SIGTERM handler, when it set one (the command line's ends the
    process at once, in one line). Prefect's flow engine swaps in a handler that raises in the main thread, which
    then waits for the stage in flight, in a worker thread, to end: minutes for a training."""
    if callable(_caller_sigterm) and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _caller_sigterm)


# ----------------------------------------------------------------------------- stage-start hooks (a seam for tests)
STAGE_START_HOOKS: list[Callable[[str], None]] = []
"""Called in order with the stage's name as each stage starts, in the process that runs it. Empty in a product run;
the flow tests add a fault injector (a transient ``OSError``, a killed Dask worker) through it."""


def stage_starting(stage: str) -> None:
    """Called as a stage starts: runs ``STAGE_START_HOOKS``."""
    for hook in list(STAGE_START_HOOKS):
        hook(stage)
