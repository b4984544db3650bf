"""Bad command-line input is refused in one line, with exit status 2, before Warp is imported and before any
file is written (the working folder is left as it was)."""

from __future__ import annotations

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
    ("view nope.hdf5", "dataset nope.hdf5 does not exist"),
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
