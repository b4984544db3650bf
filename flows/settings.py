"""Defaults of the pipeline: the demo recipes (``make demo``), and Prefect's settings for running on one machine
with no set-up: the embedded ephemeral server, no analytics, quiet logs, and a PREFECT_HOME under the project's
output folder unless the user set one. A user with a Prefect server exports ``PREFECT_API_URL`` and these
defaults leave it alone."""

from __future__ import annotations

import os
import urllib.error
import urllib.request
import warnings
from pathlib import Path
from typing import Any

DEMO_TRAIN_CFG: dict[str, Any] = {
    "down_dims": [32, 64, 128],
    "diffusion_step_embed_dim": 64,
    "activation": "silu",
    "prediction_type": "sample",
    "num_inference_steps": 5,
    "batch_size": 64,
    "lr": 6e-4,
    "warmup_steps": 300,
    "epochs": 1000,
    "max_steps": 6000,
    "seed": 0,
}
"""The demo's diffusion policy: the ``cpu`` preset's quarter-width U-Net with SiLU (a step takes 0.82x the Mish
one on 2 CPU cores), predicting the clean action chunk (x0) instead of the noise, 5 DDIM steps at inference.
Measured on the demo's 100 Mimic demos, the same 40 held-out episodes (evaluation seed 10000) each, training seed
0 / 1 (benchmarks history, "The demo pipeline"): 2500 steps 80 % / -, 5000 steps 100 % / 90 %, 6000 steps - / 92.5 %;
Mish 4000 steps 100 % / -, Mish 5000 steps - / 87.5 %. Earlier: 10 DDIM steps 68 % and action_horizon 4 60 % at
2500 steps; epsilon prediction 0-5 % after 3000-5000 steps. 6000 steps take about 2.8 min on 2 CPU cores
(``compile=True`` makes a step ~0.55x as long once torch's compile cache is warm, but its first compile on a fresh
machine costs about what it saves)."""

