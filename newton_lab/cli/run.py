"""What each ``newton-lab`` command does with its argument object (``newton_lab.commands``); each prints its
result (one JSON line last) and returns the exit status.

The library imports are deferred into the commands on purpose: Warp/Newton (envs), torch (policies) and
Prefect (flows) each take seconds to import, and a command pays only for what it runs.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from ..commands import BenchRefusalsArgs, RenderArgs, ResultsArgs, SuiteArgs, TrainRLArgs, camera_option
from ..commands import (BenchArgs, BenchCollectArgs, BenchTrainArgs, CollectArgs, EvaluateArgs, ExportArgs, MimicArgs,
                        PipelineArgs, RerunArgs, SplitArgs, TasksArgs, TrainArgs, ViewArgs)
from ..flows.report import summary_lines
from ..flows.settings import configure, demo_recipe
from ..flows.suite_rows import rows_of
from ..records import command_wall_s, default_path, make_record, write_record
from ..results import update
from ..task_api.registry import list_tasks, lookup
from .headers import checkpoint_header
from .pipeline_ends import ends_in_one_line

COLLECT_REPORT_KEYS = ("task", "episodes", "successes", "success_rate", "path", "num_envs", "average_length",
                       "termination_reasons", "diverged", "subtask_signals")
"""Keys of the collect summary printed by ``newton-lab collect`` (then ``wall_time_s``)."""


def rerun_hook(args: RerunArgs, env):
    """A rerun ``on_step`` hook when --rerun / --rerun-save is given, else None (and a closer)."""
    if not (args.rerun or args.rerun_save):
        return None, lambda: None
    from ..viz import RerunLogger  # deferred: rerun-sdk is slow to import

    lg = RerunLogger(env, save=args.rerun_save, spawn=args.rerun and not args.rerun_save, max_worlds=args.rerun_worlds,
                     image_every=args.rerun_image_every)

    def close() -> None:
        lg.close()
        if lg.path is not None:
            print(f"rerun recording: {lg.path} (open it with: rerun {lg.path})")

    return lg.on_step, close


def list_task_ids(args: TasksArgs) -> int:
    from .. import tasks as _registered  # noqa: F401  deferred: registering the tasks imports Warp

    for task_id in list_tasks():
        print(f"{task_id}\t{lookup(task_id).description}")
    return 0


def collect(args: CollectArgs) -> int:
    from ..agents import expert_agent  # deferred: Warp/Newton are slow to import
    from ..envs import make_env  # deferred: Warp/Newton are slow to import

    env = make_env(args.task, **args.env_kwargs())
    agent = expert_agent(env)
    hook, close = rerun_hook(args, env)
    try:
        summary = env.collect(agent=agent, on_step=hook, **args.collect_kwargs())
    finally:
        close()
    print(json.dumps({
        **{k: summary[k] for k in COLLECT_REPORT_KEYS},
        "wall_time_s": round(summary["wall_time_s"], 2),
        **({"saved_end_scenario_path": summary["saved_end_scenario_path"]} if args.save_end_scenario else {}),
    }))
    return 0


def load_agent(path: str, device: str):
    """The agent of a policy checkpoint: a diffusion policy (``train``) or a PPO actor (``train-rl``), by its
    format tag (read without loading the weights)."""
    from ..policies.agent import PolicyAgent  # deferred: torch is slow to import
    from ..policies.rl.agent import CHECKPOINT_FORMAT as RL_FORMAT, RLPolicyAgent  # deferred: as above

    if checkpoint_header(path)["format"] == RL_FORMAT:
        return RLPolicyAgent.from_checkpoint(path, device=device)
    return PolicyAgent.from_checkpoint(path, device=device)


def evaluate(args: EvaluateArgs) -> int:
    from ..agents import expert_agent  # deferred: Warp/Newton are slow to import
    from ..envs import make_env  # deferred: Warp/Newton are slow to import
    from ..envs.rollout import EVAL_REPORT_KEYS  # deferred: Warp/Newton are slow to import
    from ..policies.agent import phase_policy_agent  # deferred: torch is slow to import

    checkpoint_agent = load_agent(args.checkpoint, args.policy_device()) if args.checkpoint else None
    env = make_env(args.task, **args.env_kwargs())
    phases = args.phase_checkpoints()
    agent = (phase_policy_agent(env, phases, device=args.policy_device()) if phases
             else checkpoint_agent or expert_agent(env))
    hook, close = rerun_hook(args, env)
    try:
        summary = env.evaluate(agent=agent, on_step=hook, **args.rollout_kwargs())
    finally:
        close()
    print(json.dumps({k: summary[k] for k in EVAL_REPORT_KEYS}))
    return 0


def mimic(args: MimicArgs) -> int:
    from ..mimic import mimic as generate  # deferred: Warp/Newton are slow to import

    ref = generate(args.dataset_path, **args.mimic_kwargs())
    m = ref.metadata
    wall = m.get("wall_time_s") or 0.0  # the generation loop (env and sources built before it)
    print(json.dumps({"task": ref.task_id, "successes": m["successes"], "attempts": m["attempts"],
                      "generation_success_rate": m["generation_success_rate"], "path": str(ref.path),
                      "wall_time_s": wall, "demos_per_hour": m["successes"] / wall * 3600.0 if wall else None}))
    return 0


def train(args: TrainArgs) -> int:
    from ..policies import Policy  # deferred: torch is slow to import
    from ..policies.diffusion import PRESETS  # deferred: torch is slow to import

    path = Policy.from_backend("diffusion").train(args.datasets(), args.train_cfg(PRESETS), resume=args.resume,
                                                  gpus=args.gpus)
    print(json.dumps({"checkpoint": str(path)}))
    return 0


def train_rl(args: TrainRLArgs) -> int:
    out_dir = Path(args.output_dir)  # refused before rsl_rl, torch and Warp load
    if args.resume and not (out_dir / "resume.pt").is_file():
        raise FileNotFoundError(f"nothing to resume in {out_dir} (no resume.pt); start the run without --resume")
    if not args.resume and (out_dir / "checkpoint.pt").exists():
        raise FileExistsError(f"{out_dir} holds a finished run; choose a new --output-dir (or --resume an "
                              "interrupted one)")
    from ..policies.rl.train import train_ppo  # deferred: rsl_rl, torch and Warp are slow to import

    path = train_ppo(args.task, args.ppo_config(), args.output_dir, resume=args.resume)
    curve = json.loads((path.parent / "curve.json").read_text())
    final = curve[-1] if curve else {}
    out = {"checkpoint": str(path), "curve": str(path.parent / "curve.json"), "iterations": final.get("iteration"),
           "env_steps": final.get("env_steps"), "wall_s": final.get("wall_s"), "num_envs": args.num_envs,
           "success_rate": final.get("success_rate"), "env_steps_per_s": final.get("env_steps_per_s")}
    if args.eval_episodes:  # the actor on held-out scenes: a seed the training never drew from
        from ..envs import make_env  # deferred: Warp/Newton are slow to import
        from ..policies.rl.agent import RLPolicyAgent  # deferred: torch is slow to import

        env = make_env(args.task, num_envs=min(args.eval_episodes, args.num_envs), device=args.device,
                       seed=args.seed + 10_000, randomize=True, task_options=dict(args.task_options), cameras=False)
        agent = RLPolicyAgent.from_checkpoint(path, device=str(env.torch_device))
        s = env.evaluate(agent=agent, episodes=args.eval_episodes, progress=False)
        out["evaluation"] = {"episodes": s["episodes"], "successes": s["successes"], "rate": s["success_rate"],
                             "eval_seed": args.seed + 10_000}
    write_run_record("train-rl", args, args.task, args.device, {**out, "curve_rows": curve})
    print(json.dumps(out))
    return 0


def split(args: SplitArgs) -> int:
    from ..datasets import split_by_phase, split_train_val  # deferred: the dataset package imports Warp/Newton

    if args.out is None:
        keys = split_train_val(args.dataset_path, args.val_ratio, seed=args.seed, filter_key=args.filter_key)
        print(json.dumps({"path": str(args.dataset_path), "filter_keys": {k: len(v) for k, v in keys.items()}}))
        return 0
    refs = split_by_phase(args.dataset_path, args.out, phases=args.phase_names())
    print(json.dumps({name: {"path": str(r.path), "task": r.task_id, "episodes": r["episodes"]}
                      for name, r in refs.items()}))
    return 0


def export(args: ExportArgs) -> int:
    from ..datasets.lerobot import export_lerobot  # deferred: pyarrow, Warp/Newton are slow

    out = export_lerobot(args.dataset_path, args.root, include_failed=args.include_failed, video=not args.no_video)
    keys = ("root", "repo_id", "episodes", "frames", "skipped_failed", "fps", "image_keys", "video_files")
    print(json.dumps({k: out[k] for k in keys}))
    return 0


def pipeline(args: PipelineArgs) -> int:
    from .. import tasks as _registered  # noqa: F401  deferred: registering the tasks imports Warp

    long_horizon = bool(lookup(args.task).make_cfg({}).phases)  # a coherent task: the long-horizon flow
    recipe = demo_recipe(args.recipe, args.device, long_horizon=long_horizon)
    kwargs = args.pipeline_kwargs(recipe)
    if args.dry_run:  # the plan only: nothing is collected, trained or written, Prefect is not started
        stages = (["collect", "split", "train per learned phase", "evaluate composed"] if long_horizon
                  else ["collect", "mimic", "train", "evaluate"])
        print(json.dumps({"plan": {**kwargs, "long_horizon": long_horizon, "stages": stages}}, default=str))
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
    print(json.dumps({"task": summary["task"], "success_rate": summary["success_rate"], "metrics": str(metrics),
                      "record": summary["record"]}))
    return 0


def view(args: ViewArgs) -> int:
    from ..viz import replay_episode  # deferred: rerun-sdk is slow to import

    if not args.save and not args.spawn:
        raise ValueError("view needs --save file.rrd (headless) or --spawn (open a rerun viewer)")
    poses = replay_episode(args.dataset, args.episode, save=args.save, spawn=args.spawn)
    if args.save:
        print(f"rerun recording: {Path(args.save).resolve()} (open it with: rerun {Path(args.save).resolve()})")
    print(json.dumps({"dataset": args.dataset, "episode": args.episode, "frames": len(poses), "rrd": args.save}))
    return 0


def write_run_record(kind: str, args, task: str | None, device: str | None, results: dict) -> None:
    """The benchmark's run record at ``--run-record`` (default under outputs/records/); its path on stderr."""
    rec = make_record(kind, task=task, device=device, results=results, wall_s=command_wall_s())
    path = write_record(rec, args.run_record or default_path(kind, task))
    print(f"run record: {path}", file=sys.stderr)


