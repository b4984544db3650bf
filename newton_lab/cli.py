"""The ``newton-lab`` console script: ``tasks``, ``collect``, ``evaluate``, ``bench``."""

from __future__ import annotations

import argparse
import json
import sys


def _quiet_warp() -> None:
    import warp as wp

    wp.config.quiet = True  # no init banner
    wp.config.log_level = wp.LOG_WARNING  # no per-module load lines


def _add_env_flags(p: argparse.ArgumentParser, *, episodes: int = 1, max_steps: int = 1000) -> None:
    from .registry import DEFAULT_TASK_ID

    p.add_argument("--task", default=DEFAULT_TASK_ID, help="task id (see `newton-lab tasks`)")
    p.add_argument("--episodes", type=int, default=episodes)
    p.add_argument("--num-envs", type=int, default=1)
    p.add_argument("--max-steps", type=int, default=max_steps, help="episode step limit of the loop")
    p.add_argument("--device", default=None, help="Warp device, e.g. cpu or cuda:0 (default: Warp's)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--randomize", action="store_true", help="turn on the task's reset randomisation")
    p.add_argument("--headless", action="store_true", help="accepted for compatibility; newton-lab never opens a window")
    p.add_argument("--no-progress", action="store_true")


def _cmd_tasks(args) -> int:
    from .registry import list_tasks, lookup

    for task_id in list_tasks():
        print(f"{task_id}\t{lookup(task_id).get('description', '')}")
    return 0


def _make(args):
    from .envs import make_env

    return make_env(args.task, num_envs=args.num_envs, device=args.device, seed=args.seed, randomize=args.randomize)


def _cmd_collect(args) -> int:
    from .agents import PlannerAgent

    env = _make(args)
    agent = PlannerAgent.from_task(args.task)
    summary = env.collect(agent=agent, episodes=args.episodes, path=args.dataset_path, max_steps=args.max_steps,
                          progress=not args.no_progress)
    print(json.dumps({
        "task": summary["task"],
        "episodes": summary["episodes"],
        "successes": summary["successes"],
        "success_rate": summary["success_rate"],
        "path": summary["path"],
        "num_envs": summary["num_envs"],
        "average_length": summary["average_length"],
        "termination_reasons": summary["termination_reasons"],
        "wall_time_s": round(summary["wall_time_s"], 2),
    }))
    return 0


def _cmd_evaluate(args) -> int:
    from .agents import PlannerAgent

    env = _make(args)
    summary = env.evaluate(agent=PlannerAgent.from_task(args.task), episodes=args.episodes,
                           max_steps=args.max_steps, progress=not args.no_progress)
    keys = ("task", "episodes", "successes", "success_rate", "average_length", "termination_reasons")
    print(json.dumps({k: summary[k] for k in keys}))
    return 0


def _cmd_bench(args) -> int:
    from .bench import bench

    print(json.dumps(bench(args.task, num_envs=args.num_envs, steps=args.steps, device=args.device)))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="newton-lab", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("tasks", help="list registered task ids").set_defaults(func=_cmd_tasks)

    p = sub.add_parser("collect", help="collect expert episodes into HDF5 (.hdf5/.h5) or zarr (.zarr)")
    _add_env_flags(p)
    p.add_argument("--dataset-path", default="data/pick_cube_demos.hdf5")
    p.set_defaults(func=_cmd_collect)

    p = sub.add_parser("evaluate", help="run the expert planner and report the success rate")
    _add_env_flags(p)
    p.set_defaults(func=_cmd_evaluate)

    p = sub.add_parser("bench", help="env-steps/s of the captured step vs the bare solver on the same model")
    from .registry import DEFAULT_TASK_ID

    p.add_argument("--task", default=DEFAULT_TASK_ID)
    p.add_argument("--num-envs", type=int, default=4)
    p.add_argument("--steps", type=int, default=200)
    p.add_argument("--device", default=None)
    p.set_defaults(func=_cmd_bench)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    _quiet_warp()
    try:
        return args.func(args)
    except (ValueError, FileNotFoundError, FileExistsError, KeyError) as exc:
        msg = exc.args[0] if exc.args else str(exc)
        print(f"newton-lab {args.command}: error: {msg}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
