"""Bad command-line input is refused in one line, with exit status 2, before Warp is imported and before any
file is written (the working folder is left as it was)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from newton_lab.commands.refusal_cases import CASES, checkpoint_files, make_inputs

CHECK = (
    "import sys; from newton_lab.cli import main; rc = main(sys.argv[1:]); "
    "sys.exit(rc if 'warp' not in sys.modules and 'torch' not in sys.modules else 99)"
)


@pytest.mark.parametrize("argv,message", CASES, ids=[b[0] for b in CASES])
def test_bad_input_is_one_line_exit_2_and_leaves_nothing(tmp_path, argv, message, checkpoints):
    make_inputs(tmp_path, checkpoints)  # the datasets, checkpoints and files in the way that the cases name
    before = tree(tmp_path)
    out = subprocess.run([sys.executable, "-c", CHECK, *argv.split()], cwd=tmp_path, capture_output=True, text=True)
    assert out.returncode == 2, (out.returncode, out.stderr)  # 99: Warp was imported first
    assert out.stderr.count("\n") == 1 and message in out.stderr, out.stderr
    assert tree(tmp_path) == before  # how long the refusals take: `newton-lab bench-refusals` (no timed assert)


@pytest.fixture(scope="module")
def checkpoints() -> dict[str, bytes]:
    """The cases' checkpoint files, made once (torch.save)."""
    return checkpoint_files()


def test_the_checkpoint_header_reader_agrees_with_the_checkpoint_format():
    """``commands.checkpoint_headers`` reads checkpoints without torch: its format tag and version are the policy's."""
    from newton_lab.commands import checkpoint_headers as headers
    from newton_lab.policies import diffusion

    assert (headers.CHECKPOINT_FORMAT, headers.CHECKPOINT_VERSION) == (
        diffusion.CHECKPOINT_FORMAT,
        diffusion.CHECKPOINT_VERSION,
    )


def test_phases_and_mimic_sources_read_from_source_match_the_registry():
    """The coherent tasks' phases (name, component) and the Mimic variants' sources that the checks read from the
    task packages' source are the registry's."""
    import newton_lab.tasks  # noqa: F401

    from newton_lab.task_api.catalog import declared_mimic_arms, declared_phases, declared_sources
    from newton_lab.task_api.registry import list_tasks, lookup

    phases = {t: tuple((p.name, p.task_id) for p in lookup(t).make_cfg({}).phases) for t in list_tasks()}
    assert declared_phases() == {t: p for t, p in phases.items() if p}
    assert declared_sources() == {t: lookup(t).source_task for t in list_tasks() if lookup(t).source_task}
    assert declared_mimic_arms() == {
        lookup(t).source_task: lookup(t).mimic.arm for t in list_tasks() if lookup(t).source_task
    }


def tree(root: Path) -> dict[str, tuple[int, int]]:
    """Every path under ``root`` with its size and modification time."""
    return {str(p.relative_to(root)): (p.stat().st_size, p.stat().st_mtime_ns) for p in sorted(root.rglob("*"))}


def test_disk_full_during_collect_ends_in_one_line_exit_1(tmp_path):
    """The injected ENOSPC (the writer's test seam) hits after the first episode: exit 1, one line saying what
    the dataset holds, and that episode stays readable."""
    from newton_lab.datasets import read_dataset_info, read_episode

    argv = [
        "collect",
        "--episodes",
        "4",
        "--num-envs",
        "1",
        "--max-steps",
        "5",
        "--dataset-path",
        "d.hdf5",
        "--no-progress",
        "--cameras",
        "none",
    ]
    # A writer queue of one episode makes every batch one episode: with the default queue, a writer thread that
    # the OS schedules late takes episodes 1 and 2 as one batch, and the fault then rolls both back.
    # The fault is armed by this launcher through the writers' seam: the 140th write is inside the second episode's.
    one_per_batch = (
        "import sys; from newton_lab.envs import rollout; rollout.collect.__kwdefaults__['max_queued'] = 1;"
        " from newton_lab.datasets.files.write_faults import inject_write_fault; inject_write_fault(140);"
        " from newton_lab.cli import main; sys.exit(main(sys.argv[1:]))"
    )
    out = subprocess.run([sys.executable, "-c", one_per_batch, *argv], cwd=tmp_path, capture_output=True, text=True)
    errors = [line for line in out.stderr.splitlines() if "CUDA driver" not in line]
    assert out.returncode == 1 and len(errors) == 1, out.stderr
    assert "disk full after 1 episode; d.hdf5 holds 1 finished episode" in errors[0]
    assert read_dataset_info(tmp_path / "d.hdf5")["demo_ids"] == [0]
    assert read_episode(tmp_path / "d.hdf5", 0)["actions"].shape[0] == 5


@pytest.mark.parametrize(
    "device, devices, words",
    [
        ("cuda:2", 2, "--device cuda:2: this machine has 2 CUDA devices (cuda:0 to cuda:1); use one of them or cpu"),
        ("cuda:1", 1, "--device cuda:1: this machine has 1 CUDA device (cuda:0); use one of them or cpu"),
        ("cuda", 0, "--device cuda: no CUDA device here (the driver shows no device); use --device cpu"),
        ("cuda:0", "no NVIDIA driver: libcuda.so.1 not found", "(no NVIDIA driver: libcuda.so.1 not found)"),
    ],
)
def test_a_cuda_device_the_machine_lacks_is_refused(device, devices, words):
    """The GPU side of the device check (CI has no GPU): what the driver's count gives."""
    from newton_lab.commands.device_checks import check_cuda_device

    with pytest.raises(ValueError) as err:
        check_cuda_device("--device", device, devices)
    assert words in str(err.value) and "\n" not in str(err.value)
    check_cuda_device("--device", "cuda:1", 2)  # one it has
    check_cuda_device("--device", "cuda", 1)


def test_the_device_count_comes_from_the_driver_in_a_child_process():
    """This process never loads the CUDA driver for the check (it may fork workers later); without a driver the
    count says why."""
    from newton_lab.commands.device_checks import cuda_devices

    answer = cuda_devices()
    assert isinstance(answer, int) or "libcuda.so.1" in answer or "CUDA error" in answer, answer
    code = (
        "from newton_lab.commands.device_checks import cuda_devices; cuda_devices(); "
        "print('libcuda.so' in open('/proc/self/maps').read())"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_env_rows_are_checked_against_the_memory_that_holds_them():
    """``--num-envs`` times the per-row estimate against the machine's (or, for cuda, the GPU's) memory: a GPU host's
    16384 rows pass, ten million do not, and the line names the largest count that fits."""
    from newton_lab.commands.device_checks import ENV_BYTES, check_num_envs

    check_num_envs(16384, memory=80 << 30)
    with pytest.raises(ValueError) as err:
        check_num_envs(10_000_000, memory=80 << 30)
    assert f"use at most --num-envs {(80 << 30) // ENV_BYTES:,}" in str(err.value) and "\n" not in str(err.value)
