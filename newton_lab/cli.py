"""The ``newton-lab`` console script: ``tasks``, ``collect``, ``evaluate``, ``bench``, ``bench-train``, ..."""

from __future__ import annotations

import argparse
import json
import sys


def _quiet_warp() -> None:
    import warp as wp

    wp.config.quiet = True  # no init banner
    wp.config.log_level = wp.LOG_WARNING  # no per-module load lines


def _add_env_flags(p: argparse.ArgumentParser, *, episodes: int = 1, max_steps: int = 1000) -> None:
    from .task_api.registry import DEFAULT_TASK_ID

    p.add_argument("--task", default=DEFAULT_TASK_ID, help="task id (see `newton-lab tasks`)")
    p.add_argument("--episodes", type=int, default=episodes)
    p.add_argument("--num-envs", type=int, default=1)
    p.add_argument("--max-steps", type=int, default=max_steps, help="episode step limit of the loop")
    p.add_argument("--device", default=None, help="Warp device, e.g. cpu or cuda:0 (default: Warp's)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--randomize", action="store_true", help="turn on the task's reset randomisation")
    p.add_argument("--headless", action="store_true", help="accepted for compatibility; newton-lab never opens a window")
    p.add_argument("--no-progress", action="store_true")
    p.add_argument("--rerun", action="store_true", help="stream to a rerun viewer (spawned)")
    p.add_argument("--rerun-save", default=None, help="record the run to this .rrd file (headless)")
    p.add_argument("--rerun-worlds", type=int, default=4, help="rows drawn in rerun")
    p.add_argument("--sorting-object", default=None, help="SortToShelf tasks: the object to sort")
    p.add_argument("--init-scenario", default=None, help="component tasks: start from this scenario YAML")


def _logger(args, env):
    """A rerun ``on_step`` hook when --rerun / --rerun-save is given, else None (and a closer)."""
    if not (getattr(args, "rerun", False) or getattr(args, "rerun_save", None)):
        return None, lambda: None
    from .viz import RerunLogger

    lg = RerunLogger(env, save=args.rerun_save, spawn=args.rerun and not args.rerun_save, max_worlds=args.rerun_worlds)
    return (lambda reward, info: lg.log_step(reward=reward, success=info["success"])), lg.close


def _cmd_tasks(args) -> int:
    from . import tasks  # noqa: F401  (deferred: registering the tasks imports Warp)
    from .task_api.registry import list_tasks, lookup

    for task_id in list_tasks():
        print(f"{task_id}\t{lookup(task_id).description}")
    return 0


def task_options_from_args(args) -> dict:
    """Task options given on the command line (only the ones set)."""
    opts = {"sorting_object": getattr(args, "sorting_object", None), "init_scenario": getattr(args, "init_scenario", None)}
    return {k: v for k, v in opts.items() if v is not None}


def _make(args):
    from .envs import make_env

    return make_env(args.task, num_envs=args.num_envs, device=args.device, seed=args.seed, randomize=args.randomize,
                    task_options=task_options_from_args(args))


def _cmd_collect(args) -> int:
    from .agents import expert_agent

    env = _make(args)
    agent = expert_agent(env)
    hook, close = _logger(args, env)
    try:
        summary = env.collect(agent=agent, episodes=args.episodes, path=args.dataset_path, max_steps=args.max_steps,
                              progress=not args.no_progress, on_step=hook, save_end_scenario=args.save_end_scenario)
    finally:
        close()
    print(json.dumps({
        "task": summary["task"],
        "episodes": summary["episodes"],
        "successes": summary["successes"],
        "success_rate": summary["success_rate"],
        "path": summary["path"],
        "num_envs": summary["num_envs"],
        "average_length": summary["average_length"],
        "termination_reasons": summary["termination_reasons"],
        "subtask_signals": summary["subtask_signals"],
        "wall_time_s": round(summary["wall_time_s"], 2),
        **({"saved_end_scenario_path": summary["saved_end_scenario_path"]} if args.save_end_scenario else {}),
    }))
    return 0


def _cmd_evaluate(args) -> int:
    from .agents import expert_agent
    from .policies import PolicyAgent
    from .envs.rollout import EVAL_REPORT_KEYS

    on_gpu = args.device is not None and args.device.startswith("cuda")  # the policy runs beside the env
    checkpoint_agent = (PolicyAgent.from_checkpoint(args.checkpoint, device=args.device if on_gpu else None)
                        if args.checkpoint else None)
    env = _make(args)
    agent = checkpoint_agent or expert_agent(env)
    hook, close = _logger(args, env)
    try:
        summary = env.evaluate(agent=agent, episodes=args.episodes, max_steps=args.max_steps,
                               progress=not args.no_progress, on_step=hook)
    finally:
        close()
    print(json.dumps({k: summary[k] for k in EVAL_REPORT_KEYS}))
    return 0