def bench(args: BenchArgs) -> int:
    from ..bench import bench as measure  # deferred: Warp/Newton are slow to import

    cam = {} if args.camera is None else {"camera": args.camera, "resolution": tuple(args.resolution or (128, 128)),
                                          "camera_data": tuple(args.camera_data or ("rgb",))}
    out = measure(args.task, num_envs=args.num_envs, steps=args.steps, device=args.device, **cam)
    write_run_record("bench", args, args.task, args.device, out)
    print(json.dumps(out))
    return 0


def bench_collect(args: BenchCollectArgs) -> int:
    from ..bench_collect import bench_collect, bench_collect_on_workers, summary  # deferred: Warp is slow to import

    common = {"num_envs": args.num_envs, "episodes": args.episodes, "device": args.device,
              "dataset_path": args.dataset_path, "writer": args.writer, "cameras": camera_option(args.cameras),
              "task_options": dict(args.task_options)}
    if args.workers == 1:
        if args.baseline:
            raise ValueError("--baseline compares --workers W (W >= 2) with one worker alone; add --workers 2")
        out = bench_collect(args.task, prefill=args.prefill, replan_batch=args.replan_batch,
                            replan_wait=args.replan_wait, trace=args.trace, trace_after=args.trace_after, **common)
        print(summary(out), file=sys.stderr, flush=True)
    else:
        if (args.replan_batch, args.replan_wait, args.trace) != (None, None, None):
            raise ValueError("--replan-batch, --replan-wait and --trace are for one process (--workers 1)")
        out = bench_collect_on_workers(args.task, workers=args.workers, baseline=args.baseline, **common)
    write_run_record("bench-collect", args, args.task, args.device, out)
    print(json.dumps(out))
    return 0


