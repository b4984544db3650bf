"""One torchrun rank of ``data_parallel.launch``: train, and rank 0 writes the checkpoint path where ``launch``
reads it. A module of its own: the package imports ``data_parallel``, and ``python -m`` of an imported module
runs a second copy of it."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

from ..datasets._common import die_with_parent
from .data_parallel import is_main, leave
from .train import train


def main(request_path: str) -> int:
    die_with_parent(os.getppid())  # torchrun started this rank: when it ends (even by SIGKILL), so does the rank
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