def _cmd_mimic(args) -> int:
    from .mimic import mimic

    ref = mimic(args.dataset_path, episodes=args.episodes, num_envs=args.num_envs, output_path=args.output_path,
                seed=args.seed, device=args.device, max_attempts=args.max_attempts, progress=not args.no_progress)
    m = ref.metadata
    print(json.dumps({"task": ref.task_id, "successes": m["successes"], "attempts": m["attempts"],
                      "generation_success_rate": m["generation_success_rate"], "path": str(ref.path)}))
    return 0


def _cmd_train(args) -> int:
    from .policies import Policy
    from .policies.diffusion import PRESETS

    if args.preset not in PRESETS:
        raise ValueError(f"unknown training preset {args.preset!r}; valid presets: {sorted(PRESETS)}")
    cfg = dict(PRESETS[args.preset], device=args.device, seed=args.seed, output_dir=args.output_dir)
    for key in ("epochs", "batch_size", "max_steps", "lr", "time_budget_s", "init_checkpoint"):
        if getattr(args, key) is not None:
            cfg[key] = getattr(args, key)
    if args.obs_keys:
        cfg["obs_keys"] = tuple(k.strip() for k in args.obs_keys.split(",") if k.strip())
    datasets = args.dataset_path[0] if len(args.dataset_path) == 1 else args.dataset_path
    path = Policy.from_backend("diffusion").train(datasets, cfg)
    print(json.dumps({"checkpoint": str(path)}))
    return 0


def _cmd_split(args) -> int:
    from .datasets import split_by_phase

    refs = split_by_phase(args.dataset_path, args.out)
    print(json.dumps({name: {"path": str(r.path), "task": r.task_id, "episodes": r["episodes"]} for name, r in refs.items()}))
    return 0


def _cmd_export(args) -> int:
    from .datasets.lerobot import export_lerobot

    out = export_lerobot(args.dataset_path, args.root, include_failed=args.include_failed)
    print(json.dumps({k: out[k] for k in ("root", "repo_id", "episodes", "frames", "skipped_failed", "fps")}))
    return 0


DEMO_TRAIN_CFG = {"down_dims": [32, 64, 128], "diffusion_step_embed_dim": 64, "batch_size": 64, "lr": 6e-4,
                  "warmup_steps": 300, "epochs": 1000, "max_steps": 2000, "seed": 0}
"""Small embedded training default of the demo pipeline: the ``cpu`` preset cut to 2000 steps (~3.5 min on a
2-core CPU); ``newton-lab train --preset cpu`` runs the full 10k-step budget."""


def _cmd_pipeline(args) -> int:
    from pathlib import Path

    from .flows.settings import configure

    configure(Path(args.out) / ".prefect")
    from .flows.orchestration import run_pipeline

    train_cfg = dict(DEMO_TRAIN_CFG, device=args.device or "cpu")
    if args.train_steps:
        train_cfg["max_steps"] = args.train_steps
    summary = run_pipeline(runner=args.runner, workers=args.workers, address=args.address, retries=args.retries,
                           task_id=args.task, demos=args.demos, mimic_episodes=args.mimic_episodes,
                           train_cfg=train_cfg, eval_episodes=args.eval_episodes, num_envs=args.num_envs,
                           device=args.device, out=str(Path(args.out).resolve()), seed=args.seed)
    arts = summary["artifacts"]
    print(f"success rate: {summary['success_rate']:.1%} over {summary['evaluation']['episodes']} evaluation episodes")
    for name in ("demos", "mimic", "checkpoint"):
        print(f"{name}: {arts[name]['path']}")
    print(f"metrics: {Path(args.out).resolve() / 'metrics.json'}")
    print("stages: " + ", ".join(f"{k} {'/'.join(v)}" for k, v in summary["stage_states"].items()))
    print(json.dumps({"task": summary["task"], "success_rate": summary["success_rate"],
                      "metrics": str(Path(args.out).resolve() / "metrics.json")}))
    return 0


def _cmd_view(args) -> int:
    from .viz import replay_episode

    if not args.save and not args.spawn:
        raise ValueError("view needs --save file.rrd (headless) or --spawn (open a rerun viewer)")
    poses = replay_episode(args.dataset, args.episode, save=args.save, spawn=args.spawn)
    print(json.dumps({"dataset": args.dataset, "episode": args.episode, "frames": len(poses), "rrd": args.save}))
    return 0


def _cmd_bench(args) -> int:
    from .bench import bench

    print(json.dumps(bench(args.task, num_envs=args.num_envs, steps=args.steps, device=args.device)))
    return 0


def _cmd_bench_train(args) -> int:
    from .bench import bench_train

    print(json.dumps(bench_train(args.dataset_path, batch_size=args.batch_size, steps=args.steps,
                                 device=args.device, preset=args.preset)))
    return 0