def bench_train(args: BenchTrainArgs) -> int:
    from ..bench import bench_train as measure  # deferred: torch is slow to import

    out = measure(args.dataset_path, batch_size=args.batch_size, steps=args.steps, device=args.device,
                  preset=args.preset, bf16=args.bf16)
    write_run_record("bench-train", args, out.get("task"), args.device, out)
    print(json.dumps(out))
    return 0


def bench_refusals(args: BenchRefusalsArgs) -> int:
    from .bench_refusals import bench_refusals as measure  # deferred: its sample files need h5py, zarr and torch

    def progress(case: dict) -> None:
        if not case["refused"]:
            print(f"not refused as the table says: newton-lab {case['argv']} (exit {case['exit']}, one line "
                  f"{case['one_line']}, words {case['words']}, folder unchanged {case['unchanged']})", file=sys.stderr)

    out = measure(args.only, on_case=progress)
    write_run_record("bench-refusals", args, None, "cpu", out)
    print(json.dumps({k: v for k, v in out.items() if k != "per_case"}))
    return 0 if out["refused"] == out["cases"] else 1


def suite(args: SuiteArgs) -> int:
    rows = rows_of(args.recipe, args.only)
    if args.dry_run:
        for row in rows:
            print(f"{row.name}: newton-lab {' '.join(row.command(Path(args.out), '<UTC time>'))}")
        return 0
    configure(Path(args.out) / ".prefect")  # before Prefect is imported
    from ..flows.suite import suite as run_suite  # deferred: Prefect is slow to import, and after configure

    summary = run_suite(recipe=args.recipe, out=str(Path(args.out).resolve()), records=args.records, page=args.page,
                        only=args.only)
    for r in summary["rows"]:
        state = "ok" if r["exit"] == 0 else f"failed (exit {r['exit']})"
        print(f"{r['row']:<32} {state:<18} {r.get('record', '')}")
    print(json.dumps({"recipe": args.recipe, "failed": [r["row"] for r in summary["rows"] if r["exit"] != 0],
                      "page": summary.get("page")}))
    return 0 if all(r["exit"] == 0 for r in summary["rows"]) else 1


