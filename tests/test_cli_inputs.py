"""Bad command-line input is refused in one line, with exit status 2, before Warp is imported and before any
file is written (the working folder is left as it was)."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

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
]
CHECK = "import sys; from newton_lab.cli import main; rc = main(sys.argv[1:]); sys.exit(rc if 'warp' not in sys.modules else 99)"


@pytest.mark.parametrize("argv,message", BAD, ids=[b[0] for b in BAD])
def test_bad_input_is_one_line_exit_2_and_leaves_nothing(tmp_path, argv, message):
    (tmp_path / "src.hdf5").write_bytes(b"")  # an existing (empty) source, for the checks that need one
    before = sorted(p.name for p in tmp_path.iterdir())
    out = subprocess.run([sys.executable, "-c", CHECK, *argv.split()], cwd=tmp_path, capture_output=True, text=True)
    assert out.returncode == 2, (out.returncode, out.stderr)
    assert out.stderr.count("\n") == 1 and message in out.stderr, out.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == before


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
