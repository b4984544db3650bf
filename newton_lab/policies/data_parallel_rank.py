"""One torchrun rank of ``data_parallel.launch``: train, and rank 0 writes the checkpoint path where ``launch``
reads it. A module of its own: the package imports ``data_parallel``, and ``python -m`` of an imported module
runs a second copy of it."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

from ..datasets.writers.child_process import die_with_parent

# torchrun started this rank: when it ends (even by SIGKILL), so does the rank. Set before torch loads (seconds on a
# busy machine): a torchrun killed meanwhile would otherwise leave the rank running, reparented to init.
if os.getppid() == 1:  # torchrun ended before this rank got here
    sys.exit(1)
die_with_parent(os.getppid())

from .data_parallel import is_main, leave  # noqa: E402  deferred: after the parent-death signal (imports torch)
from .train import train  # noqa: E402  deferred: as above


def main(request_path: str) -> int:
    request = json.loads(Path(request_path).read_text())
    try:
        path = train(request["datasets"], request["cfg"], resume=request["resume"])
        if is_main():
            Path(request["answer"]).write_text(json.dumps({"checkpoint": str(path)}))
    finally:
        leave()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
