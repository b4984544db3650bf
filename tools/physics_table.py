"""A task's physics settings against variants of them: env-steps/s and expert success, side by side in one process,
as a markdown table (benchmarks history, "Per-task physics settings").

    python tools/physics_table.py [--device cuda:0] [--num-envs 4096] [--episodes 100] [--tasks ID ...]
        [--variant iterations=5,contact_filter=gripper_only ...] [--out table.md]

For each task, the ``task`` row is its ``TaskCfg.physics``, and each ``--variant`` adds a row with those fields
replaced (``contact_filter=gripper_only``: only the left gripper touches the scene;
``contact_filter=left_arm+left_gripper``: those robot groups, each with every scene object; ``contact_filter=None``:
no filter): ``newton_lab.bench.bench`` times the captured env step at ``--num-envs`` rows (state only, the same code as
``newton-lab bench``), then the task's expert runs ``--episodes`` randomised episodes as that many parallel rows (at
most ``--eval-envs``; the same seed for every setting, so every setting sees the same episodes). Tasks with choices
(SortToShelf's objects) split the episodes evenly over them. Progress goes to stderr, the table to stdout.
CPU check at tiny size: ``--device cpu --num-envs 2 --episodes 2 --tasks GalbotG1-PickCube-v0``.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import gc
import json
import sys
import time

import newton_lab.tasks  # noqa: F401  (registers every task id)

from newton_lab.agents import expert_agent
from newton_lab.bench import bench
from newton_lab.envs import make_env
from newton_lab.task_api.physics import PhysicsCfg, gripper_only
from newton_lab.task_api.registry import lookup

TASKS = ("GalbotG1-PickCube-v0", "GalbotG1-StackCube-v0", "GalbotG1-PickToShelf-v0", "GalbotG1-SortToShelf-v0")


def _variant(text: str) -> dict:
    """``iterations=3,cone=pyramidal`` -> {"iterations": 3, "cone": "pyramidal"} (``PhysicsCfg`` fields)."""
    out = {}
    for part in filter(None, text.split(",")):
        key, _, value = part.partition("=")
        if key not in {f.name for f in dataclasses.fields(PhysicsCfg)} or not value:
            raise SystemExit(
                f"--variant {text!r}: use field=value[,...] over PhysicsCfg's fields, e.g. "
                f"iterations=3,cone=pyramidal (contact_filter: None, gripper_only or robot groups "
                f"joined by '+', e.g. left_arm+left_gripper)"
            )
        if key == "contact_filter" and value != "None":
            # gripper_only: the left gripper alone; "a+b": those robot groups, each with every scene object
            out[key] = gripper_only(*([] if value == "gripper_only" else value.split("+")))
            continue
        try:
            out[key] = ast.literal_eval(value)
        except (ValueError, SyntaxError):
            out[key] = value
    return out


def _settings(task_id: str, variants: list[str]) -> list[tuple[str, PhysicsCfg]]:
    own = lookup(task_id).make_cfg({}).physics
    rows = [("task", own)]
    return rows + [(v, dataclasses.replace(own, **_variant(v))) for v in variants]


def _success(
    task_id: str, physics: PhysicsCfg, *, episodes: int, eval_envs: int, device: str, seed: int, max_steps: int
) -> tuple[int, int]:
    """(successes, episodes) of the task's expert over ``episodes`` randomised episodes, split over its choices."""
    choices = list(lookup(task_id).choice_sets())
    ok = total = 0
    for i, options in enumerate(choices):
        share = episodes // len(choices) + (i < episodes % len(choices))
        if share == 0:
            continue
        env = make_env(
            task_id,
            num_envs=min(share, eval_envs),
            device=device,
            seed=seed,
            randomize=True,
            task_options=options,
            cameras=False,
            physics=physics,
        )
        summary = env.evaluate(agent=expert_agent(env), episodes=share, max_steps=max_steps, progress=False)
        ok, total = ok + int(summary["successes"]), total + share
        del env
        gc.collect()
    return ok, total


def _describe(p: PhysicsCfg) -> str:
    text = f"{p.iterations}/{p.ls_iterations} it, {p.cone}"
    if p.tolerance is not None:
        text += f", tol {p.tolerance:g}"
    if p.contacts_per_world or p.constraints_per_world:
        text += f", cap {p.contacts_per_world or '-'}c/{p.constraints_per_world or '-'}r"
    if p.contact_filter is not None:
        text += ", filter " + " ".join(f"{g}:{'+'.join(t) or '-'}" for g, t in p.contact_filter.robot.items())
    if p.weld_idle_joints:
        text += ", idle joints welded"
    return text


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default=None, help="Warp device (default: Warp's)")
    ap.add_argument("--num-envs", type=int, default=4096, help="rows of the timed env step")
    ap.add_argument("--steps", type=int, default=200, help="env steps timed per setting")
    ap.add_argument("--episodes", type=int, default=100, help="expert episodes per setting (0: no success column)")
    ap.add_argument("--eval-envs", type=int, default=100, help="most parallel rows of the expert runs")
    ap.add_argument("--seed", type=int, default=100)
    ap.add_argument("--max-steps", type=int, default=3000, help="expert episode step limit")
    ap.add_argument("--tasks", nargs="*", default=list(TASKS))
    ap.add_argument(
        "--variant",
        action="append",
        default=[],
        help="also the task's physics with these fields replaced, e.g. iterations=3,ls_iterations=3 (repeatable)",
    )
    ap.add_argument("--out", default=None, help="also write the table to this file")
    args = ap.parse_args()

    rows, t_start = [], time.perf_counter()
    for task_id in args.tasks:
        task_rate = None
        for name, physics in _settings(task_id, args.variant):
            t0 = time.perf_counter()
            r = bench(task_id, num_envs=args.num_envs, steps=args.steps, device=args.device, physics=physics)
            gc.collect()
            ok, n = (
                _success(
                    task_id,
                    physics,
                    episodes=args.episodes,
                    eval_envs=args.eval_envs,
                    device=args.device,
                    seed=args.seed,
                    max_steps=args.max_steps,
                )
                if args.episodes > 0
                else (0, 0)
            )
            rate = r["env_steps_per_s"]
            task_rate = task_rate or rate
            rows.append(
                [
                    task_id.removeprefix("GalbotG1-"),
                    name,
                    _describe(physics),
                    f"{rate:,.0f}",
                    f"{rate / task_rate:.2f}x",
                    f"{r['ratio_env_step_to_bare']:.3f}",
                    f"{ok}/{n} ({100 * ok / n:.0f} %)" if n else "–",
                ]
            )
            print(
                json.dumps(
                    {
                        "task": task_id,
                        "setting": name,
                        "env_steps_per_s": rate,
                        "ratio_env_step_to_bare": r["ratio_env_step_to_bare"],
                        "successes": ok,
                        "episodes": n,
                        "seconds": round(time.perf_counter() - t0, 1),
                    }
                ),
                file=sys.stderr,
                flush=True,
            )
            device_name = f"{r['device_name']} ({r['device']})"
    header = [
        "task",
        "setting",
        "physics",
        f"env-steps/s @ {args.num_envs}",
        "vs task",
        "env / bare",
        f"expert success (seed {args.seed})",
    ]
    lines = [
        f"Device: {device_name}; {time.strftime('%Y-%m-%d')}; {time.perf_counter() - t_start:.0f} s in all.",
        "",
        "| " + " | ".join(header) + " |",
        "|" + "---|" * len(header),
    ]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    table = "\n".join(lines)
    print(table)
    if args.out:
        with open(args.out, "w") as f:
            f.write(table + "\n")


if __name__ == "__main__":
    main()