DEMO_RECIPES: dict[str, dict[str, Any]] = {
    # on 2 CPU cores from a fresh clone with cold caches: the policy observes state (nothing is rendered)
    "cpu": {
        "demos": 4,
        "mimic_episodes": 100,
        "eval_episodes": 40,
        "num_envs": 4,
        "cameras": "none",
        "task_options": {},
        "train": DEMO_TRAIN_CFG,
    },
    # full size on a CUDA device, from pixels: the policy sees the front head camera (96x72 RGB) and
    # proprioception only (obs_mode=sensors: no cube or block pose anywhere in its input); 16 expert demos grown
    # to 1024 by Mimic (rendered from the same camera), the visuomotor preset under bf16 for a fixed wall-clock
    # budget, 100 held-out randomised evaluation episodes. num_envs bounds each stage's rows (collection uses
    # one row per demo, evaluation one per episode).
    "gpu": {
        "demos": 16,
        "mimic_episodes": 1024,
        "eval_episodes": 100,
        "num_envs": 512,
        "cameras": "front_head=96x72:rgb",
        "task_options": {"obs_mode": "sensors"},
        "train": {"preset": "vision", "bf16": True, "lr": 3e-4, "time_budget_s": 330},
    },
}
"""Counts, cameras, task options and training of ``newton-lab pipeline`` / ``make demo`` for every flag left
unset (``cameras``: the ``--cameras`` of collection, Mimic and evaluation)."""
LONG_HORIZON_RECIPES: dict[str, dict[str, Any]] = {
    # The smallest end-to-end run on 2 CPU cores: a few coherent demos, short trainings of the quarter-width
    # visuomotor policy on the front camera, a few evaluation episodes (it shows the flow works; no success is
    # expected at this size).
    "cpu": {
        "demos": 4,
        "eval_episodes": 4,
        "num_envs": 2,
        "eval_max_steps": 3000,
        "cameras": "front_head=96x72:rgb",
        "train": {"preset": "vision_cpu", "max_steps": 1000},
    },
    # Full size on a GPU: the visuomotor preset under bf16 with the front head and the left wrist camera (at 96x72
    # the bar is a few pixels wide in the head view; the wrist view holds it large through the grasp and the
    # place), 600 coherent demos and one 6-minute training per learned phase, the phases side by side on the GPU
    # (each in a process of its own).
    "gpu": {
        "demos": 600,
        "eval_episodes": 100,
        "num_envs": 300,
        "eval_max_steps": 3000,
        "cameras": "front_head=96x72:rgb,left_wrist=96x72:rgb",
        "train": {
            "preset": "vision",
            "image_keys": ("front_head_rgb", "left_wrist_rgb"),
            "bf16": True,
            "lr": 3e-4,
            "time_budget_s": 360,
        },
    },
}
"""Counts, cameras and training of ``newton-lab pipeline`` on a coherent task (``newton_lab.flows.long_horizon``):
every policy input is what the robot measures: its cameras (``cameras``: the ``--cameras`` of collection and
evaluation) and proprioception (``obs_mode="sensors"``: no object or target pose)."""
LONG_HORIZON_TASK_RECIPES: dict[str, dict[str, dict[str, Any]]] = {
    # SortToShelf-All: an expert episode takes ~2350 steps (PickToShelf's ~470), and each episode gives every
    # learned phase kind four segments, one of each object. One pick policy told its object by a one-hot did not
    # learn to pick that object: 0 of 100 on one H200 with the one-hot in the U-Net's condition (160 demos; pick_1
    # passed 22), 2 of 100 with it also FiLM-conditioning the camera trunks (``instruction_keys``; 300 demos, 600 s;
    # pick_1 passed 33) -- both lifted other objects than their target far more often than it. So the pick trains
    # one policy per object (``per_target``: each sees that object's 300 segments and always picks it, as the
    # single-object SortToShelf policies that pick 94-100 % of theirs do), switched per row on the one-hot; the
    # place policy, which placed 45 of the 46 objects it was handed, stays one conditioned policy. With 300 demos
    # (300 segments an object) and 600 s a policy, all side by side, 55 of 100 sorted all four on one H200 in 24
    # minutes, the per-object picks passing 286 of 325 (the single-object SortToShelf picks, 94-100 %, learned from
    # 600). Collection was bound by the HDF5 writer's deflate (the 300 rows stepped 2350 steps in ~90 s, then
    # handed over 1.6 episodes/s); with frames deflated on every core, 600 demos (two rounds of the 300 rows) are
    # expected to fit the 30 minutes. Policies move slower than the expert, so evaluation runs to 5000 steps.
    "GalbotG1-SortToShelf-All-v0": {
        "gpu": {
            "demos": 600,
            "eval_max_steps": 5000,
            "train": {**LONG_HORIZON_RECIPES["gpu"]["train"], "time_budget_s": 600},
            "per_target": ("pick",),
        },
        "cpu": {"demos": 2, "eval_episodes": 2, "eval_max_steps": 3000},
    },
    # PickToShelf: two runs alone on one H200 with 360 s a phase (~5.3 k steps) scored 97 and 92 of 100, the misses
    # pick episodes that tipped the bar; 420 s gives each phase ~6.2 k steps and still ends within 15 minutes.
    "GalbotG1-PickToShelf-v0": {"gpu": {"train": {**LONG_HORIZON_RECIPES["gpu"]["train"], "time_budget_s": 420}}},
    # StackCube-Phased: a cube set on a 5 cm cube within its tolerance needs more data and training than a bar
    # on a shelf. Measured from pixels (100 held-out episodes): 48 of 100 with 600 demos and ~2.1 k steps a phase
    # (one H200 shared with other runs), 82 of 100 with 800 demos and 600 s a phase (16.6 k steps, each phase on an
    # H100 of its own); these are that run's counts (on one GPU the two phases share it, ~9 k steps each).
    "GalbotG1-StackCube-Phased-v0": {
        "gpu": {"demos": 800, "train": {**LONG_HORIZON_RECIPES["gpu"]["train"], "time_budget_s": 600}}
    },
}
"""Per coherent task, what differs from ``LONG_HORIZON_RECIPES`` (by recipe name)."""
LONG_HORIZON_OPTIONS = {"obs_mode": "sensors"}
"""Task options the long-horizon pipeline always sets (policies see no privileged state)."""

