"""The pipeline's stages as plain functions over artifacts (Prefect wraps them in ``pipeline``).

Every stage writes its output under ``out_dir`` next to a manifest (``<name>.manifest.json``) naming the
inputs that produced it: re-running with the same inputs reuses the output, and an output folder that
holds another pipeline's artifacts is refused instead of overwritten.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

from .artifacts import artifact


def _guard(out_dir: Path, name: str, inputs: dict[str, Any]) -> dict[str, Any] | None:
    """The finished artifact of ``name`` if it was made from ``inputs``; raises if made from others."""
    manifest = out_dir / f"{name}.manifest.json"
    if not manifest.exists():
        return None
    saved = json.loads(manifest.read_text())
    if saved["inputs"] != json.loads(json.dumps(inputs)):
        raise ValueError(f"{out_dir} holds another pipeline's {name} ({manifest}); use a new --out folder")
    if not Path(saved["artifact"]["path"]).exists():
        return None
    return saved["artifact"]


def _finish(out_dir: Path, name: str, inputs: dict[str, Any], art: dict[str, Any]) -> dict[str, Any]:
    tmp = out_dir / f".{name}.manifest.json.tmp"
    tmp.write_text(json.dumps({"inputs": inputs, "artifact": art}, indent=1))
    tmp.replace(out_dir / f"{name}.manifest.json")
    return art


def _fresh(path: Path) -> Path:
    """Remove a leftover partial output of an interrupted run (never a finished one: those have manifests)."""
    if path.exists():
        shutil.rmtree(path) if path.is_dir() else path.unlink()
    return path


def collect_stage(*, task_id: str, episodes: int, num_envs: int, seed: int, device: str | None, out_dir: str,
                  name: str = "demos", progress: bool = True) -> dict[str, Any]:
    """Expert demos of ``task_id`` (planner, randomised) -> dataset artifact."""
    from ..agents import expert_agent
    from ..envs import make_env

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    inputs = {"stage": "collect", "task_id": task_id, "episodes": episodes, "num_envs": num_envs, "seed": seed}
    if (done := _guard(out, name, inputs)) is not None:
        return done
    path = _fresh(out / f"{name}.hdf5")
    env = make_env(task_id, num_envs=num_envs, device=device, seed=seed, randomize=True)
    ref = env.collect(agent=expert_agent(env), episodes=episodes, path=path, progress=progress)
    art = artifact(path, "dataset", episodes=ref["episodes"], successes=ref["successes"],
                   success_rate=ref["success_rate"])
    return _finish(out, name, inputs, art)


def mimic_stage(*, source: dict[str, Any], episodes: int, num_envs: int, seed: int, device: str | None,
                out_dir: str, name: str = "mimic", progress: bool = True) -> dict[str, Any]:
    """Mimic expansion of a source dataset artifact -> dataset artifact (successes only)."""
    from ..mimic import mimic

    out = Path(out_dir)
    inputs = {"stage": "mimic", "source": source["sha256"], "episodes": episodes, "num_envs": num_envs, "seed": seed}
    if (done := _guard(out, name, inputs)) is not None:
        return done
    path = _fresh(out / f"{name}.hdf5")
    ref = mimic(source["path"], episodes=episodes, num_envs=num_envs, output_path=path, seed=seed, device=device,
                progress=progress)
    m = ref.metadata
    art = artifact(path, "dataset", episodes=m["successes"], attempts=m["attempts"],
                   generation_success_rate=m["generation_success_rate"])
    return _finish(out, name, inputs, art)


def train_stage(*, dataset: dict[str, Any], train_cfg: dict[str, Any], out_dir: str, name: str = "policy") -> dict[str, Any]:
    """Diffusion policy on a dataset artifact -> checkpoint artifact."""
    from ..policies import Policy

    out = Path(out_dir)
    inputs = {"stage": "train", "dataset": dataset["sha256"], "train_cfg": train_cfg}
    if (done := _guard(out, name, inputs)) is not None:
        return done
    run_dir = _fresh(out / name)
    ckpt = Policy.from_backend("diffusion").train(dataset["path"], {**train_cfg, "output_dir": str(run_dir)})
    log_path = Path(ckpt).parent / "train_log.json"
    final_loss = json.loads(log_path.read_text()).get("final_loss") if log_path.exists() else None
    return _finish(out, name, inputs, artifact(ckpt, "checkpoint", final_loss=final_loss))


def evaluate_stage(*, checkpoint: dict[str, Any], task_id: str, episodes: int, num_envs: int, seed: int,
                   device: str | None, max_steps: int = 600, progress: bool = True) -> dict[str, Any]:
    """Success rate of a checkpoint artifact on ``task_id`` (randomised, its own seed range)."""
    from ..policies import PolicyAgent
    from ..envs import make_env
    from ..envs.rollout import EVAL_REPORT_KEYS

    env = make_env(task_id, num_envs=num_envs, device=device, seed=seed, randomize=True)
    s = env.evaluate(agent=PolicyAgent.from_checkpoint(checkpoint["path"]), episodes=episodes, max_steps=max_steps,
                     progress=progress)
    return {k: s[k] for k in EVAL_REPORT_KEYS if k != "task"}
