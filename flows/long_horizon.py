"""The long-horizon pipeline of a coherent task (PickToShelf, SortToShelf): collect the whole task with its expert
-> split the demos by phase -> train one visuomotor policy per learned phase (mapped task runs: on a Dask cluster
they spread over its workers, one GPU each) -> evaluate the coherent task run by the learned phases, the other
phases by their component's expert. Every stage is cached on its inputs and resumable, as in ``pipeline``.

Which phases are learned: every phase but the ones that drive the base (navigation runs the planner's exact
base motion; a policy would only copy it). The phases' data is the coherent task's own demos, split: each
phase's policy sees the scenes that the phase before it leaves behind, which is what it meets when composed.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from prefect import flow, get_run_logger, unmapped

from ..datasets.files.output_paths import output_path
from ..task_api.registry import lookup
from . import runlog, stages
from .run_record import StageClock, record_run
from .settings import LONG_HORIZON_OPTIONS, LONG_HORIZON_RECIPES, PIPELINE_DATASET_FORMAT, phase_trainings, with_inputs
from .stage_runs import REPORTED_ERRORS, results, run_collect, run_evaluate, stage_task, train_task

split_task = stage_task(stages.split_stage, "split")

COLLECT_MAX_STEPS = 3000
"""Step limit of an expert coherent episode in the collect stage (PickToShelf's take ~470, SortToShelf's ~440,
SortToShelf-All's ~2350);
``eval_max_steps`` bounds the evaluation alone."""


def has_phases(task_id: str) -> bool:
    """Whether ``task_id`` is a coherent task (its pipeline is the long-horizon one)."""
    from .. import tasks  # noqa: F401  deferred: registering the task ids imports Warp

    return bool(lookup(task_id).make_cfg({}).phases)


@flow(name="long-horizon pipeline")
def long_horizon_pipeline(
    task_id: str,
    demos: int,
    train_cfg: dict[str, Any],
    eval_episodes: int,
    num_envs: int,
    device: str | None,
    out: str,
    seed: int = 0,
    workers: int = 1,
    eval_max_steps: int = 3000,
    cameras: str = LONG_HORIZON_RECIPES["cpu"]["cameras"],
    task_options: dict[str, Any] | None = None,
    gpus: int = 1,
    record: bool = True,
    recipe: str | None = None,
    domain_randomize: dict[str, float] | None = None,
    dataset_format: str = PIPELINE_DATASET_FORMAT,
    distractors: int = 0,
    per_target: list[str] | None = None,
) -> dict[str, Any]:
    """collect (coherent) -> split -> train per learned phase -> evaluate composed, each stage a task run of this
    flow; writes ``<out>/metrics.json`` (per-phase reached / passed / stalled included), a markdown summary and a
    run record (``<out>/records/``; ``summary["record"]``).
    ``workers`` > 1 shards collection and evaluation and runs the phase trainings side by side (Dask);
    ``gpus`` > 1 trains each phase data-parallel; ``domain_randomize`` (axis -> level) randomises collection's rows
    (the evaluation stays on the task's own distribution), and ``distractors`` objects stand on its table;
    ``dataset_format`` (hdf5 or zarr) is that of the demos and of the phase datasets split from them;
    the kinds of ``per_target`` train one policy per value of their target, switched per row by the composed agent
    (``settings.phase_trainings``)."""
    runlog.quiet_console(REPORTED_ERRORS)
    runlog.restore_caller_sigterm()
    log = get_run_logger()
    out_dir = output_path(Path(out) / "metrics.json").parent
    options = {**LONG_HORIZON_OPTIONS, **(task_options or {})}
    per_target = list(per_target or [])
    from .. import tasks  # noqa: F401  deferred: registering the task ids imports Warp

    cfg = lookup(task_id).make_cfg(options)
    trainings = phase_trainings(cfg, train_cfg, per_target)
    train_cfg = with_inputs(train_cfg, cfg.target_observations)  # the record's: a policy per kind
    clock = StageClock()
    collect = {"max_steps": COLLECT_MAX_STEPS, "domain_randomize": domain_randomize, "dataset_format": dataset_format}
    collect["distractors"] = distractors
    demo_art, s_collect = run_collect(
        task_id, demos, num_envs, seed, device, out, workers, cameras=cameras, task_options=options, **collect
    )
    clock.lap("collect")
    log.info("collect: %s", "/".join(s_collect))
    split, s_split = _split(demo_art, out, per_target, clock)
    checkpoints, s_train = _train_phases(split, trainings, out, gpus, clock)
    metrics, s_eval = run_evaluate(
        None,
        task_id,
        eval_episodes,
        num_envs,
        seed + 10_000,
        device,
        workers,
        eval_max_steps,
        recording=Path(out) / "evaluation.rrd" if record else None,
        cameras=cameras,
        task_options=options,
        phase_checkpoints=checkpoints,
    )
    clock.lap("evaluate")
    log.info("evaluate: %s", evaluation_line(s_eval, metrics))
    summary = {
        "task": task_id,
        "success_rate": metrics["success_rate"],
        "evaluation": metrics,
        "learned_phases": list(trainings),
        "artifacts": {"demos": demo_art, "phases": split, "checkpoints": checkpoints},
        "stage_states": {"collect": s_collect, "split": s_split, "train": s_train, "evaluate": s_eval},
    }
    settings = {"seed": seed, "device": train_cfg.get("device", device), "train_cfg": dict(train_cfg)}
    settings.update(cameras=cameras, task_options=options, recipe=recipe, dataset_format=dataset_format)
    settings.update(domain_randomize=domain_randomize or None, distractors=distractors, per_target=per_target)
    return record_run(summary, clock, out_dir, **settings)


def _split(demo_art: dict, out: str, per_target: list[str], clock):
    """The split stage (``per_target``'s kinds one dataset per target value), logged; returns the phase datasets
    and the stage's states."""
    (split,), s_split = results([split_task.submit(source=demo_art, out_dir=out, by_target=per_target)], "split")
    clock.lap("split")
    get_run_logger().info(
        "split: %s -> %s", "/".join(s_split), ", ".join(f"{p} {a['metrics']['episodes']}" for p, a in split.items())
    )
    return split, s_split


def _train_phases(split: dict, trainings: dict[str, dict[str, Any]], out: str, gpus: int, clock):
    """One training per learned phase (or phase and target) on its split dataset (side by side where the runner
    allows), each loss curve published; returns the checkpoints by phase and the trainings' states."""
    log = get_run_logger()
    phases = list(trainings)
    arts, s_train = results(
        train_task.map(
            dataset=[split[p] for p in phases],
            train_cfg=[dict(c) for c in trainings.values()],
            out_dir=unmapped(out),
            name=[f"policy_{p.replace('/', '-')}" for p in phases],
            gpus=unmapped(gpus),
        ),
        "train",
    )
    checkpoints = dict(zip(phases, arts))
    clock.lap("train")
    for art in arts:
        runlog.publish_loss_curve(art)
    log.info("train: %s (%s)", "/".join(s_train), ", ".join(phases))
    return checkpoints, s_train


def summary_lines(summary: dict[str, Any], out_dir: str | Path, recipe: str | None = None) -> list[str]:
    """Human-readable end of a long-horizon run: demos, per-phase datasets and trainings, the composed success,
    where each phase's rows stopped and in how many episodes each subtask signal fired, then where to look."""
    arts, ev = summary["artifacts"], summary["evaluation"]
    demos = arts["demos"]["metrics"]
    head = f"{summary['task']} long-horizon pipeline" + (f" ({recipe} recipe)" if recipe else "")
    lines = [
        f"{head}:",
        f"  expert demos    {demos.get('episodes')} collected, {demos.get('success_rate', 0):.0%} success",
    ]
    width = max(9, *(len(p) for p in arts["phases"]))  # pick/yellow_cylinder: a policy per target
    for phase, art in arts["phases"].items():
        ckpt = arts["checkpoints"].get(phase)
        trained = (
            f"; policy {ckpt['metrics'].get('steps')} steps, final loss {ckpt['metrics'].get('final_loss'):.4f}"
            if ckpt
            else "; expert"
        )
        lines.append(f"  phase {phase:<{width}} {art['metrics']['episodes']} segments{trained}")
    lines.append(
        f"  composed        {ev['success_rate']:.1%} success over {ev['episodes']} held-out randomised episodes"
    )
    for phase, p in ev["phases"].items():
        stalled = ", ".join(f"{k} {v}" for k, v in p["stalled"].items()) or "none"
        lines.append(f"    {phase:<13} passed {p['passed']}/{p['reached']} (stopped: {stalled})")
    for kind, by_value in (ev.get("phase_targets") or {}).items():  # SortToShelf-All: each kind per object
        cells = ", ".join(f"{v} {c['passed']}/{c['reached']}" for v, c in by_value.items())
        lines.append(f"    {kind + ' by target':<13} {cells}")
    if ev.get("subtask_signals"):  # e.g. SortToShelf-All's sorted_<object>: episodes that sorted each object
        signals = ", ".join(f"{k} {v}/{ev['episodes']}" for k, v in ev["subtask_signals"].items())
        lines.append(f"    signals       {signals}")
    lines += ["where to look:", f"  metrics         {Path(out_dir).resolve() / 'metrics.json'}"]
    lines += [f"  checkpoint      {phase}: {art['path']}" for phase, art in arts["checkpoints"].items()]
    if ev.get("recording"):
        lines.append(f"  evaluation rrd  {ev['recording']}")
    return lines


def evaluation_line(states: list[str], metrics: dict[str, Any]) -> str:
    """The evaluate stage's log line: its states, the composed success rate and each phase's passed / reached."""
    phases = ", ".join(f"{k} {v['passed']}/{v['reached']}" for k, v in metrics["phases"].items())
    return (
        f"{'/'.join(states)}; success rate {100 * metrics['success_rate']:.1f}% over {metrics['episodes']} "
        f"episodes; {phases}"
    )
