"""Maps the top-level folders kernels/, tasks/, flows/ and assets/ into the newton_lab namespace."""

from pathlib import Path

from setuptools import setup

ROOTS = {"newton_lab": "newton_lab", "newton_lab.kernels": "kernels", "newton_lab.tasks": "tasks",
         "newton_lab.flows": "flows", "newton_lab.assets": "assets"}


def _packages():
    found = []
    for pkg, folder in ROOTS.items():
        for init in sorted(Path(folder).rglob("__init__.py")):
            rel = init.parent.relative_to(folder).parts
            found.append(".".join((pkg, *rel)))
    return found


def _package_dir():
    dirs = dict(ROOTS)
    for pkg in _packages():
        root = max((r for r in ROOTS if pkg.startswith(r + ".")), key=len, default=None)
        if root is not None and pkg not in ROOTS:
            dirs[pkg] = str(Path(ROOTS[root], *pkg[len(root) + 1:].split(".")))
    return dirs


setup(packages=_packages(), package_dir=_package_dir())
