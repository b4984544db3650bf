"""The bad-input table: command lines a user may get wrong, each with the words of the one line that refuses it
(exit status 2, before Warp or torch is imported, nothing written). One table for the test that checks every case
(``tests/test_cli_inputs.py``) and the benchmark that times them as a user meets them (``newton-lab
bench-refusals``); :func:`make_inputs` writes the files the cases name into a working folder.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import numpy as np

from ..datasets import open_writer
from .checkpoint_headers import CHECKPOINT_FORMAT, CHECKPOINT_VERSION

CASES: list[tuple[str, str]] = [
    ("collect --episodes 0 --dataset-path x.hdf5", "--episodes must be an integer >= 1"),
    ("collect --episodes -3 --dataset-path x.hdf5", "--episodes must be an integer >= 1"),
    ("collect --max-steps 0 --dataset-path x.hdf5", "--max-steps must be an integer >= 1"),
    ("collect --num-envs 0 --dataset-path x.hdf5", "--num-envs must be an integer >= 1"),
    ("collect --dataset-path x.txt", "unknown dataset suffix"),
    ("evaluate --episodes 0", "--episodes must be an integer >= 1"),
    ("evaluate --checkpoint nope.pt", "--checkpoint nope.pt does not exist"),
    ("evaluate --perturb wind=mild", "--perturb: unknown axis 'wind'; valid axes: action_noise, action_latency"),
    ("evaluate --perturb action_noise=huge", "level 'huge' is not mild, strong or a number [rad]"),
    ("evaluate --perturb action_latency=1.5", "action_latency takes a whole number of steps"),
    ("collect --domain-randomize light_intensity=mild", "'light_intensity' is not drawn per env row"),
    (
        "train-rl --device cpu --domain-randomize camera_tilt=mild",
        "train-rl's rows render no cameras; randomise physics",
    ),
    ("train-rl --device cpu --init-noise-std 0", "--init-noise-std must be > 0 (action units)"),
    ("train-rl --device cpu --mini-batches 0", "--mini-batches must be an integer >= 1"),
    ("evaluate --perturb object_mass=0", "object_mass is a factor, a finite number > 0"),
    ("evaluate --perturb distractors=4", "distractors goes up to 3 objects"),
    ("collect --distractors 4", "--distractors 4: there are 0 to 3 distractor objects"),
    ("pipeline --task GalbotG1-PickToShelf-v0 --distractors -1", "--distractors -1: there are 0 to 3"),
    ("bench --render-orders", "--render-orders times the camera render; add --cameras"),
    ("bench-train --dataset-path src.hdf5 --native-norms", "--native-norms times the bf16 norms"),
    ("render --perturb sweep", "render draws one frame; give AXIS=LEVEL"),
    ("render --perturb action_noise=mild", "acts on an agent's actions, and render runs none"),
    ("mimic --dataset-path nope.hdf5 --episodes 2", "--dataset-path nope.hdf5 does not exist"),
    ("mimic --dataset-path src.hdf5 --output-path out.csv", "unknown dataset suffix"),
    ("mimic --dataset-path src.hdf5 --episodes 0", "--episodes must be an integer >= 1"),
    ("bench --steps -5", "--steps must be an integer >= 1"),
    ("bench --num-envs 0", "--num-envs must be an integer >= 1"),
    ("bench-train --dataset-path nope.hdf5", "--dataset-path nope.hdf5 does not exist"),
    ("pipeline --demos 0", "--demos must be an integer >= 1"),
    ("pipeline --eval-episodes -1", "--eval-episodes must be an integer >= 1"),
    ("pipeline --workers 0", "--workers must be an integer >= 1"),
    ("pipeline --runner bogus", "--runner 'bogus': use local or dask"),
    ("collect --device banana --dataset-path x.hdf5", "--device 'banana' is not a device; use cpu, cuda or cuda:N"),
    (
        "collect --task GalbotG1-SortToShelf-Pick-v0 --sorting-object unicorn --dataset-path x.hdf5",
        "unknown sorting_object 'unicorn'",
    ),
    (
        "collect --task GalbotG1-PickCube-v0 --init-scenario s.yaml --dataset-path x.hdf5",
        "GalbotG1-PickCube-v0 takes no option --init-scenario",
    ),
    ("view nope.hdf5", "dataset nope.hdf5 does not exist"),
    ("train --dataset-path src.hdf5 --checkpoint-every-steps 0", "--checkpoint-every-steps must be an integer >= 1"),
    ("train --dataset-path src.hdf5 --checkpoint-every-s -1", "--checkpoint-every-s must be > 0"),
    ("train --dataset-path src.hdf5 --time-budget-s 0", "--time-budget-s must be > 0"),
    ("train --dataset-path src.hdf5 --max-steps 0", "--max-steps must be an integer >= 1"),
    ("train --dataset-path src.txt", "unknown dataset suffix"),
    # typos: the closest task id / flag is named, answered before Warp (the task ids are read from source)
    (
        "collect --task GalbotG1-PickCub-v0",
        "unknown task id 'GalbotG1-PickCub-v0' (did you mean GalbotG1-PickCube-v0?)",
    ),
    ("evaluate --task GalbotG1-Reach-v1 --episodes 2", "(did you mean GalbotG1-Reach-v0?)"),
    ("pipeline --task GalbotG1-StackCub-v0", "(did you mean GalbotG1-StackCube-v0?)"),
    ("bench --task galbotg1-pickcube-v0", "(did you mean GalbotG1-PickCube-v0?)"),
    ("collect --epsiodes 2", "unrecognized arguments: --epsiodes (did you mean --episodes?) 2"),
    ("bench-train --dataset-path src.hdf5 --batchsize 8", "--batchsize (did you mean --batch-size?)"),
    ("collect --task GalbotG1-PickCube-v0 --dataset-path d/x.txt", "unknown dataset suffix"),  # no d/ left behind
    # an output under a file: the rule of every output (datasets/files/output_paths.py), one line (was `error: 17`)
    ("collect --dataset-path src.hdf5/x.hdf5", "cannot write src.hdf5/x.hdf5: its parent src.hdf5 is a file; choose"),
    ("mimic --dataset-path src.hdf5 --output-path src.hdf5/d/m.hdf5", "src.hdf5, on its path, is a file; choose"),
    # an output folder that cannot be made or takes no file (permission denied, read-only file system, /proc)
    ("collect --dataset-path /sys/nl/x.hdf5", "cannot write /sys/nl/x.hdf5: cannot create the folder /sys/nl ("),
    ("collect --dataset-path /proc/x.hdf5", "cannot write /proc/x.hdf5: /proc takes no new file ("),
    ("export --dataset-path src.hdf5 --root /proc/nl/out", "cannot write /proc/nl/out: cannot create the folder"),
    # refused before Warp: a CUDA device this machine lacks (asked of the driver), a dataset input that is not one,
    # an episode the dataset lacks, a task option value or option the task does not take, a runner
    ("collect --device cuda:7 --dataset-path x.hdf5", "--device cuda:7: "),
    ("evaluate --device cuda:99 --episodes 2", "--device cuda:99: "),
    ("teleop --sim-device cuda:42", "--sim-device cuda:42: "),
    ("mimic --dataset-path junk.hdf5 --episodes 2", "junk.hdf5 is not a newton_lab dataset or is damaged"),
    ("train --dataset-path src.hdf5 junk.hdf5", "junk.hdf5 is not a newton_lab dataset or is damaged"),
    ("bench-train --dataset-path junk.hdf5", "junk.hdf5 is not a newton_lab dataset or is damaged"),
    ("export --dataset-path junk.hdf5 --root out", "junk.hdf5 is not a newton_lab dataset or is damaged"),
    ("split --dataset-path junk.hdf5", "junk.hdf5 is not a newton_lab dataset or is damaged"),
    ("view src.hdf5 --episode 999 --save v.rrd", "--episode 999: src.hdf5 has no episode 999; its 3 episodes: 0, 1, 2"),
    ("view src.hdf5", "view needs --save file.rrd (headless) or --spawn"),
    ("collect --task GalbotG1-SortToShelf-Pick-v0 --sorting-object unicorn", "unknown sorting_object 'unicorn'"),
    ("pipeline --task GalbotG1-PickCube-v0 --sorting-object banana", "takes no option --sorting-object"),
    # split --phases: the phase names recorded in the dataset (a coherent task's), a split by phase only
    (
        "split --dataset-path pts.hdf5 --out parts --phases pick,plase",
        "GalbotG1-PickToShelf-v0 has no phase 'plase' (did you mean place?); its phases: pick, nav, place",
    ),
    ("split --dataset-path pts.hdf5 --phases pick", "--phases selects the phases of a split by phase: give --out"),
    # a damaged or foreign dataset to append to: read from its header (h5py / zarr metadata), before Warp
    ("collect --dataset-path file.zarr", "file.zarr is not a newton_lab dataset or is damaged (not a zarr directory)"),
    ("collect --dataset-path junk.hdf5", "junk.hdf5 is not a newton_lab dataset or is damaged"),
    ("collect --dataset-path folder.hdf5", "folder.hdf5 is not a newton_lab dataset or is damaged (it is a folder"),
    (
        "collect --task GalbotG1-Reach-v0 --dataset-path src.hdf5",
        "src.hdf5 holds a dataset of task 'GalbotG1-PickCube-v0', not 'GalbotG1-Reach-v0'",
    ),
    # a dataset's recording set is part of what it is: other cameras or task options are not appended
    (
        "collect --cameras front_head=96x72 --dataset-path cam.hdf5",
        "cam.hdf5 was recorded with cameras none, not front_head=96x72; append with --cameras none",
    ),
    ("collect --obs-mode sensors --dataset-path cam.hdf5", "cam.hdf5 was recorded with --obs-mode state, not sensors"),
    (
        "collect --task GalbotG1-SortToShelf-Pick-v0 --sorting-object blue_cuboid --dataset-path sort.hdf5",
        "sort.hdf5 was recorded with --sorting-object red_cube, not blue_cuboid; append with --sorting-object red_cube",
    ),
    # cameras: a mount, a resolution, data the G1 has, each once
    ("collect --cameras bogus=96x72 --dataset-path x.hdf5", "--cameras: unknown camera 'bogus'"),
    ("collect --cameras front_haed=96x72 --dataset-path x.hdf5", "(did you mean front_head?)"),
    ("collect --cameras front_head=96x72:rgbd --dataset-path x.hdf5", "data 'rgbd' (did you mean rgb?) is unknown"),
    ("collect --cameras front_head=96x72:rgb+rgb --dataset-path x.hdf5", "names data rgb+rgb with a repeat"),
    ("collect --cameras front_head=2x2 --dataset-path x.hdf5", "resolution 2x2 is out of range; width and height"),
    (
        "collect --cameras front_head=96x72,front_head=96x72 --dataset-path x.hdf5",
        "names camera front_head twice; give each camera once",
    ),
    ("bench --camera left_wirst", "--camera: unknown camera 'left_wirst' (did you mean left_wrist?)"),
    ("bench --camera front_head --resolution 1 1", "resolution 1x1 is out of range"),
    # numbers in range: seeds Warp's kernels and numpy take, rows the memory holds, retries, GPUs the machine has
    ("collect --seed 99999999999999999999 --dataset-path x.hdf5", "--seed must be an integer in [0, 1073741823]"),
    ("collect --seed -1 --dataset-path x.hdf5", "--seed must be an integer in [0, 1073741823]"),
    ("collect --num-envs 10000000 --dataset-path x.hdf5", "--num-envs 10,000,000 needs about 4,883 GiB"),
    (
        "collect --max-steps 99999999999999999 --dataset-path x.hdf5",
        "--max-steps 99,999,999,999,999,999 with --num-envs 1 records about ",
    ),
    ("pipeline --workers 4", "--workers 4 shards the stages over Dask workers, and the local runner runs them in"),
    ("pipeline --runner dask --workers 4096 --device cpu", "--workers 4096: with no CUDA device a local Dask cluster"),
    ("pipeline --retries -1", "--retries must be an integer >= 0 (0: no retry), got -1"),
    ("pipeline --gpus 0", "--gpus must be an integer >= 1, got 0"),
    ("pipeline --eval-max-steps 0", "--eval-max-steps must be an integer >= 1, got 0"),
    (
        "pipeline --task GalbotG1-PickToShelf-v0 --mimic-episodes 4",
        "GalbotG1-PickToShelf-v0 is a coherent task: its pipeline takes more coherent demos (--demos)",
    ),
    ("pipeline --task GalbotG1-Reach-v0", "GalbotG1-Reach-v0 has no Mimic variant, and the pipeline runs collect"),
    ("pipeline --runner dask --address nonsense", "--address 'nonsense' is not a scheduler address"),
    ("pipeline --address tcp://10.0.0.5:8786", "names a Dask scheduler; add --runner dask"),
    ("train --dataset-path src.hdf5 --gpus 4096 --device cpu", "--gpus 4096: with no CUDA device each is a gloo"),
    # checkpoints: the header (zip + pickle, no torch) gives the format and the task
    (
        "evaluate --checkpoint trunc.pt",
        "--checkpoint trunc.pt is not a newton_lab diffusion-policy checkpoint or is "
        "damaged (not a torch.save zip, or truncated)",
    ),
    ("evaluate --checkpoint text.pt", "--checkpoint text.pt is not a newton_lab diffusion-policy checkpoint"),
    ("evaluate --checkpoint earlier", "--checkpoint earlier is a folder; give the checkpoint file in it"),
    (
        "evaluate --checkpoint pick.pt --task GalbotG1-Reach-v0",
        "--checkpoint pick.pt was trained for GalbotG1-PickCube-v0 but the env runs GalbotG1-Reach-v0",
    ),
    (
        "evaluate --checkpoint vis.pt --cameras none",
        "--checkpoint vis.pt sees front_head_rgb at 96x72 px, which "
        "--cameras none does not render; evaluate with --cameras front_head=96x72",
    ),
    ("evaluate --checkpoint vis.pt --cameras front_head=64x48", "which --cameras front_head=64x48 does not render"),
    (
        "evaluate --task GalbotG1-PickToShelf-v0 --phase-checkpoint plase=pick.pt",
        "GalbotG1-PickToShelf-v0 has no phase 'plase' (did you mean place?); its phases: pick, nav, place",
    ),
    (
        "evaluate --task GalbotG1-PickToShelf-v0 --phase-checkpoint pick=pick.pt",
        "but phase 'pick' of GalbotG1-PickToShelf-v0 runs GalbotG1-PickToShelf-Pick-v0; give that phase a checkpoint",
    ),
    (
        "evaluate --task GalbotG1-PickToShelf-v0 --phase-checkpoint nav=text.pt",
        "--phase-checkpoint nav=text.pt is not a newton_lab diffusion-policy checkpoint",
    ),
    (
        "evaluate --task GalbotG1-PickCube-v0 --phase-checkpoint pick=pick.pt",
        "--phase-checkpoint is for the phases of a coherent task, and GalbotG1-PickCube-v0 has none",
    ),
    # what a run found only after Warp loaded: scenarios, recordings, Mimic's source and output, split's source
    (
        "collect --save-end-scenario s.yaml --num-envs 2 --dataset-path x.hdf5",
        "--save-end-scenario needs --num-envs 1 and --episodes 1, got 2 and 1",
    ),
    (
        "collect --task GalbotG1-PickToShelf-Nav-v0 --init-scenario nope.yaml --dataset-path x.hdf5",
        "scenario file nope.yaml does not exist; check the path (or save one with --save-end-scenario)",
    ),
    ("collect --rerun-save x.txt --dataset-path x.hdf5", "--rerun-save x.txt: a rerun recording is an .rrd file"),
    ("mimic --dataset-path reach.pt.hdf5 --episodes 2", "task 'GalbotG1-Reach-v0' has no Mimic variant"),
    (
        "mimic --dataset-path src.hdf5 --output-path pts.hdf5 --episodes 2",
        "pts.hdf5 holds a dataset of task 'GalbotG1-PickToShelf-v0', not 'GalbotG1-PickCube-v0'; choose another",
    ),
    ("mimic --dataset-path src.hdf5 --episodes 2", "src.hdf5: actions do not hold the left arm joints; Mimic needs"),
    ("split --dataset-path src.hdf5 --out parts", "src.hdf5 was recorded on GalbotG1-PickCube-v0, which has no phases"),
    ("pipeline --out afile", "cannot write afile/.prefect: its parent afile is a file; choose another path"),
    ("bench-collect --workers 1 --baseline", "--baseline compares --workers W (W >= 2) with one worker alone"),
    ("train --dataset-path src.hdf5 pts.hdf5", "pts.hdf5 (GalbotG1-PickToShelf-v0) does not match src.hdf5"),
    (
        "train --dataset-path src.hdf5 --output-dir afile",
        "cannot write afile/checkpoint.pt: its parent afile is a file",
    ),
    # split: a new folder, at least one phase
    ("split --dataset-path pts.hdf5 --out afile", "--out afile is a file; split into a new folder"),
    ("split --dataset-path pts.hdf5 --out earlier", "--out earlier is a folder that holds files already"),
    ("split --dataset-path pts.hdf5 --out new --phases ,", "--phases ',' names no phase"),
    # train: what its run found only after torch loaded
    ("train --dataset-path src.hdf5 --preset cpuu", "unknown training preset 'cpuu' (did you mean cpu?); valid"),
    ("train --dataset-path src.hdf5 --obs-keys cube_pose,cube_poze", "records no observation 'cube_poze' (did you"),
    ("train --dataset-path cam.hdf5 --image-keys front_head_rgb", "records no image 'front_head_rgb'"),
    (
        "train --dataset-path src.hdf5 --preset vision --instruction-keys cube_poze",
        "--instruction-keys: src.hdf5 records no observation 'cube_poze'",
    ),
    (
        "train --dataset-path src.hdf5 --instruction-keys cube_pose",
        "--instruction-keys cube_pose condition the image trunks; give image_keys too",
    ),
    ("train --dataset-path src.hdf5 --resume", "no resume file outputs/policy/resume.pt: nothing to resume there"),
    ("train --dataset-path src.hdf5 --lr 0", "--lr must be > 0, got 0.0"),
    (
        "train --dataset-path src.hdf5 --init-checkpoint reach.pt",
        "--init-checkpoint reach.pt was trained for GalbotG1-Reach-v0 and src.hdf5 holds GalbotG1-PickCube-v0",
    ),
]

"""(command line after ``newton-lab``, words its one-line refusal holds), run in a folder :func:`make_inputs`
filled."""

TASK = "GalbotG1-PickCube-v0"
JOINTS = [f"joint_{i}" for i in range(7)] + ["gripper"]
"""Action columns of the sample datasets: not the G1's arm joints (Mimic refuses them)."""
OBS = {"robot_joint_pos": 34, "tcp_pose": 7, "gripper_pos": 1, "cube_pose": 7, "blue_block_pos": 3, "actions": 8}
"""Observation terms of the sample datasets and their widths."""
LENGTHS = (12, 7, 9)
"""Steps of src.hdf5's three demos (demo 1 failed)."""


