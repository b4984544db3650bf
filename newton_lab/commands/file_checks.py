"""The checks of ``check_args`` that read the files a command names, light: a dataset's header (h5py / zarr
metadata: task, cameras, task options, observation terms, episodes), a checkpoint's header
(``checkpoint_headers.checkpoint_header``: format, task), the training presets (read from source) and a split's
output folder. Each refuses in one line before Warp or torch loads."""

from __future__ import annotations

import ast
import functools
import importlib.util
from pathlib import Path
from typing import Any

from ..task_api.catalog import (
    declared_mimic_arms,
    declared_phase_kinds,
    declared_phases,
    declared_sources,
    did_you_mean,
)
from .checkpoint_headers import checkpoint_header
from .env import camera_option
from .workflow import CollectArgs, EvaluateArgs, MimicArgs, SplitArgs, TrainArgs, ViewArgs


def flag_of(args: Any, name: str) -> str:
    """How the command line spells field ``name``: ``--flag-name``, or the bare name of a positional."""
    if args.__dataclass_fields__[name].metadata.get("positional"):
        return name
    return f"--{name.replace('_', '-')}"


def trained_for(trained: str | None, task_id: str) -> bool:
    """A policy trained on ``trained`` runs on ``task_id``: the same task, its Mimic variant's source, or a
    component of a coherent ``task_id`` (``newton_lab.policies.agent._compatible_task``, from source)."""
    if trained is None or trained == task_id:
        return True
    return declared_sources().get(task_id) == trained or trained in [c for _, c in declared_phases().get(task_id, ())]


def check_checkpoints(args: EvaluateArgs) -> None:
    """``evaluate``'s checkpoints: each one's header (format, task), and each phase a phase of a coherent task."""
    phases = args.phase_checkpoints()
    if phases and args.checkpoint:
        raise ValueError(
            "give --checkpoint (one policy for the whole task) or --phase-checkpoint (one per phase "
            "of a coherent task), not both"
        )
    if args.checkpoint is not None:
        header = checkpoint_header(args.checkpoint, "--checkpoint")
        trained = header["info"].get("task_id")
        if not trained_for(trained, args.task):
            raise ValueError(
                f"--checkpoint {args.checkpoint} was trained for {trained} but the env runs {args.task}; "
                f"evaluate it on --task {trained}"
            )
        check_policy_cameras(f"--checkpoint {args.checkpoint}", header, args.cameras)
    if not phases:
        return
    task_phases = {**dict(declared_phases().get(args.task, ())), **declared_phase_kinds().get(args.task, {})}
    if not task_phases:
        raise ValueError(
            f"--phase-checkpoint is for the phases of a coherent task, and {args.task} has none; use "
            "--checkpoint, or a coherent task: " + ", ".join(declared_phases())
        )
    for phase, path in phases.items():
        if phase not in task_phases:
            raise ValueError(
                f"--phase-checkpoint {phase}={path}: {args.task} has no phase {phase!r}"
                f"{did_you_mean(phase, task_phases)}; its phases: {', '.join(_listed(args.task))}"
            )
        if not Path(path).exists():
            raise FileNotFoundError(f"--phase-checkpoint {phase}={path}: {path} does not exist; check the path")
        trained = checkpoint_header(path, f"--phase-checkpoint {phase}=")["info"].get("task_id")
        component = task_phases[phase]
        if trained is not None and component not in (trained, declared_sources().get(trained)):
            raise ValueError(
                f"checkpoint {path} was trained for {trained}, but phase {phase!r} of {args.task} runs "
                f"{component}; give that phase a checkpoint of {component}"
            )


def _listed(task_id: str) -> list[str]:
    """What ``--phase-checkpoint`` names for ``task_id``: its phase kinds where several phases share one, else its
    phases."""
    kinds, names = declared_phase_kinds().get(task_id, {}), [n for n, _ in declared_phases().get(task_id, ())]
    return list(kinds) if len(kinds) < len(names) else names