PIPELINE_DATASET_FORMAT = "hdf5"
"""The format of the pipeline's datasets (``demos.*``, ``mimic.*``, the phase datasets of a split) when neither the
recipe nor ``--dataset-format`` (hdf5 or zarr) names one."""

PIPELINE_CAMERAS = "none"
"""Default ``--cameras`` of the pipeline's collect, Mimic and evaluation envs when a recipe names none: a state
policy, so nothing is rendered or recorded (image terms would cost a render per step and ~0.9 MB per 298x224
demo)."""


def _sees_cuda() -> bool:
    """torch finds a CUDA device (quietly: a CPU-only machine is the normal case here)."""
    import torch  # deferred: torch is slow to import; asked only when the recipe is "auto"

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return torch.cuda.is_available()


def demo_recipe(
    name: str = "auto", device: str | None = None, *, long_horizon: bool = False, task: str | None = None
) -> dict[str, Any]:
    """The demo recipe ``name`` ("cpu", "gpu", or "auto": gpu when torch sees a CUDA device and ``device`` is not
    a CPU), with ``name`` resolved, ``device`` (envs: "cpu" for the cpu recipe, else the given one or Warp's) and
    ``train_device`` (the given device, else cpu / cuda) added; ``long_horizon``: a coherent task's recipe
    (``LONG_HORIZON_RECIPES``, with ``task``'s own counts from ``LONG_HORIZON_TASK_RECIPES``)."""
    if name not in (*DEMO_RECIPES, "auto"):
        raise ValueError(f"unknown demo recipe {name!r}; valid recipes: auto, {', '.join(DEMO_RECIPES)}")
    if name == "auto":
        on_cpu = device is not None and device.startswith("cpu")
        name = "gpu" if not on_cpu and (device is not None and device.startswith("cuda") or _sees_cuda()) else "cpu"
    env_device = device if device is not None else ("cpu" if name == "cpu" else None)
    train_device = device if device is not None else ("cpu" if name == "cpu" else "cuda")
    recipes = LONG_HORIZON_RECIPES if long_horizon else DEMO_RECIPES
    own = LONG_HORIZON_TASK_RECIPES.get(task, {}).get(name, {}) if long_horizon else {}
    return {
        **recipes[name],
        **own,
        "name": name,
        "device": env_device,
        "train_device": train_device,
        "long_horizon": long_horizon,
    }


NAVIGATION_GROUPS = ("base",)
"""Joint groups of a phase that navigates: such a phase runs its component's expert, not a learned policy."""


def learned_kinds(cfg) -> list[str]:
    """The phase kinds of a coherent task's ``cfg`` that the long-horizon pipeline trains a policy for: all but the
    navigating ones, one policy per kind (``TaskCfg.phase_kinds``: SortToShelf-All's ``pick`` runs in ``pick_1`` ..
    ``pick_4``)."""
    return [
        kind
        for kind, ix in cfg.phase_kinds.items()
        if not set(cfg.phases[ix[0]].action_groups or ()) & set(NAVIGATION_GROUPS)
    ]


def with_inputs(train_cfg: dict[str, Any], obs_keys: list[str]) -> dict[str, Any]:
    """``train_cfg`` whose policy also observes ``obs_keys`` (a coherent task's per-row targets,
    ``TaskCfg.target_observations``), where it names its observation terms (none named: it sees them all); a
    policy from cameras takes them as its instruction as well (``instruction_keys``: they condition its image
    trunks, so the keypoints follow the object the phase acts on)."""
    if not obs_keys:
        return train_cfg
    named = train_cfg.get("obs_keys")
    out = dict(train_cfg)
    if named is not None:
        out["obs_keys"] = [*named, *(k for k in obs_keys if k not in named)]
    if train_cfg.get("image_keys"):
        out["instruction_keys"] = list(obs_keys)
    return out