def _obs_terms() -> dict[str, list[int]]:
    out, col = {}, 0
    for name, width in OBS.items():
        out[name] = [col, col + width]
        col += width
    return out


ENV_ARGS: dict[str, Any] = {
    "env_kwargs": {"num_envs": 2, "seed": 0},
    "newton_lab": {"sim_dt": 0.01, "decimation": 5, "action_joint_names": JOINTS, "obs_terms": _obs_terms()},
}
"""The ``env_args`` the sample datasets record."""


def sample_episode(seed: int, steps: int) -> dict[str, Any]:
    """A made-up episode of ``steps`` steps with the sample datasets' actions, observations and states."""
    rng = np.random.default_rng(seed)
    actions = rng.standard_normal((steps, len(JOINTS))).astype(np.float32)
    obs = {name: rng.standard_normal((steps, w)).astype(np.float32) for name, w in OBS.items() if name != "actions"}
    obs["actions"] = actions.copy()
    return {
        "actions": actions,
        "obs": obs,
        "states": rng.standard_normal((steps, 81)).astype(np.float32),
        "rewards": rng.random(steps).astype(np.float32),
        "dones": np.zeros(steps, dtype=np.int64),
        "datagen": {
            "tcp_pose": rng.standard_normal((steps, 7)).astype(np.float32),
            "phase": np.arange(steps, dtype=np.int32),
        },
    }