def check_policy_cameras(label: str, header: dict, cameras: str) -> None:
    """A policy that sees cameras (its ``image_keys``) is evaluated with ``--cameras`` that render them at the
    trained size; ``default`` (the task's cameras) is checked when the env is built."""
    keys = list(header["config"].get("image_keys") or ())
    wanted = camera_option(cameras)
    if not keys or wanted is None:
        return
    shapes = header["info"].get("image_shapes") or {}
    need = {k.rsplit("_", 1)[0]: (shapes[k][1], shapes[k][0]) for k in keys if len(shapes.get(k, ())) >= 2}
    fix = ",".join(f"{cam}={w}x{h}" for cam, (w, h) in need.items())
    for key in keys:
        cam, data = key.rsplit("_", 1)
        spec = (wanted or {}).get(cam)
        res = spec if isinstance(spec, tuple) else (spec or {}).get("resolution")
        datas = ("rgb",) if isinstance(spec, tuple) else tuple((spec or {}).get("data", ("rgb",)))
        if spec is None or data not in datas or (cam in need and tuple(res) != need[cam]):
            raise ValueError(
                f"{label} sees {key} at {'x'.join(map(str, need.get(cam, ('?', '?'))))} px, which "
                f"--cameras {cameras} does not render; evaluate with --cameras {fix}"
            )


def check_append(args: CollectArgs) -> None:
    """``collect`` onto an existing dataset: it opens, holds this task, and was recorded with the cameras and task
    options given now (a dataset's recording set is part of what it is; ``default`` cameras and options left unset
    are compared when the env is built, ``datasets.storage``)."""
    from ..datasets import read_dataset_info  # deferred: the datasets package imports h5py and zarr (~1 s)

    path = args.dataset_path
    info = read_dataset_info(path)  # a one-line ValueError if it is no dataset or is damaged
    if info["task_id"] != args.task:
        raise ValueError(
            f"{path} holds a dataset of task {info['task_id']!r}, not {args.task!r}; choose another "
            f"path for {args.task!r}"
        )
    recorded = info["env_args"].get("newton_lab", {}).get("cameras")
    wanted = camera_option(args.cameras)
    if recorded is not None and wanted is not None:
        now = (
            {}
            if wanted is False
            else {
                name: (
                    (spec if isinstance(spec, tuple) else spec["resolution"]),
                    tuple(spec.get("data", ())) if isinstance(spec, dict) else None,
                )
                for name, spec in wanted.items()
            }
        )
        before = {name: ((c["width"], c["height"]), tuple(c.get("data", ()))) for name, c in recorded.items()}
        same = now.keys() == before.keys() and all(
            now[n][0] == before[n][0] and (now[n][1] is None or now[n][1] == before[n][1]) for n in now
        )
        if not same:
            raise ValueError(
                f"{path} was recorded with cameras {_cameras_text(before)}, not {args.cameras}; append "
                f"with --cameras {_cameras_text(before)}, or collect into another path"
            )
    options = info["env_args"].get("env_kwargs", {}).get("task_options")
    if isinstance(options, dict):
        for name, value in args.task_options.items():
            if value is not None and name in options and options[name] != value:
                flag = "--" + name.replace("_", "-")
                raise ValueError(
                    f"{path} was recorded with {flag} {options[name]}, not {value}; append with "
                    f"{flag} {options[name]}, or collect into another path"
                )


def _cameras_text(cameras: dict[str, tuple]) -> str:
    """A recorded camera set as ``--cameras`` spells it."""
    if not cameras:
        return "none"
    return ",".join(f"{n}={w}x{h}" + (f":{'+'.join(d)}" if d else "") for n, ((w, h), d) in cameras.items())


@functools.cache
def train_preset_fields() -> dict[str, tuple[str, ...]]:
    """The names of ``newton_lab.policies.config.PRESETS`` and the fields each sets, read from its source
    (importing it imports torch)."""
    spec = importlib.util.find_spec("newton_lab.policies")
    for root in (spec.submodule_search_locations or []) if spec else []:
        for node in ast.walk(ast.parse((Path(root) / "config.py").read_text())):
            target = node.target if isinstance(node, ast.AnnAssign) else None
            if isinstance(target, ast.Name) and target.id == "PRESETS" and isinstance(node.value, ast.Dict):
                return {
                    k.value: tuple(f.value for f in v.keys if isinstance(f, ast.Constant))
                    if isinstance(v, ast.Dict)
                    else ()
                    for k, v in zip(node.value.keys, node.value.values)
                    if isinstance(k, ast.Constant)
                }
    return {}