def without_inputs(train_cfg: dict[str, Any], obs_keys: list[str]) -> dict[str, Any]:
    """``train_cfg`` with ``obs_keys`` taken out of its observation terms and its instruction (``with_inputs``
    undone): a policy per target value, whose data holds that value alone."""
    out = dict(train_cfg)
    if out.get("obs_keys") is not None:
        out["obs_keys"] = [k for k in out["obs_keys"] if k not in obs_keys]
    if out.get("instruction_keys") is not None:
        kept = [k for k in out.pop("instruction_keys") if k not in obs_keys]
        if kept:
            out["instruction_keys"] = kept
    return out


def phase_trainings(cfg, train_cfg: dict[str, Any], per_target=()) -> dict[str, dict[str, Any]]:
    """The long-horizon pipeline's trainings of coherent task ``cfg``: policy name -> training config. One per
    learned kind (``learned_kinds``), observing the task's per-row targets (``with_inputs``); a kind in
    ``per_target`` instead trains one policy per value of its target (``kind/value``, on the split's dataset of that
    value), which takes no target input."""
    from ..task_api.compose import per_target_names  # deferred: the task API imports the registry

    if not cfg.phases:
        raise ValueError(f"{cfg.task_id} has no phases; run the single-task pipeline on it (no long-horizon recipe)")
    kinds = learned_kinds(cfg)
    wrong = [k for k in per_target if k not in kinds]
    if wrong:
        raise ValueError(
            f"per-target policies for {wrong[0]!r}: {cfg.task_id} learns the phase kinds {', '.join(kinds)}; "
            "name one of those"
        )
    targets = cfg.target_observations
    out: dict[str, dict[str, Any]] = {}
    for kind in kinds:
        if kind in per_target:
            out.update(dict.fromkeys(per_target_names(cfg, [kind]), without_inputs(train_cfg, targets)))
        else:
            out[kind] = with_inputs(train_cfg, targets)
    return out


DEFAULTS = {
    "PREFECT_SERVER_ANALYTICS_ENABLED": "false",
    "PREFECT_LOGGING_LEVEL": "WARNING",
    # run logs (stage lines) reach the API at INFO; the console shows PREFECT_LOGGING_LEVEL and above
    "PREFECT_LOGGING_LOGGERS_PREFECT_FLOW_RUNS_LEVEL": "INFO",
    "PREFECT_LOGGING_LOGGERS_PREFECT_TASK_RUNS_LEVEL": "INFO",
    "PREFECT_SERVER_UI_ENABLED": "false",
    "PREFECT_TELEMETRY_ENABLE_RESOURCE_METRICS": "false",
    "PREFECT_CLOUD_ENABLE_ORCHESTRATION_TELEMETRY": "false",
    "PREFECT_SERVER_EPHEMERAL_STARTUP_TIMEOUT_SECONDS": "90",
}


def configure(home: str | os.PathLike | None = None) -> None:
    """Set the defaults above where the user has not set them (call before importing prefect). Run logs are
    sent to the user's own server (``PREFECT_API_URL`` set: its UI shows them), not to the embedded one."""
    for key, value in DEFAULTS.items():
        os.environ.setdefault(key, value)
    os.environ.setdefault("PREFECT_LOGGING_HANDLERS_CONSOLE_LEVEL", os.environ["PREFECT_LOGGING_LEVEL"])
    if not os.environ.get("PREFECT_API_URL"):
        os.environ.setdefault("PREFECT_LOGGING_TO_API_ENABLED", "false")
    if "PREFECT_HOME" not in os.environ:
        os.environ["PREFECT_HOME"] = str(Path(home or "outputs/.prefect").resolve())
    Path(os.environ["PREFECT_HOME"]).mkdir(parents=True, exist_ok=True)


def check_api_reachable(timeout_s: float = 5.0) -> None:
    """If ``PREFECT_API_URL`` is set, fail within ``timeout_s`` with a one-line error when it is down."""
    url = os.environ.get("PREFECT_API_URL")
    if not url:
        return
    try:
        urllib.request.urlopen(url.rstrip("/") + "/health", timeout=timeout_s)
    except (urllib.error.URLError, OSError, ValueError) as exc:
        raise ConnectionError(
            f"Prefect API at PREFECT_API_URL={url} is unreachable ({exc}); start the server or unset "
            f"PREFECT_API_URL to use the embedded one"
        ) from None
