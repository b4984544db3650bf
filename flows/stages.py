"""The pipeline's stages as plain functions over artifacts (Prefect wraps them in ``pipeline``); collect,
Mimic and evaluation take the command argument objects of ``newton_lab.commands`` (the CLI's own model).

Every stage writes its output next to a manifest (``<name>.manifest.json``) naming the
inputs that produced it: re-running with the same inputs reuses the output, and an output folder that
holds another pipeline's artifacts is refused instead of overwritten.
"""

from __future__ import annotations

import concurrent.futures
import json
import multiprocessing
import shutil
import time
from pathlib import Path
from typing import Any

from ..commands import CollectArgs, EvaluateArgs, MimicArgs
from ..datasets.files.inside_root import contained
from ..datasets.files.output_paths import output_path
from .artifacts import artifact

BACKEND = "diffusion"
"""The pipeline's policy backend: ``train_stage`` trains with it, ``evaluate_stage`` loads through it."""


def _guard(out_dir: Path, name: str, inputs: dict[str, Any]) -> dict[str, Any] | None:
    """The finished artifact of ``name`` if it was made from ``inputs``; raises if made from others."""
    manifest = out_dir / f"{name}.manifest.json"
    if not manifest.exists():
        return None
    saved = json.loads(manifest.read_text())
    if saved["inputs"] != json.loads(json.dumps(inputs)):
        raise ValueError(f"{out_dir} holds another pipeline's {name} ({manifest}); use a new --out folder")
    if not contained(out_dir, saved["artifact"]["path"], f"{manifest} artifact path").exists():
        return None
    return saved["artifact"]


def _finish(out_dir: Path, name: str, inputs: dict[str, Any], art: dict[str, Any]) -> dict[str, Any]:
    tmp = out_dir / f".{name}.manifest.json.tmp"
    tmp.write_text(json.dumps({"inputs": inputs, "artifact": art}, indent=1))
    tmp.replace(out_dir / f"{name}.manifest.json")
    return art


def dataset_samples(path: str | Path) -> int:
    """Steps (samples) summed over the dataset's episodes."""
    from ..datasets import read_dataset_info  # deferred: the datasets package imports h5py and zarr

    return read_dataset_info(path)["total"]


def _fresh(path: Path) -> Path:
    """Remove a leftover partial output of an interrupted run (never a finished one: those have manifests)."""
    if path.exists():
        shutil.rmtree(path) if path.is_dir() else path.unlink()
    return path


def collect_stage(*, args: CollectArgs, name: str = "demos") -> dict[str, Any]:
    """Expert demos (the task's expert) -> dataset artifact at ``args.dataset_path`` (its folder holds the
    manifest ``<name>.manifest.json``)."""
    path = Path(args.dataset_path)
    out = output_path(path).parent
    inputs = {
        "stage": "collect",
        "task_id": args.task,
        "episodes": args.episodes,
        "num_envs": args.num_envs,
        "seed": args.seed,
        **({"domain_randomize": args.domain_randomization()} if args.domain_randomize else {}),
        **({"distractors": args.distractors} if args.distractors else {}),
    }
    if (done := _guard(out, name, inputs)) is not None:
        return done
    _fresh(path)
    t0 = time.perf_counter()
    ref = _on_device(args.device, _collect, args)
    t1 = time.perf_counter()
    art = artifact(
        path,
        "dataset",
        episodes=ref["episodes"],
        successes=ref["successes"],
        success_rate=ref["success_rate"],
        samples=dataset_samples(path),
    )
    art["metrics"]["seconds"] = {
        **ref["stage_seconds"],
        "loop": round(ref["wall_time_s"], 2),
        "call": round(t1 - t0, 2),
        "hash": round(time.perf_counter() - t1, 2),
    }
    return _finish(out, name, inputs, art)


COLLECT_SECONDS = {
    "call": "the collection's call: its own process on a GPU (start-up and imports), env and writer included",
    "env_build": "make_env: the scene, the model and the env's buffers",
    "collect": "env.collect: the episode loop, then the writer draining what the loop handed it",
    "loop": "the episode loop alone (Warp's first kernel compile included)",
    "hash": "the dataset's content hash and sample count, after the call",
}
"""Where a collect stage's seconds went (``metrics["seconds"]`` of its artifact, ``collect_seconds`` of a
pipeline's run record: those of the run that made the artifact, also in a re-run answered from the cache)."""


def _collect(args: CollectArgs) -> dict[str, Any]:
    from ..agents import expert_agent  # deferred: Warp/Newton are slow to import
    from ..envs import make_env  # deferred: Warp/Newton are slow to import
    from ..envs.perturb import collect_randomized  # deferred: Warp/Newton are slow to import

    t0 = time.perf_counter()
    env = make_env(args.task, **args.env_kwargs())
    t1 = time.perf_counter()
    ref = collect_randomized(
        env, args.domain_randomization(), seed=args.seed, agent=expert_agent(env), **args.collect_kwargs()
    )
    ref.metadata["stage_seconds"] = {"env_build": round(t1 - t0, 2), "collect": round(time.perf_counter() - t1, 2)}
    return ref