def check_train(args: TrainArgs) -> None:
    """``train``'s slips that its run would find only after torch is imported: the preset, the observation and
    camera keys against the dataset, the numbers, the resume file, the init checkpoint."""
    from ..datasets import read_dataset_info  # deferred: the datasets package imports h5py and zarr (~1 s)
    from ..datasets.files.output_paths import output_path  # deferred: as above

    preset_fields = train_preset_fields()
    presets = tuple(preset_fields)
    if presets and args.preset not in presets:
        raise ValueError(
            f"--preset: unknown training preset {args.preset!r}{did_you_mean(args.preset, presets)}; "
            f"valid presets: {', '.join(presets)}"
        )
    if args.instruction_keys and not args.image_keys and "image_keys" not in preset_fields.get(args.preset, ()):
        raise ValueError(
            f"--instruction-keys {args.instruction_keys} condition the image trunks; give image_keys too "
            "(--image-keys, or a vision preset), or leave them to --obs-keys alone"
        )
    for name in ("lr", "obs_min_range", "weight_decay"):
        value = getattr(args, name)
        if value is not None and (value < 0 or (name == "lr" and value == 0)):
            raise ValueError(f"--{name.replace('_', '-')} must be {'> 0' if name == 'lr' else '>= 0'}, got {value!r}")
    if args.num_workers is not None and args.num_workers < 0:
        raise ValueError(f"--num-data-workers must be an integer >= 0, got {args.num_workers!r}")
    info = read_dataset_info(args.dataset_path[0])
    first = (info["task_id"], info["env_args"].get("newton_lab", {}).get("action_joint_names"))
    for other in args.dataset_path[1:]:
        more = read_dataset_info(other)
        if (more["task_id"], more["env_args"].get("newton_lab", {}).get("action_joint_names")) != first:
            raise ValueError(
                f"{other} ({more['task_id']}) does not match {args.dataset_path[0]} ({info['task_id']}): "
                "datasets trained together need the same task and action columns"
            )
    output_path(Path(args.output_dir) / "checkpoint.pt", create=False)  # --output-dir (or a folder above) a file
    newton = info["env_args"].get("newton_lab", {})
    terms = newton.get("obs_terms")
    for flag, keys in (("--obs-keys", args.obs_keys), ("--instruction-keys", args.instruction_keys)):
        for key in (keys or "").split(","):
            if key.strip() and terms is not None and key.strip() not in terms:
                raise ValueError(
                    f"{flag}: {args.dataset_path[0]} records no observation {key.strip()!r}"
                    f"{did_you_mean(key.strip(), terms)}; its terms: {', '.join(sorted(terms))}"
                )
    cameras = newton.get("cameras")
    if args.image_keys and cameras is not None:
        images = [f"{c}_{d}" for c, spec in cameras.items() for d in spec.get("data", ())]
        for key in (k.strip() for k in args.image_keys.split(",") if k.strip()):
            if key not in images:
                raise ValueError(
                    f"--image-keys: {args.dataset_path[0]} records no image {key!r}"
                    f"{did_you_mean(key, images)}; its images: {', '.join(images) or 'none'} (record "
                    "cameras with collect --cameras)"
                )
    out = Path(args.output_dir)
    resume = out / "resume.pt"
    if args.resume and not resume.is_file():
        raise FileNotFoundError(
            f"no resume file {resume}: nothing to resume there; check --output-dir, or train "
            "without --resume to start from step 0"
        )
    if not args.resume and resume.exists():
        raise FileExistsError(
            f"{resume} holds an interrupted run; continue it with --resume or delete that file to start over"
        )
    if args.init_checkpoint is not None:
        trained = checkpoint_header(args.init_checkpoint, "--init-checkpoint")["info"].get("task_id")
        task = info["task_id"]
        if trained is not None and trained != task:
            raise ValueError(
                f"--init-checkpoint {args.init_checkpoint} was trained for {trained} and "
                f"{args.dataset_path[0]} holds {task}; continue it on a dataset of {trained}, or train "
                "from scratch"
            )