def results(args: ResultsArgs) -> int:
    fresh = update(args.page, args.records, check=args.check)
    if args.check and not fresh:
        print(f"{args.page} does not match the run records in {args.records}; run `newton-lab results` to "
              "regenerate it", file=sys.stderr)
        return 1
    print(f"{args.page}: {'up to date' if fresh else 'regenerated'} from {args.records}")
    return 0


def _check_render(args: RenderArgs) -> None:
    """One-line errors for a ``render`` request (before Warp is imported)."""
    from ..robots.registry import camera_facts  # deferred: numpy, only for this command

    mounts, min_side, max_side = camera_facts()
    if args.camera not in mounts:
        raise ValueError(f"--camera {args.camera!r} is unknown; the G1's cameras are {', '.join(mounts)}")
    res = args.resolution
    if res is not None and (len(res) != 2 or not all(min_side <= v <= max_side for v in res)):
        raise ValueError(f"--resolution takes width and height in [{min_side}, {max_side}] px, got "
                         f"{' '.join(map(str, res))}; e.g. --resolution 298 224")
    if args.expert_steps < 0:
        raise ValueError(f"--expert-steps must be >= 0, got {args.expert_steps}")
    if Path(args.out).suffix.lower() != ".png":
        raise ValueError(f"--out {args.out}: the picture is a PNG; name it e.g. render.png")


def render(args: RenderArgs) -> int:
    _check_render(args)  # before Warp is imported
    from PIL import Image  # deferred: only this command writes pictures

    from ..datasets.outputs import output_path  # deferred: the datasets package imports h5py and zarr (~1 s)

    from ..agents import expert_agent  # deferred: Warp/Newton are slow to import
    from ..envs import make_env  # deferred: Warp/Newton are slow to import
    from ..envs.cameras import picture  # deferred: Warp/Newton are slow to import

    view = {"data": ("rgb", "depth", "segmentation")}
    if args.resolution:
        view["resolution"] = tuple(args.resolution)
    env = make_env(args.task, **args.env_kwargs(), cameras={args.camera: view})
    if args.expert_steps:
        agent = expert_agent(env)
        for _ in range(args.expert_steps):
            env.step(agent.act(env))
    images = env.render()
    output_path(args.out)
    Image.fromarray(picture(images, args.camera)).save(args.out)
    cam, names = env.cameras.specs[args.camera], env.cameras.segmentation_names
    seen = images[f"{args.camera}_segmentation"][0].unique().tolist()
    print(json.dumps({"task": args.task, "camera": args.camera, "resolution": [cam.width, cam.height],
                      "visible": [names[i] for i in seen], "out": args.out}))
    return 0