def _on_device(device: str | None, fn, *args):
    """``fn(*args)``, in a spawned process of its own when ``device`` (Warp's default when ``None``) is a CUDA
    device. The env's buffers and the Warp and torch memory pools of that process go back to the device when the
    stage ends; in the flow's process they stayed reserved through the trainings and the evaluation that follow
    (24-30 GB a pipeline after a 300-row SortToShelf collection with two cameras, and the trainings of four
    pipelines side by side on one H200 ran out of memory)."""
    import warp as wp  # deferred: Warp is slow to import

    if not wp.get_device(device).is_cuda and not IN_OWN_PROCESS_ON_CPU:
        return fn(*args)
    return _in_own_process(fn, *args)


def _in_own_process(fn, *args):
    """``fn(*args)`` in a spawned process (a CUDA context of its own); its exception is raised here."""
    ctx = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(max_workers=1, mp_context=ctx) as pool:
        return pool.submit(fn, *args).result()


IN_OWN_PROCESS_ON_CPU = False
"""Tests set this to run the CUDA path (a process of its own per env stage) on the CPU."""


def mimic_stage(*, source: dict[str, Any], args: MimicArgs, name: str = "mimic") -> dict[str, Any]:
    """Mimic expansion of the source dataset artifact (``args.dataset_path`` is its path) -> dataset artifact
    at ``args.output_path`` (successes only)."""
    path = Path(args.output_path)
    out = output_path(path).parent
    inputs = {
        "stage": "mimic",
        "source": source["sha256"],
        "episodes": args.episodes,
        "num_envs": args.num_envs,
        "seed": args.seed,
    }
    if (done := _guard(out, name, inputs)) is not None:
        return done
    _fresh(path)
    m = _on_device(args.device, _mimic, args)
    art = artifact(
        path,
        "dataset",
        episodes=m["successes"],
        attempts=m["attempts"],
        generation_success_rate=m["generation_success_rate"],
        samples=dataset_samples(path),
    )
    return _finish(out, name, inputs, art)


def _mimic(args: MimicArgs) -> dict[str, Any]:
    from ..mimic import mimic  # deferred: Warp/Newton are slow to import

    return dict(mimic(args.dataset_path, **args.mimic_kwargs()).metadata)


def train_stage(
    *, dataset: dict[str, Any], train_cfg: dict[str, Any], out_dir: str, name: str = "policy", gpus: int = 1
) -> dict[str, Any]:
    """Diffusion policy on a dataset artifact -> checkpoint artifact (``gpus`` > 1: data-parallel). An interrupted
    run (its folder holds a ``resume.pt``) is continued; any other leftover of it is removed first."""
    from ..policies import Policy  # deferred: torch is slow to import
    from ..policies.resume import RESUME_NAME  # deferred: torch is slow to import

    out = Path(out_dir)
    inputs = {
        "stage": "train",
        "dataset": dataset["sha256"],
        "train_cfg": train_cfg,
        **({"gpus": gpus} if gpus > 1 else {}),
    }  # batch_size is per GPU: more GPUs, another run
    if (done := _guard(out, name, inputs)) is not None:
        return done
    run_dir = out / name
    resume = (run_dir / RESUME_NAME).is_file()
    for leftover in list(run_dir.iterdir()) if resume else [run_dir]:
        if leftover.name != RESUME_NAME:
            _fresh(leftover)
    cfg = {**train_cfg, "output_dir": str(run_dir)}
    if str(train_cfg.get("device", "cpu")).startswith("cuda") and gpus == 1:
        ckpt = _train_in_own_process(dataset["path"], cfg, resume)
    else:
        ckpt = Policy.from_backend(BACKEND).train(dataset["path"], cfg, resume=resume, gpus=gpus)
    log_path = Path(ckpt).parent / "train_log.json"
    log = json.loads(log_path.read_text()) if log_path.exists() else {}
    curve = [{k: e[k] for k in ("epoch", "steps", "loss", "lr")} for e in log.get("epoch_log", [])]
    return _finish(
        out,
        name,
        inputs,
        artifact(
            ckpt,
            "checkpoint",
            final_loss=log.get("final_loss"),
            steps=log.get("steps"),
            wall_time_s=log.get("wall_time_s"),
            loss_curve=curve,
        ),
    )


def _train(path: str, cfg: dict[str, Any], resume: bool) -> str:
    from ..policies import Policy  # deferred: torch is slow to import

    return str(Policy.from_backend(BACKEND).train(path, cfg, resume=resume))


def _train_in_own_process(path: str, cfg: dict[str, Any], resume: bool) -> str:
    """A CUDA training in a process of its own: the flow maps a coherent task's phase trainings onto threads of one
    process, and a CUDA-graph capture in one thread forbids the CUDA calls of another (torch's capture is
    process-global); processes also keep one training's failure from taking the flow down. Spawned, so the child
    has a CUDA context of its own."""
    return _in_own_process(_train, path, cfg, resume)


