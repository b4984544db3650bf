"""Bad command-line input is refused in one line, with exit status 2, before Warp is imported and before any
file is written (the working folder is left as it was)."""

from __future__ import annotations

import os
import resource
import subprocess
import sys
from pathlib import Path

import pytest

from test_lerobot_export import make_dataset

BAD = [
    ("collect --episodes 0 --dataset-path x.hdf5", "--episodes must be an integer >= 1"),
    ("collect --episodes -3 --dataset-path x.hdf5", "--episodes must be an integer >= 1"),
    ("collect --max-steps 0 --dataset-path x.hdf5", "--max-steps must be an integer >= 1"),
    ("collect --num-envs 0 --dataset-path x.hdf5", "--num-envs must be an integer >= 1"),
    ("collect --dataset-path x.txt", "unknown dataset suffix"),
    ("evaluate --episodes 0", "--episodes must be an integer >= 1"),
    ("evaluate --checkpoint nope.pt", "--checkpoint nope.pt does not exist"),
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
    ("collect --task GalbotG1-SortToShelf-Pick-v0 --sorting-object unicorn --dataset-path x.hdf5",
     "unknown sorting_object 'unicorn'"),
    ("collect --task GalbotG1-PickCube-v0 --init-scenario s.yaml --dataset-path x.hdf5",
     "GalbotG1-PickCube-v0 takes no option --init-scenario"),
    ("view nope.hdf5", "dataset nope.hdf5 does not exist"),
    ("train --dataset-path src.hdf5 --checkpoint-every-steps 0", "--checkpoint-every-steps must be an integer >= 1"),
    ("train --dataset-path src.hdf5 --checkpoint-every-s -1", "--checkpoint-every-s must be > 0"),
    ("train --dataset-path src.hdf5 --time-budget-s 0", "--time-budget-s must be > 0"),
    ("train --dataset-path src.hdf5 --max-steps 0", "--max-steps must be an integer >= 1"),
    ("train --dataset-path src.txt", "unknown dataset suffix"),
    # typos: the closest task id / flag is named, answered before Warp (the task ids are read from source)
    ("collect --task GalbotG1-PickCub-v0", "unknown task id 'GalbotG1-PickCub-v0' (did you mean GalbotG1-PickCube-v0?)"),
    ("evaluate --task GalbotG1-Reach-v1 --episodes 2", "(did you mean GalbotG1-Reach-v0?)"),
    ("pipeline --task GalbotG1-StackCub-v0", "(did you mean GalbotG1-StackCube-v0?)"),
    ("bench --task galbotg1-pickcube-v0", "(did you mean GalbotG1-PickCube-v0?)"),
    ("collect --epsiodes 2", "unrecognized arguments: --epsiodes (did you mean --episodes?) 2"),
    ("bench-train --dataset-path src.hdf5 --batchsize 8", "--batchsize (did you mean --batch-size?)"),
    ("collect --task GalbotG1-PickCube-v0 --dataset-path d/x.txt", "unknown dataset suffix"),  # no d/ left behind
    # an output under a file: the rule of every output (datasets/outputs.py), one line (was `error: 17`)
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
    ("split --dataset-path pts.hdf5 --out parts --phases pick,plase",
     "GalbotG1-PickToShelf-v0 has no phase 'plase' (did you mean place?); its phases: pick, nav, place"),
    ("split --dataset-path pts.hdf5 --phases pick", "--phases selects the phases of a split by phase: give --out"),
    # a damaged or foreign dataset to append to: read from its header (h5py / zarr metadata), before Warp
    ("collect --dataset-path file.zarr", "file.zarr is not a newton_lab dataset or is damaged (not a zarr directory)"),
    ("collect --dataset-path junk.hdf5", "junk.hdf5 is not a newton_lab dataset or is damaged"),
    ("collect --dataset-path folder.hdf5", "folder.hdf5 is not a newton_lab dataset or is damaged (it is a folder"),
    ("collect --task GalbotG1-Reach-v0 --dataset-path src.hdf5",
     "src.hdf5 holds a dataset of task 'GalbotG1-PickCube-v0', not 'GalbotG1-Reach-v0'"),
    # a dataset's recording set is part of what it is: other cameras or task options are not appended
    ("collect --cameras front_head=96x72 --dataset-path cam.hdf5",
     "cam.hdf5 was recorded with cameras none, not front_head=96x72; append with --cameras none"),
    ("collect --obs-mode sensors --dataset-path cam.hdf5", "cam.hdf5 was recorded with --obs-mode state, not sensors"),
    # cameras: a mount, a resolution, data the G1 has, each once
    ("collect --cameras bogus=96x72 --dataset-path x.hdf5", "--cameras: unknown camera 'bogus'"),
    ("collect --cameras front_haed=96x72 --dataset-path x.hdf5", "(did you mean front_head?)"),
    ("collect --cameras front_head=96x72:rgbd --dataset-path x.hdf5", "data 'rgbd' (did you mean rgb?) is unknown"),
    ("collect --cameras front_head=96x72:rgb+rgb --dataset-path x.hdf5", "names data rgb+rgb with a repeat"),
    ("collect --cameras front_head=2x2 --dataset-path x.hdf5", "resolution 2x2 is out of range; width and height"),
    ("collect --cameras front_head=96x72,front_head=96x72 --dataset-path x.hdf5",
     "names camera front_head twice; give each camera once"),
    ("bench --camera left_wirst", "--camera: unknown camera 'left_wirst' (did you mean left_wrist?)"),
    ("bench --camera front_head --resolution 1 1", "resolution 1x1 is out of range"),
    # numbers in range: seeds Warp's kernels and numpy take, rows the memory holds, retries, GPUs the machine has
    ("collect --seed 99999999999999999999 --dataset-path x.hdf5", "--seed must be an integer in [0, 1073741823]"),
    ("collect --seed -1 --dataset-path x.hdf5", "--seed must be an integer in [0, 1073741823]"),
    ("collect --num-envs 10000000 --dataset-path x.hdf5", "--num-envs 10,000,000 needs about 4,883 GiB"),
    ("pipeline --retries -1", "--retries must be an integer >= 0 (0: no retry), got -1"),
    ("pipeline --gpus 0", "--gpus must be an integer >= 1, got 0"),
    ("pipeline --eval-max-steps 0", "--eval-max-steps must be an integer >= 1, got 0"),
    ("pipeline --task GalbotG1-PickToShelf-v0 --mimic-episodes 4",
     "GalbotG1-PickToShelf-v0 is a coherent task: its pipeline takes more coherent demos (--demos)"),
    ("pipeline --task GalbotG1-Reach-v0", "GalbotG1-Reach-v0 has no Mimic variant, and the pipeline runs collect"),
    ("pipeline --runner dask --address nonsense", "--address 'nonsense' is not a scheduler address"),
    ("pipeline --address tcp://10.0.0.5:8786", "names a Dask scheduler; add --runner dask"),
    ("train --dataset-path src.hdf5 --gpus 4096 --device cpu", "--gpus 4096: with no CUDA device each is a gloo"),
    # checkpoints: the header (zip + pickle, no torch) gives the format and the task
    ("evaluate --checkpoint trunc.pt", "--checkpoint trunc.pt is not a newton_lab diffusion-policy checkpoint or is "
     "damaged (not a torch.save zip, or truncated)"),
    ("evaluate --checkpoint text.pt", "--checkpoint text.pt is not a newton_lab diffusion-policy checkpoint"),
    ("evaluate --checkpoint earlier", "--checkpoint earlier is a folder; give the checkpoint file in it"),
    ("evaluate --checkpoint pick.pt --task GalbotG1-Reach-v0",
     "--checkpoint pick.pt was trained for GalbotG1-PickCube-v0 but the env runs GalbotG1-Reach-v0"),
    ("evaluate --checkpoint vis.pt --cameras none", "--checkpoint vis.pt sees front_head_rgb at 96x72 px, which "
     "--cameras none does not render; evaluate with --cameras front_head=96x72"),
    ("evaluate --checkpoint vis.pt --cameras front_head=64x48", "which --cameras front_head=64x48 does not render"),
    ("evaluate --task GalbotG1-PickToShelf-v0 --phase-checkpoint plase=pick.pt",
     "GalbotG1-PickToShelf-v0 has no phase 'plase' (did you mean place?); its phases: pick, nav, place"),
    ("evaluate --task GalbotG1-PickToShelf-v0 --phase-checkpoint pick=pick.pt",
     "but phase 'pick' of GalbotG1-PickToShelf-v0 runs GalbotG1-PickToShelf-Pick-v0; give that phase a checkpoint"),
    ("evaluate --task GalbotG1-PickToShelf-v0 --phase-checkpoint nav=text.pt",
     "--phase-checkpoint nav=text.pt is not a newton_lab diffusion-policy checkpoint"),
    ("evaluate --task GalbotG1-PickCube-v0 --phase-checkpoint pick=pick.pt",
     "--phase-checkpoint is for the phases of a coherent task, and GalbotG1-PickCube-v0 has none"),
    # what a run found only after Warp loaded: scenarios, recordings, Mimic's source and output, split's source
    ("collect --save-end-scenario s.yaml --num-envs 2 --dataset-path x.hdf5",
     "--save-end-scenario needs --num-envs 1 and --episodes 1, got 2 and 1"),
    ("collect --task GalbotG1-PickToShelf-Nav-v0 --init-scenario nope.yaml --dataset-path x.hdf5",
     "scenario file nope.yaml does not exist; check the path (or save one with --save-end-scenario)"),
    ("collect --rerun-save x.txt --dataset-path x.hdf5", "--rerun-save x.txt: a rerun recording is an .rrd file"),
    ("mimic --dataset-path reach.pt.hdf5 --episodes 2", "task 'GalbotG1-Reach-v0' has no Mimic variant"),
    ("mimic --dataset-path src.hdf5 --output-path pts.hdf5 --episodes 2",
     "pts.hdf5 holds a dataset of task 'GalbotG1-PickToShelf-v0', not 'GalbotG1-PickCube-v0'; choose another"),
    ("mimic --dataset-path src.hdf5 --episodes 2", "src.hdf5: actions do not hold the left arm joints; Mimic needs"),
    ("split --dataset-path src.hdf5 --out parts", "src.hdf5 was recorded on GalbotG1-PickCube-v0, which has no phases"),
    ("pipeline --out afile", "cannot write afile/.prefect: its parent afile is a file; choose another path"),
    ("bench-collect --workers 1 --baseline", "--baseline compares --workers W (W >= 2) with one worker alone"),
    ("train --dataset-path src.hdf5 pts.hdf5", "pts.hdf5 (GalbotG1-PickToShelf-v0) does not match src.hdf5"),
    ("train --dataset-path src.hdf5 --output-dir afile", "cannot write afile/checkpoint.pt: its parent afile is a file"),
    # split: a new folder, at least one phase
    ("split --dataset-path pts.hdf5 --out afile", "--out afile is a file; split into a new folder"),
    ("split --dataset-path pts.hdf5 --out earlier", "--out earlier is a folder that holds files already"),
    ("split --dataset-path pts.hdf5 --out new --phases ,", "--phases ',' names no phase"),
    # train: what its run found only after torch loaded
    ("train --dataset-path src.hdf5 --preset cpuu", "unknown training preset 'cpuu' (did you mean cpu?); valid"),
    ("train --dataset-path src.hdf5 --obs-keys cube_pose,cube_poze", "records no observation 'cube_poze' (did you"),
    ("train --dataset-path cam.hdf5 --image-keys front_head_rgb", "records no image 'front_head_rgb'"),
    ("train --dataset-path src.hdf5 --resume", "no resume file outputs/policy/resume.pt: nothing to resume there"),
    ("train --dataset-path src.hdf5 --lr 0", "--lr must be > 0, got 0.0"),
    ("train --dataset-path src.hdf5 --init-checkpoint reach.pt",
     "--init-checkpoint reach.pt was trained for GalbotG1-Reach-v0 and src.hdf5 holds GalbotG1-PickCube-v0"),
]
CPU_SECONDS = 2.0
"""Each refusal's CPU time, interpreter start included (0.2-0.6 s here; importing Warp first took 5-12 s on 2 cores).
CPU time and not wall time: the latter grows with whatever else runs on the cores (up to 1.5 s measured at a load
of 7 on 2 cores)."""
CHECK = ("import sys; from newton_lab.cli import main; rc = main(sys.argv[1:]); "
         "sys.exit(rc if 'warp' not in sys.modules and 'torch' not in sys.modules else 99)")


