"""``newton-lab train-rl``: PPO (rsl_rl) on a task's dense reward, its curve and an optional held-out evaluation,
written as a run record (arguments: ``newton_lab.commands.rl``; the output folder is checked before rsl_rl, torch
and Warp load)."""

from __future__ import annotations

import json

from ..commands import TrainRLArgs
from ..records import write_run_record


def train_rl(args: TrainRLArgs) -> int:
    from ..policies.rl.train import run_summary, train_ppo  # deferred: rsl_rl, torch and Warp are slow to import

    path = train_ppo(args.task, args.ppo_config(), args.output_dir, resume=args.resume)
    curve = json.loads((path.parent / "curve.json").read_text())
    out = {
        "checkpoint": str(path),
        "curve": str(path.parent / "curve.json"),
        **run_summary(curve),
        "num_envs": args.num_envs,
    }
    if args.eval_episodes:  # the actor on held-out scenes: a seed the training never drew from
        from ..envs import make_env  # deferred: Warp/Newton are slow to import
        from ..policies.rl.agent import RLPolicyAgent  # deferred: torch is slow to import

        env = make_env(
            args.task,
            num_envs=min(args.eval_episodes, args.num_envs),
            device=args.device,
            seed=args.seed + 10_000,
            randomize=True,
            task_options=dict(args.task_options),
            cameras=False,
        )
        agent = RLPolicyAgent.from_checkpoint(path, device=str(env.torch_device))
        s = env.evaluate(agent=agent, episodes=args.eval_episodes, progress=False)
        out["evaluation"] = {
            "episodes": s["episodes"],
            "successes": s["successes"],
            "rate": s["success_rate"],
            "eval_seed": args.seed + 10_000,
        }
    results = {**out, "curve_rows": curve}
    write_run_record("train-rl", args.run_record, task=args.task, device=args.device, results=results)
    print(json.dumps(out))
    return 0
