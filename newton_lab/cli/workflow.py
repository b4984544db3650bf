"""The workflow commands (``collect``, ``evaluate``, ``mimic``, ``train``, ``split``, ``export``, ``view``;
``pipeline`` has a module of its own): each calls the library with its argument object
(``newton_lab.commands.workflow``), prints its result (one JSON line last) and returns the exit status. The library
imports are deferred into the commands on purpose: Warp/Newton (envs), torch (policies) and Prefect (flows) each
take seconds to import, and a command pays only for what it runs."""

from __future__ import annotations

import json
from pathlib import Path

from ..commands import CollectArgs, EvaluateArgs, ExportArgs, MimicArgs, SplitArgs, TrainArgs, ViewArgs
from ..records import write_run_record
from .env import rerun_hook

COLLECT_REPORT_KEYS = (
    "task",
    "episodes",
    "successes",
    "success_rate",
    "path",
    "num_envs",
    "average_length",
    "termination_reasons",
    "diverged",
    "subtask_signals",
)
"""Keys of the collect summary printed by ``newton-lab collect`` (then ``wall_time_s``)."""


def collect(args: CollectArgs) -> int:
    from ..agents import expert_agent  # deferred: Warp/Newton are slow to import
    from ..envs import make_env  # deferred: Warp/Newton are slow to import
    from ..envs.perturb import collect_randomized  # deferred: Warp/Newton are slow to import

    env = make_env(args.task, **args.env_kwargs())
    agent = expert_agent(env)
    hook, close = rerun_hook(args, env)
    try:
        summary = collect_randomized(
            env, args.domain_randomization(), seed=args.seed, agent=agent, on_step=hook, **args.collect_kwargs()
        )
    finally:
        close()
    saved = {"saved_end_scenario_path": summary["saved_end_scenario_path"]} if args.save_end_scenario else {}
    print(
        json.dumps(
            {**{k: summary[k] for k in COLLECT_REPORT_KEYS}, "wall_time_s": round(summary["wall_time_s"], 2), **saved}
        )
    )
    return 0


def evaluate(args: EvaluateArgs) -> int:
    from ..agents import evaluate_perturbed, expert_agent  # deferred: Warp/Newton are slow to import
    from ..envs import make_env  # deferred: Warp/Newton are slow to import
    from ..envs.rollout import EVAL_REPORT_KEYS  # deferred: Warp/Newton are slow to import
    from ..policies.agent import checkpoint_agent, phase_policy_agent  # deferred: torch is slow to import

    from_checkpoint = checkpoint_agent(args.checkpoint, args.policy_device()) if args.checkpoint else None
    env = make_env(args.task, **args.env_kwargs())
    phases = args.phase_checkpoints()
    agent = (
        phase_policy_agent(env, phases, device=args.policy_device()) if phases else from_checkpoint or expert_agent(env)
    )
    hook, close = rerun_hook(args, env)
    try:
        summary = evaluate_perturbed(
            env, agent, args.perturbation_cells(), seed=args.seed, on_step=hook, **args.rollout_kwargs()
        )
    finally:
        close()
    out = {k: summary[k] for k in (*EVAL_REPORT_KEYS, "perturbations", "timing") if k in summary}
    if args.perturb or args.run_record:
        results = {**out, "checkpoint": args.checkpoint}
        write_run_record("evaluate", args.run_record, task=args.task, device=args.device, results=results)
    print(json.dumps(out))
    return 0


def mimic(args: MimicArgs) -> int:
    from ..mimic import mimic as generate  # deferred: Warp/Newton are slow to import

    ref = generate(args.dataset_path, **args.mimic_kwargs())
    m = ref.metadata
    wall = m.get("wall_time_s") or 0.0  # the generation loop (env and sources built before it)
    print(
        json.dumps(
            {
                "task": ref.task_id,
                "successes": m["successes"],
                "attempts": m["attempts"],
                "generation_success_rate": m["generation_success_rate"],
                "path": str(ref.path),
                "wall_time_s": wall,
                "demos_per_hour": m["successes"] / wall * 3600.0 if wall else None,
            }
        )
    )
    return 0


def train(args: TrainArgs) -> int:
    from ..policies import Policy  # deferred: torch is slow to import
    from ..policies.diffusion import PRESETS  # deferred: torch is slow to import

    path = Policy.from_backend("diffusion").train(
        args.datasets(), args.train_cfg(PRESETS), resume=args.resume, gpus=args.gpus
    )
    print(json.dumps({"checkpoint": str(path)}))
    return 0


def split(args: SplitArgs) -> int:
    from ..datasets import split_by_phase, split_train_val  # deferred: the dataset package imports Warp/Newton

    if args.out is None:
        keys = split_train_val(args.dataset_path, args.val_ratio, seed=args.seed, filter_key=args.filter_key)
        print(json.dumps({"path": str(args.dataset_path), "filter_keys": {k: len(v) for k, v in keys.items()}}))
        return 0
    refs = split_by_phase(args.dataset_path, args.out, phases=args.phase_names())
    print(
        json.dumps(
            {name: {"path": str(r.path), "task": r.task_id, "episodes": r["episodes"]} for name, r in refs.items()}
        )
    )
    return 0


def export(args: ExportArgs) -> int:
    from ..datasets.lerobot import export_lerobot  # deferred: pyarrow, Warp/Newton are slow

    out = export_lerobot(args.dataset_path, args.root, include_failed=args.include_failed, video=not args.no_video)
    keys = ("root", "repo_id", "episodes", "frames", "skipped_failed", "fps", "image_keys", "video_files")
    print(json.dumps({k: out[k] for k in keys}))
    return 0


def view(args: ViewArgs) -> int:
    from ..viz import replay_episode  # deferred: rerun-sdk is slow to import

    poses = replay_episode(args.dataset, args.episode, save=args.save, spawn=args.spawn)
    if args.save:
        print(f"rerun recording: {Path(args.save).resolve()} (open it with: rerun {Path(args.save).resolve()})")
    print(json.dumps({"dataset": args.dataset, "episode": args.episode, "frames": len(poses), "rrd": args.save}))
    return 0