@pytest.mark.parametrize("argv,message", BAD, ids=[b[0] for b in BAD])
def test_bad_input_is_one_line_exit_2_and_leaves_nothing(tmp_path, argv, message, checkpoints):
    make_dataset(tmp_path / "src.hdf5")  # a source dataset (demos 0, 1, 2), for the checks that need one
    make_coherent_dataset(tmp_path / "pts.hdf5")
    make_fixtures(tmp_path, checkpoints)
    before = tree(tmp_path)
    start = cpu_of_children()
    out = subprocess.run([sys.executable, "-c", CHECK, *argv.split()], cwd=tmp_path, capture_output=True, text=True)
    seconds = cpu_of_children() - start
    assert out.returncode == 2, (out.returncode, out.stderr)  # 99: Warp was imported first
    assert out.stderr.count("\n") == 1 and message in out.stderr, out.stderr
    assert tree(tmp_path) == before
    assert seconds < CPU_SECONDS, f"{seconds:.2f} s of CPU"


@pytest.fixture(scope="module")
def checkpoints(tmp_path_factory) -> dict[str, bytes]:
    """Checkpoints as ``torch.save`` writes them (the header the checks read: format, version, config, info), of
    PickCube and Reach, and a truncated one."""
    import io

    import torch

    from newton_lab.policies.diffusion import CHECKPOINT_FORMAT, CHECKPOINT_VERSION

    out = {}
    for name, task in (("pick.pt", "GalbotG1-PickCube-v0"), ("reach.pt", "GalbotG1-Reach-v0")):
        buf = io.BytesIO()
        torch.save({"format": CHECKPOINT_FORMAT, "version": CHECKPOINT_VERSION, "backend": "diffusion", "config": {},
                    "weights": {"w": torch.zeros(64)}, "normalizers": {}, "info": {"task_id": task}}, buf)
        out[name] = buf.getvalue()
    buf = io.BytesIO()  # a visuomotor policy: it sees the front camera's RGB at 96 x 72
    torch.save({"format": CHECKPOINT_FORMAT, "version": CHECKPOINT_VERSION, "backend": "diffusion",
                "config": {"image_keys": ["front_head_rgb"]}, "weights": {"w": torch.zeros(64)}, "normalizers": {},
                "info": {"task_id": "GalbotG1-PickCube-v0", "image_shapes": {"front_head_rgb": [72, 96, 3]}}}, buf)
    out["vis.pt"] = buf.getvalue()
    out["trunc.pt"] = out["pick.pt"][: len(out["pick.pt"]) // 2]
    out["text.pt"] = b"a checkpoint, honest\n"
    return out


def make_fixtures(root: Path, checkpoints: dict[str, bytes]) -> None:
    """What the bad-input cases refer to beside src.hdf5 and pts.hdf5."""
    from newton_lab.datasets import open_writer
    from test_lerobot_export import ENV_ARGS, make_episode

    (root / "junk.hdf5").write_bytes(b"not a dataset")
    (root / "file.zarr").write_bytes(b"a file named .zarr")
    (root / "folder.hdf5").mkdir()
    (root / "afile").write_text("a file")
    (root / "earlier").mkdir()
    (root / "earlier" / "pick.hdf5").write_text("an earlier split's file")
    for name, data in checkpoints.items():
        (root / name).write_bytes(data)
    args = {"env_kwargs": {"task_options": {"obs_mode": "state"}},
            "newton_lab": {**ENV_ARGS["newton_lab"], "cameras": {}}}  # recorded state only, no camera
    with open_writer(root / "cam.hdf5", task_id="GalbotG1-PickCube-v0", env_args=args, fsync=False) as w:
        w.append_episode(make_episode(0, 5, None, False, 1), success=True)
    with open_writer(root / "reach.pt.hdf5", task_id="GalbotG1-Reach-v0", env_args=ENV_ARGS, fsync=False) as w:
        w.append_episode(make_episode(0, 5, None, False, 1), success=True)  # a task without a Mimic variant


def test_the_checkpoint_header_reader_agrees_with_the_checkpoint_format():
    """``cli.headers`` reads checkpoints without torch: its format tag and version are the policy's."""
    from newton_lab.cli import headers
    from newton_lab.policies import diffusion

    assert (headers.CHECKPOINT_FORMAT, headers.CHECKPOINT_VERSION) == (diffusion.CHECKPOINT_FORMAT,
                                                                       diffusion.CHECKPOINT_VERSION)


def test_phases_and_mimic_sources_read_from_source_match_the_registry():
    """The coherent tasks' phases (name, component) and the Mimic variants' sources that the checks read from the
    task packages' source are the registry's."""
    import newton_lab.tasks  # noqa: F401
    from newton_lab.task_api.catalog import declared_mimic_arms, declared_phases, declared_sources
    from newton_lab.task_api.registry import list_tasks, lookup

    phases = {t: tuple((p.name, p.task_id) for p in lookup(t).make_cfg({}).phases) for t in list_tasks()}
    assert declared_phases() == {t: p for t, p in phases.items() if p}
    assert declared_sources() == {t: lookup(t).source_task for t in list_tasks() if lookup(t).source_task}
    assert declared_mimic_arms() == {lookup(t).source_task: lookup(t).mimic.arm for t in list_tasks()
                                     if lookup(t).source_task}


def make_coherent_dataset(path: Path) -> None:
    """One demo whose ``env_args`` say it was recorded on PickToShelf (phases pick, nav, place)."""
    from newton_lab.datasets import open_writer
    from test_lerobot_export import ENV_ARGS, make_episode

    args = {**ENV_ARGS, "newton_lab": {**ENV_ARGS["newton_lab"], "phases": ["pick", "nav", "place"]}}
    with open_writer(path, task_id="GalbotG1-PickToShelf-v0", env_args=args, fsync=False) as w:
        w.append_episode(make_episode(0, 5, None, False, 1), success=True)


def cpu_of_children() -> float:
    """User + system CPU seconds of this process's finished children (and theirs)."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def tree(root: Path) -> dict[str, tuple[int, int]]:
    """Every path under ``root`` with its size and modification time."""
    return {str(p.relative_to(root)): (p.stat().st_size, p.stat().st_mtime_ns) for p in sorted(root.rglob("*"))}


def test_disk_full_during_collect_ends_in_one_line_exit_1(tmp_path):
    """The injected ENOSPC (the writer's test seam) hits after the first episode: exit 1, one line saying what
    the dataset holds, and that episode stays readable."""
    from newton_lab.datasets import read_dataset_info, read_episode

    env = {**os.environ, "NEWTON_LAB_TEST_WRITE_FAULT": "140"}  # inside the second episode's writes
    argv = ["collect", "--episodes", "4", "--num-envs", "1", "--max-steps", "5", "--dataset-path", "d.hdf5",
            "--no-progress", "--cameras", "none"]
    # A writer queue of one episode makes every batch one episode: with the default queue, a writer thread that
    # the OS schedules late takes episodes 1 and 2 as one batch, and the fault then rolls both back.
    one_per_batch = ("import sys; from newton_lab.envs import rollout; rollout.collect.__kwdefaults__['max_queued'] = 1;"
                     " from newton_lab.cli import main; sys.exit(main(sys.argv[1:]))")
    out = subprocess.run([sys.executable, "-c", one_per_batch, *argv], cwd=tmp_path, capture_output=True,
                         text=True, env=env)
    errors = [line for line in out.stderr.splitlines() if "CUDA driver" not in line]
    assert out.returncode == 1 and len(errors) == 1, out.stderr
    assert "disk full after 1 episode; d.hdf5 holds 1 finished episode" in errors[0]
    assert read_dataset_info(tmp_path / "d.hdf5")["demo_ids"] == [0]
    assert read_episode(tmp_path / "d.hdf5", 0)["actions"].shape[0] == 5


@pytest.mark.parametrize("device, devices, words", [
    ("cuda:2", 2, "--device cuda:2: this machine has 2 CUDA devices (cuda:0 to cuda:1); use one of them or cpu"),
    ("cuda:1", 1, "--device cuda:1: this machine has 1 CUDA device (cuda:0); use one of them or cpu"),
    ("cuda", 0, "--device cuda: no CUDA device here (the driver shows no device); use --device cpu"),
    ("cuda:0", "no NVIDIA driver: libcuda.so.1 not found", "(no NVIDIA driver: libcuda.so.1 not found)"),
])
def test_a_cuda_device_the_machine_lacks_is_refused(device, devices, words):
    """The GPU side of the device check (CI has no GPU): what the driver's count gives."""
    from newton_lab.cli.checks import check_cuda_device

    with pytest.raises(ValueError) as err:
        check_cuda_device("--device", device, devices)
    assert words in str(err.value) and "\n" not in str(err.value)
    check_cuda_device("--device", "cuda:1", 2)  # one it has
    check_cuda_device("--device", "cuda", 1)


def test_the_device_count_comes_from_the_driver_in_a_child_process():
    """This process never loads the CUDA driver for the check (it may fork workers later); without a driver the
    count says why."""
    from newton_lab.cli.checks import cuda_devices

    answer = cuda_devices()
    assert isinstance(answer, int) or "libcuda.so.1" in answer or "CUDA error" in answer, answer
    code = ("from newton_lab.cli.checks import cuda_devices; cuda_devices(); "
            "print('libcuda.so' in open('/proc/self/maps').read())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_env_rows_are_checked_against_the_memory_that_holds_them():
    """``--num-envs`` times the per-row estimate against the machine's (or, for cuda, the GPU's) memory: a GPU host's
    16384 rows pass, ten million do not, and the line names the largest count that fits."""
    from newton_lab.cli.checks import ENV_BYTES, check_num_envs

    check_num_envs(16384, memory=80 << 30)
    with pytest.raises(ValueError) as err:
        check_num_envs(10_000_000, memory=80 << 30)
    assert f"use at most --num-envs {(80 << 30) // ENV_BYTES:,}" in str(err.value) and "\n" not in str(err.value)
