"""The pipeline's stages as commands (``collect``, ``mimic``, ``train``, ``evaluate``; ``pipeline`` chains them in a
module of its own), and the rerun stream of the episodes a command runs (``rerun_hook``; ``teleop`` streams too): each
calls the library with its argument object (``newton_lab.commands.workflow``), prints its result (one JSON line last)
and returns the exit status. The library imports are deferred into the commands on purpose: Warp/Newton (envs), torch
(policies) and rerun-sdk (viz) each take seconds to import, and a command pays only for what it runs."""

from __future__ import annotations

import json

from ..commands import CollectArgs, EvaluateArgs, MimicArgs, RerunArgs, TrainArgs
from ..records import write_run_record

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


def rerun_hook(args: RerunArgs, env):
    """A rerun ``on_step`` hook when --rerun / --rerun-save is given, else None (and a closer)."""
    if not (args.rerun or args.rerun_save):
        return None, lambda: None
    from ..viz import RerunLogger  # deferred: rerun-sdk is slow to import

    lg = RerunLogger(
        env,
        save=args.rerun_save,
        spawn=args.rerun and not args.rerun_save,
        max_worlds=args.rerun_worlds,
        image_every=args.rerun_image_every,
    )

    def close() -> None:
        lg.close()
        if lg.path is not None:
            print(f"rerun recording: {lg.path} (open it with: rerun {lg.path})")

    return lg.on_step, close


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
    from ..envs.perturb import scene_axes  # deferred: Warp/Newton are slow to import
    from ..envs.rollout import EVAL_REPORT_KEYS  # deferred: Warp/Newton are slow to import
    from ..policies.agent import checkpoint_agent, phase_policy_agent  # deferred: torch is slow to import

    graphs = not args.eager_policy
    from_checkpoint = (
        checkpoint_agent(args.checkpoint, args.policy_device(), graphs=graphs) if args.checkpoint else None
    )
    phases = args.phase_checkpoints()

    def build(**scene):
        """The env (with ``scene``: distractor objects) and the agent on it."""
        env = make_env(args.task, **args.env_kwargs(), **scene)
        if phases:
            return env, phase_policy_agent(env, phases, device=args.policy_device(), graphs=graphs)
        return env, from_checkpoint or expert_agent(env)

    cells = args.perturbation_cells()
    env, agent = build(**scene_axes(cells[0].values)) if cells else build()  # the first cell's scene
    hook, close = rerun_hook(args, env)
    try:
        summary = evaluate_perturbed(
            env, agent, cells, seed=args.seed, on_step=hook, rebuild=build, **args.rollout_kwargs()
        )
    finally:
        close()
    out = {k: summary[k] for k in (*EVAL_REPORT_KEYS, "perturbations", "timing") if k in summary}
    if args.perturb or args.run_record:
        results = {**out, "checkpoint": args.checkpoint, "phase_checkpoints": phases or None}
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