def check_datasets(args: Any, name: str) -> None:
    """The dataset(s) a command reads exist and open (and ``view``'s episode is in its dataset): one line each."""
    from ..datasets import read_dataset_info  # deferred: the datasets package imports h5py and zarr (~1 s)

    value = getattr(args, name)
    for path in value if isinstance(value, list) else [value]:
        if not Path(path).exists():
            raise FileNotFoundError(f"{flag_of(args, name)} {path} does not exist; check the path")
        info = read_dataset_info(path)  # a one-line ValueError if it is no dataset or is damaged
        ids = info["demo_ids"]
        if isinstance(args, SplitArgs) and args.out and info["task_id"] not in declared_phases():
            raise ValueError(
                f"{path} was recorded on {info['task_id']}, which has no phases; nothing to split (a "
                "coherent task's dataset splits by phase: " + ", ".join(declared_phases()) + ")"
            )
        if isinstance(args, MimicArgs):
            check_mimic_output(args, path, info)
        if isinstance(args, SplitArgs) and args.phases:
            check_split_phases(args, path, info)
        if isinstance(args, ViewArgs) and args.episode not in ids:
            listed = ", ".join(map(str, ids[:5])) + (", ..." if len(ids) > 5 else "")
            raise ValueError(
                f"--episode {args.episode}: {path} has no episode {args.episode}; its {len(ids)} "
                f"episodes: {listed or 'none'}"
            )


def check_mimic_output(args: MimicArgs, path: str, info: dict[str, Any]) -> None:
    """Mimic's source: its task has a Mimic variant and its actions command the arm the variant segments; an existing
    output dataset holds demos of the same task."""
    task_id = info["task_id"]
    variants = [v for v, source in declared_sources().items() if source == task_id]
    if not variants:
        raise ValueError(
            f"task {task_id!r} has no Mimic variant; tasks with one: "
            f"{', '.join(sorted(set(declared_sources().values())))}"
        )
    src = Path(path)
    out = Path(args.output_path) if args.output_path else src.with_name(f"{src.stem}_mimic{src.suffix}")
    from ..datasets import read_dataset_info  # deferred: the datasets package imports h5py and zarr (~1 s)
    from ..datasets.files.output_paths import output_path  # deferred: as above

    output_path(out, create=False)  # a file on its path: refused now
    if out.exists():
        held = read_dataset_info(out)["task_id"]  # a one-line ValueError if it is no dataset or is damaged
        if held != task_id:  # Mimic's demos are recorded under their source's task id
            raise ValueError(f"{out} holds a dataset of task {held!r}, not {task_id!r}; choose another --output-path")
    names = info["env_args"].get("newton_lab", {}).get("action_joint_names")
    arm = declared_mimic_arms().get(task_id, "left")
    if names is not None:
        from ..robots.registry import joint_group_facts  # deferred: numpy, only for mimic

        if not all(j in names for j in joint_group_facts().get(f"{arm}_arm", ())):
            raise ValueError(
                f"{path}: actions do not hold the {arm} arm joints; Mimic needs arm joint-target actions "
                "(demos of the task's expert, newton-lab collect)"
            )


def check_split_phases(args: SplitArgs, path: str, info: dict[str, Any]) -> None:
    """``split --phases`` names phases (kinds) that the dataset's task has (as recorded in its ``env_args``; a dataset
    recorded before the phase names were is checked after the task is built), and only with ``--out``."""
    if not args.out:
        raise ValueError("--phases selects the phases of a split by phase: give --out too")
    from ..datasets.split import check_phase_names  # deferred: the datasets package imports h5py and zarr (~1 s)

    facts = info["env_args"].get("newton_lab", {})
    recorded = facts.get("phase_kinds") or facts.get("phases")
    if recorded is not None:
        check_phase_names(path, info["task_id"], recorded, args.phase_names())


def check_split_out(args: SplitArgs) -> None:
    """``split --out`` is a new folder (or an empty one), and ``--phases`` names at least one phase."""
    if args.phases is not None and not args.phase_names():
        raise ValueError(
            f"--phases {args.phases!r} names no phase; give comma-separated names, e.g. --phases pick,place"
        )
    if args.out is None:
        return
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise FileExistsError(f"--out {out} is a file; split into a new folder")
    if out.is_dir() and any(out.iterdir()):
        raise FileExistsError(f"--out {out} is a folder that holds files already; split into a new folder")
