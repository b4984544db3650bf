"""Maps the top-level folders kernels/, tasks/, flows/ and assets/ into the newton_lab namespace.

Every folder under them is a package (``find_namespace_packages``), data-only ones (assets/g1,
tasks/*/config/g1/scenarios) included, so setuptools ships their files without warnings.
"""

from setuptools import find_namespace_packages, setup

ROOTS = {
    "newton_lab": "newton_lab",
    "newton_lab.kernels": "kernels",
    "newton_lab.tasks": "tasks",
    "newton_lab.flows": "flows",
    "newton_lab.assets": "assets",
}


def _packages() -> dict[str, str]:
    """Package name -> folder, for every folder under ``ROOTS`` (caches excluded)."""
    found = {}
    for pkg, folder in ROOTS.items():
        found[pkg] = folder
        for sub in find_namespace_packages(where=folder, exclude=["__pycache__", "*.__pycache__"]):
            found[f"{pkg}.{sub}"] = f"{folder}/{sub.replace('.', '/')}"
    return found


PACKAGES = _packages()
setup(packages=sorted(PACKAGES), package_dir=PACKAGES)
