"""newton_lab's process-wide Warp settings (``kernels/runtime.py``): no adjoint kernels unless asked for, applied
to Newton's modules as well as the project's, whichever of Warp and newton_lab is imported first."""

import json
import os
import subprocess
import sys

import pytest

PROBE = """
import json, sys
if sys.argv[1] == "warp_first":
    import warp
import newton_lab
import warp as wp
import newton._src.sim.articulation as articulation  # a Newton module created after newton_lab's import
from newton_lab.kernels import fuse
print(json.dumps({"config": wp.config.enable_backward,
                  "newton": articulation.eval_articulation_fk.module.options["enable_backward"],
                  "project": fuse.keep_terminal_coords.module.options["enable_backward"]}))
"""


def _probe(order: str, **env: str) -> dict:
    child = {k: v for k, v in os.environ.items() if k != "NEWTON_LAB_WARP_BACKWARD"} | env
    out = subprocess.run([sys.executable, "-c", PROBE, order], capture_output=True, text=True, env=child, timeout=300)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("order", ["newton_lab_first", "warp_first"])
def test_no_adjoint_kernels_by_default(order):
    assert _probe(order) == {"config": False, "newton": False, "project": False}


def test_backward_kept_on_request():
    assert _probe("newton_lab_first", NEWTON_LAB_WARP_BACKWARD="1") == {"config": True, "newton": True, "project": True}