def rl_train_stage(*, task_id: str, ppo: dict[str, Any], out_dir: str, name: str = "ppo") -> dict[str, Any]:
    """PPO on ``task_id`` (``ppo``: ``PPOConfig`` fields) -> checkpoint artifact of kind ``rl checkpoint`` with the
    run's curve; an interrupted run (its folder holds a ``resume.pt``) continues from its last chunk."""
    from ..policies.rl.train import RESUME_NAME, PPOConfig, run_summary, train_ppo  # deferred: rsl_rl, torch

    out = Path(out_dir)
    inputs = {"stage": "train-rl", "task_id": task_id, "ppo": ppo}
    if (done := _guard(out, name, inputs)) is not None:
        return done
    run_dir = out / name
    resume = (run_dir / RESUME_NAME).is_file()
    if not resume:
        _fresh(run_dir)
    ckpt = train_ppo(task_id, PPOConfig(**ppo), run_dir, resume=resume)
    curve = json.loads((run_dir / "curve.json").read_text())
    summary = run_summary(curve)
    summary["wall_time_s"] = summary.pop("wall_s")
    return _finish(out, name, inputs, artifact(ckpt, "rl checkpoint", **summary, curve=curve))


def split_stage(
    *, source: dict[str, Any], out_dir: str, name: str = "phases", by_target: list[str] | None = None
) -> dict[str, dict[str, Any]]:
    """A coherent task's dataset artifact split by phase -> {phase name: dataset artifact} in ``<out_dir>/<name>/``
    (``newton_lab.datasets.split_by_phase``; the kinds of ``by_target`` one dataset per target value)."""
    from ..datasets import split_by_phase  # deferred: the dataset package imports Warp/Newton

    out = output_path(Path(out_dir) / f"{name}.manifest.json").parent
    inputs = {"stage": "split", "source": source["sha256"]}
    if by_target:
        inputs["by_target"] = list(by_target)
    if (done := _guard(out, name, inputs)) is not None:
        return done["phases"]
    folder = _fresh(out / name)
    refs = split_by_phase(source["path"], folder, by_target=by_target or ())
    phases = {
        p: artifact(ref.path, "dataset", episodes=ref.metadata["episodes"], samples=dataset_samples(ref.path))
        for p, ref in refs.items()
    }
    _finish(out, name, inputs, artifact(folder, "phase datasets", phases=phases))
    return phases


def evaluate_stage(
    *,
    checkpoint: dict[str, Any] | None = None,
    args: EvaluateArgs,
    phase_checkpoints: dict[str, dict[str, Any]] | None = None,
) -> dict[str, Any]:
    """Success rate of the checkpoint artifact (``args.checkpoint`` is its path) on ``args.task``, or of a coherent
    task run by one checkpoint artifact per learned phase (``phase_checkpoints``: phase name -> artifact; the
    other phases run their component's expert); with ``args.rerun_save``, the first episode of each of the first
    ``args.rerun_worlds`` rows is recorded there (``recording`` in the result)."""
    return _on_device(args.device, _evaluate, args, checkpoint, phase_checkpoints)


def _evaluate(
    args: EvaluateArgs, checkpoint: dict[str, Any] | None, phase_checkpoints: dict[str, dict[str, Any]] | None
) -> dict[str, Any]:
    from ..envs import make_env  # deferred: Warp/Newton are slow to import
    from ..envs.rollout import EVAL_REPORT_KEYS  # deferred: Warp/Newton are slow to import
    from ..policies import Policy  # deferred: torch is slow to import
    from ..policies.agent import PolicyAgent, phase_policy_agent  # deferred: imports the env stack (Warp)

    policy_device = args.policy_device()
    env = make_env(args.task, **args.env_kwargs())
    if phase_checkpoints:
        agent = phase_policy_agent(env, {p: a["path"] for p, a in phase_checkpoints.items()}, device=policy_device)
    elif checkpoint is not None and checkpoint.get("kind") == "rl checkpoint":
        from ..policies.rl.agent import RLPolicyAgent  # deferred: only a PPO checkpoint needs it

        agent = RLPolicyAgent.from_checkpoint(args.checkpoint, device=policy_device)
    else:
        agent = PolicyAgent(Policy.from_backend(BACKEND).load_policy(args.checkpoint, device=policy_device))
    logger = None
    if args.rerun_save:  # the first episode of each of the first ``rerun_worlds`` rows, to a fresh .rrd
        from ..viz import RerunLogger  # deferred: rerun-sdk is slow to import

        logger = RerunLogger(
            env,
            save=_fresh(Path(args.rerun_save)),
            max_worlds=args.rerun_worlds,
            episodes_per_row=1,
            app_id="newton_lab_evaluation",
        )
    try:
        s = env.evaluate(agent=agent, **args.rollout_kwargs(), on_step=None if logger is None else logger.on_step)
    finally:
        if logger is not None:
            logger.close()
    report = {k: s[k] for k in EVAL_REPORT_KEYS if k != "task"}
    if logger is not None:
        report["recording"] = str(logger.path)
    return report
