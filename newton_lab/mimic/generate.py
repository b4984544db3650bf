"""``mimic(dataset, episodes=N, num_envs=K)``: expand a few source demos into many on a batched env."""

from __future__ import annotations

from pathlib import Path

from ..datasets.ref import DatasetRef
from ..envs import make_env
from ..envs.recorder import recorded_scene
from ..task_api.registry import mimic_variant_of
from .agent import MimicAgent
from .source import load_sources


def mimic(
    dataset,
    *,
    episodes: int,
    num_envs: int = 4,
    output_path=None,
    seed: int = 1,
    device=None,
    max_attempts: int | None = None,
    max_steps: int = 1000,
    progress: bool = True,
    cameras: bool | dict | None = None,
) -> DatasetRef:
    """Generate ``episodes`` successful demos from the source demos of ``dataset`` (a path or a
    ``DatasetRef``) and append them to ``output_path`` (default ``<stem>_mimic<suffix>`` beside the source).

    Each attempt re-randomises the scene (seeded), picks a source segment per subtask (nearest object
    pose, top-k), replays it in the current object frame, and keeps the attempt only if the task's success
    fired at some step. Returns a ``DatasetRef``; its metadata holds ``attempts``, ``successes`` and
    ``success_rate`` (also stored as provenance in the dataset). ``cameras`` (``make_env``'s): ``None`` renders
    and records the cameras the source dataset recorded (none for a state-only source). The task options the
    source was recorded with (``obs_mode`` among them) are applied where the Mimic variant takes them.
    """
    src = dataset if isinstance(dataset, DatasetRef) else DatasetRef.open(dataset)
    path = Path(src.path)
    if not path.exists():
        raise FileNotFoundError(f"source dataset {path} does not exist; collect source demos first")
    task_id = src.info()["task_id"]
    variant = mimic_variant_of(task_id)
    mimic_id, cfg = variant.id, variant.mimic
    out = Path(output_path) if output_path is not None else path.with_name(f"{path.stem}_mimic{path.suffix}")
    if out.resolve() == path.resolve():
        raise ValueError(f"output_path {out} is the source dataset; choose another path")
    if cameras is None:  # the source's cameras (env_args newton_lab.cameras), at its resolutions and data
        recorded = src.info()["env_args"].get("newton_lab", {}).get("cameras") or {}
        cameras = {
            cam: {"resolution": (c["width"], c["height"]), "data": tuple(c["data"])} for cam, c in recorded.items()
        } or False
    # the source's task options (obs_mode included): the generated demos record what the source's did
    recorded_options = src.info()["env_args"].get("env_kwargs", {}).get("task_options") or {}
    options = {k: v for k, v in recorded_options.items() if k in variant.option_names}
    env = make_env(
        mimic_id,
        num_envs=num_envs,
        device=device,
        seed=seed,
        randomize=True,
        cameras=cameras,
        task_options=options,
        **recorded_scene(src.info()["env_args"]),  # the source's distractors: Mimic's demos stand among them too
    )
    sources = load_sources(
        path, cfg, env.robot.kinematics(256, device=env.device, arm=cfg.arm), task_id=task_id, robot=env.robot
    )
    agent = MimicAgent(sources, cfg, seed=seed)
    ref = env.collect(
        agent=agent,
        episodes=episodes,
        path=out,
        max_steps=max_steps,
        progress=progress,
        only_successes=True,
        max_attempts=max_attempts if max_attempts is not None else 10 * episodes,
        end_when_agent_done=True,
        dataset_task_id=task_id,
        operation="mimic",
        config={"source_path": str(path), "mimic_task_id": mimic_id, "num_sources": len(sources), "seed": seed},
    )
    meta = dict(ref.metadata)
    meta.update(
        source_task_id=task_id,
        mimic_task_id=mimic_id,
        num_sources=len(sources),
        status="complete" if meta["successes"] >= episodes else "incomplete",
        generation_success_rate=meta["successes"] / max(meta["attempts"], 1),
    )
    return DatasetRef(ref.path, task_id=task_id, metadata=meta, provenance=ref.provenance)
