"""Every registered task's expert over randomised episodes on the CPU: one JSON line per task.

    python tools/expert_success.py [--episodes 8] [--num-envs 4] [--seed 100] [--tasks ID ...]

The figure behind "every task's expert success unchanged": run it before and after a change to the task
terms and compare the lines (the same seed gives the same episodes). Teleop variants (no expert, the operator
ends the episode) are skipped; coherent tasks run their component experts phase by phase (``expert_agent``).
SortToShelf ids run once per sorting object.
"""

from __future__ import annotations

import argparse
import json
import time

import newton_lab.tasks  # noqa: F401  (registers every task id)

from newton_lab.agents import expert_agent
from newton_lab.envs import make_env
from newton_lab.task_api.registry import list_tasks, lookup


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=8)
    ap.add_argument("--num-envs", type=int, default=4)
    ap.add_argument("--seed", type=int, default=100)
    ap.add_argument("--max-steps", type=int, default=3000)
    ap.add_argument("--tasks", nargs="*", default=None)
    args = ap.parse_args()
    for task_id in args.tasks or list_tasks():
        spec = lookup(task_id)
        if spec.expert is None and not spec.cfg().phases:  # the operator's variant: no expert
            continue
        for options in spec.choice_sets():
            t0 = time.perf_counter()
            env = make_env(
                task_id,
                num_envs=args.num_envs,
                device="cpu",
                seed=args.seed,
                randomize=True,
                task_options=options,
                cameras=False,
            )
            summary = env.evaluate(
                agent=expert_agent(env), episodes=args.episodes, max_steps=args.max_steps, progress=False
            )
            print(
                json.dumps(
                    {
                        "task": task_id,
                        **options,
                        "episodes": args.episodes,
                        "success_rate": summary["success_rate"],
                        "termination_reasons": summary.get("termination_reasons"),
                        "seconds": round(time.perf_counter() - t0, 1),
                    }
                ),
                flush=True,
            )


if __name__ == "__main__":
    main()