def build_parser() -> argparse.ArgumentParser:
    from .task_api.registry import DEFAULT_TASK_ID

    parser = argparse.ArgumentParser(prog="newton-lab", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("tasks", help="list registered task ids").set_defaults(func=_cmd_tasks)

    p = sub.add_parser("collect", help="collect expert episodes into HDF5 (.hdf5/.h5) or zarr (.zarr)")
    _add_env_flags(p)
    p.add_argument("--dataset-path", default="data/pick_cube_demos.hdf5")
    p.add_argument("--save-end-scenario", default=None,
                   help="write the final scene as a scenario YAML (needs --episodes 1 --num-envs 1)")
    p.set_defaults(func=_cmd_collect)

    p = sub.add_parser("evaluate", help="run a policy checkpoint (or the expert planner) and report the success rate")
    _add_env_flags(p)
    p.add_argument("--checkpoint", default=None, help="policy checkpoint; the expert planner when omitted")
    p.set_defaults(func=_cmd_evaluate)

    p = sub.add_parser("mimic", help="expand source demos with Mimic (successes only)")
    p.add_argument("--dataset-path", required=True)
    p.add_argument("--output-path", default=None)
    p.add_argument("--episodes", type=int, default=36)
    p.add_argument("--num-envs", type=int, default=8)
    p.add_argument("--max-attempts", type=int, default=None)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--device", default=None)
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=_cmd_mimic)

    p = sub.add_parser("train", help="train a diffusion policy on a dataset")
    p.add_argument("--dataset-path", required=True, nargs="+",
                   help="one dataset, or several of the same task trained as one")
    p.add_argument("--output-dir", default="outputs/policy")
    p.add_argument("--preset", default="default", help="named settings: default (GPU-sized) or cpu (2-core budget)")
    p.add_argument("--epochs", type=int, default=None, help="passes over the data (default 100)")
    p.add_argument("--max-steps", type=int, default=None)
    p.add_argument("--batch-size", type=int, default=None, help="default 256 (cpu preset: 64)")
    p.add_argument("--lr", type=float, default=None, help="peak learning rate")
    p.add_argument("--obs-keys", default=None,
                   help="comma-separated obs terms to condition on (default: every low-dim term but actions)")
    p.add_argument("--init-checkpoint", default=None,
                   help="continue training this checkpoint (its architecture and normalisers are kept)")
    p.add_argument("--time-budget-s", type=float, default=None,
                   help="wall-clock budget [s]: the run is shortened to fit (LR schedule re-planned)")
    p.add_argument("--device", default="cpu")
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=_cmd_train)

    p = sub.add_parser("split", help="split a coherent task's dataset into one dataset per phase")
    p.add_argument("--dataset-path", required=True)
    p.add_argument("--out", required=True, help="folder for <phase>.hdf5 / .zarr (files must not exist)")
    p.set_defaults(func=_cmd_split)

    p = sub.add_parser("export", help="export a dataset to LeRobot v3")
    p.add_argument("--dataset-path", required=True)
    p.add_argument("--root", required=True, help="new LeRobot dataset folder (must not exist)")
    p.add_argument("--include-failed", action="store_true")
    p.set_defaults(func=_cmd_export)

    p = sub.add_parser("pipeline", help="Prefect flow: collect -> mimic -> train -> evaluate")
    p.add_argument("--task", default=DEFAULT_TASK_ID)
    p.add_argument("--demos", type=int, default=4)
    p.add_argument("--mimic-episodes", type=int, default=40)
    p.add_argument("--train-steps", type=int, default=None, help="gradient steps (demo default 2000)")
    p.add_argument("--eval-episodes", type=int, default=10)
    p.add_argument("--num-envs", type=int, default=4)
    p.add_argument("--device", default=None)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="outputs/pipeline")
    p.add_argument("--runner", default="local", help="local or dask")
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--address", default=None, help="Dask scheduler address (default: start a local cluster)")
    p.add_argument("--retries", type=int, default=1, help="retries of a failed stage")
    p.set_defaults(func=_cmd_pipeline)

    p = sub.add_parser("view", help="replay a recorded episode into rerun by re-applying its states")
    p.add_argument("dataset")
    p.add_argument("--episode", type=int, default=0)
    p.add_argument("--save", default=None, help=".rrd file to write")
    p.add_argument("--spawn", action="store_true", help="open a rerun viewer")
    p.set_defaults(func=_cmd_view)

    p = sub.add_parser("bench", help="env-steps/s of the captured step vs the bare solver on the same model")
    p.add_argument("--task", default=DEFAULT_TASK_ID)
    p.add_argument("--num-envs", type=int, default=4)
    p.add_argument("--steps", type=int, default=200)
    p.add_argument("--device", default=None)
    p.set_defaults(func=_cmd_bench)

    p = sub.add_parser("bench-train", help="diffusion-policy training steps/s: eager vs CUDA-graph step")
    p.add_argument("--dataset-path", required=True)
    p.add_argument("--batch-size", type=int, default=1024)
    p.add_argument("--steps", type=int, default=200)
    p.add_argument("--preset", default="default", choices=["default", "cpu"])
    p.add_argument("--device", default="cpu")
    p.set_defaults(func=_cmd_bench_train)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    _quiet_warp()
    try:
        return args.func(args)
    except (ValueError, FileNotFoundError, FileExistsError, KeyError, ConnectionError) as exc:
        msg = exc.args[0] if exc.args else str(exc)
        print(f"newton-lab {args.command}: error: {msg}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
