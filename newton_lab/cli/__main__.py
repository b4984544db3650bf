"""``python -m newton_lab.cli``: the ``newton-lab`` console script."""

from . import main

if __name__ == "__main__":
    raise SystemExit(main())