def _dataset(path: Path, task: str, env_args: dict[str, Any], lengths=(5,), failed=()) -> None:
    with open_writer(path, task_id=task, env_args=env_args, fsync=False) as w:
        for i, steps in enumerate(lengths):
            ok = i not in failed
            w.append_episode(
                sample_episode(i, steps), success=ok, attrs={"termination_reason": "success" if ok else "timeout"}
            )


def checkpoint_files() -> dict[str, bytes]:
    """Checkpoints as ``torch.save`` writes them (the header the checks read: format, version, config, info): of
    PickCube (pick.pt), Reach (reach.pt), a visuomotor PickCube policy (vis.pt, front camera RGB at 96 x 72), a
    truncated one and a text file."""
    import torch  # deferred: torch is slow to import, and only the files are made with it

    def saved(config: dict[str, Any], info: dict[str, Any]) -> bytes:
        buf = io.BytesIO()
        torch.save(
            {
                "format": CHECKPOINT_FORMAT,
                "version": CHECKPOINT_VERSION,
                "backend": "diffusion",
                "config": config,
                "weights": {"w": torch.zeros(64)},
                "normalizers": {},
                "info": info,
            },
            buf,
        )
        return buf.getvalue()

    out = {
        "pick.pt": saved({}, {"task_id": TASK}),
        "reach.pt": saved({}, {"task_id": "GalbotG1-Reach-v0"}),
        "vis.pt": saved(
            {"image_keys": ["front_head_rgb"]}, {"task_id": TASK, "image_shapes": {"front_head_rgb": [72, 96, 3]}}
        ),
    }
    out["trunc.pt"] = out["pick.pt"][: len(out["pick.pt"]) // 2]
    out["text.pt"] = b"a checkpoint, honest\n"
    return out


def make_inputs(root: Path, checkpoints: dict[str, bytes] | None = None) -> None:
    """Write into ``root`` what the cases name: datasets (src.hdf5: PickCube, demos 0, 1, 2; pts.hdf5: recorded on
    the coherent PickToShelf; cam.hdf5: state only, no camera; reach.pt.hdf5: Reach, which has no Mimic variant;
    sort.hdf5: SortToShelf's pick of the red cube),
    damaged ones (junk.hdf5, file.zarr, folder.hdf5), a file and a non-empty folder in the way (afile, earlier/)
    and the checkpoints (``checkpoints``: those of :func:`checkpoint_files`, made when not given)."""
    root = Path(root)
    _dataset(root / "src.hdf5", TASK, ENV_ARGS, LENGTHS, failed=(1,))
    _dataset(
        root / "pts.hdf5",
        "GalbotG1-PickToShelf-v0",
        {**ENV_ARGS, "newton_lab": {**ENV_ARGS["newton_lab"], "phases": ["pick", "nav", "place"]}},
    )
    _dataset(
        root / "cam.hdf5",
        TASK,
        {
            "env_kwargs": {"task_options": {"obs_mode": "state"}},
            "newton_lab": {**ENV_ARGS["newton_lab"], "cameras": {}},
        },
    )
    _dataset(root / "reach.pt.hdf5", "GalbotG1-Reach-v0", ENV_ARGS)
    _dataset(
        root / "sort.hdf5",
        "GalbotG1-SortToShelf-Pick-v0",
        {**ENV_ARGS, "env_kwargs": {"task_options": {"sorting_object": "red_cube"}}},
    )
    (root / "junk.hdf5").write_bytes(b"not a dataset")
    (root / "file.zarr").write_bytes(b"a file named .zarr")
    (root / "folder.hdf5").mkdir()
    (root / "afile").write_text("a file")
    (root / "earlier").mkdir()
    (root / "earlier" / "pick.hdf5").write_text("an earlier split's file")
    for name, data in (checkpoints or checkpoint_files()).items():
        (root / name).write_bytes(data)
