"""``newton-lab pipeline``: the Prefect flow collect -> mimic -> train -> evaluate (the long-horizon flow on a
coherent task), or its plan with ``--dry-run``; prints the summary, the stages' states and the run record. Prefect
is imported only once the run starts (after ``configure``), and not at all for a plan."""

from __future__ import annotations

import json
from pathlib import Path

from ..commands import PipelineArgs
from ..flows.report import summary_lines
from ..flows.settings import configure, demo_recipe, phase_trainings, with_inputs
from ..task_api.registry import lookup
from .pipeline_ends import ends_in_one_line


def pipeline(args: PipelineArgs) -> int:
    from .. import tasks as _registered  # noqa: F401  deferred: registering the tasks imports Warp

    cfg = lookup(args.task).make_cfg({})
    long_horizon = bool(cfg.phases)  # a coherent task: the long-horizon flow
    recipe = demo_recipe(args.recipe, args.device, long_horizon=long_horizon, task=args.task)
    kwargs = args.pipeline_kwargs(recipe)
    kwargs["train_cfg"] = with_inputs(kwargs["train_cfg"], cfg.target_observations)
    # the policies to train, now: a kind that cannot be learned per target is refused before Prefect starts
    trainings = phase_trainings(cfg, kwargs["train_cfg"], kwargs.get("per_target", ())) if long_horizon else {}
    if args.dry_run:  # the plan only: nothing is collected, trained or written, Prefect is not started
        stages = (
            ["collect", "split", "train per learned phase", "evaluate composed"]
            if long_horizon
            else ["collect", "mimic", "train", "evaluate"]
        )
        plan = {**kwargs, "long_horizon": long_horizon, "stages": stages}
        if long_horizon:
            plan["learned_phases"] = list(trainings)
        print(json.dumps({"plan": plan}, default=str))
        return 0
    with ends_in_one_line(args.out):  # Ctrl-C: one line, exit 130; SIGKILL: no server or worker left running
        configure(Path(args.out) / ".prefect")  # before Prefect is imported
        from ..flows.orchestration import run_pipeline  # deferred: Prefect is slow to import, and after configure

        summary = run_pipeline(**kwargs)
    from ..flows.long_horizon import summary_lines as long_horizon_lines  # deferred: Prefect is slow to import

    metrics = Path(args.out).resolve() / "metrics.json"
    lines = long_horizon_lines if long_horizon else summary_lines
    print("\n".join(lines(summary, args.out, recipe["name"])))
    print("stages: " + ", ".join(f"{k} {'/'.join(v)}" for k, v in summary["stage_states"].items()))
    print(f"run record: {summary['record']}")
    print(
        json.dumps(
            {
                "task": summary["task"],
                "success_rate": summary["success_rate"],
                "metrics": str(metrics),
                "record": summary["record"],
            }
        )
    )
    return 0
