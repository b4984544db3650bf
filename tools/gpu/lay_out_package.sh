#!/usr/bin/env bash
# Lays this checkout out as the installed package newton_lab in the folder $1 (made or replaced): newton_lab/ with
# the top-level kernels/ tasks/ flows/ assets/ as its subpackages, as setup.py's package_dir maps them. For a GPU
# host without setuptools or a package index; run from the repository root. Put $1 on PYTHONPATH and run the
# CLI from another folder (from the root, `python -m` would import the unpackaged newton_lab/).
set -euo pipefail
dest=$1/newton_lab
rm -rf "$dest" && mkdir -p "$1" && cp -r newton_lab "$dest"
for d in kernels tasks flows assets; do rm -rf "${dest:?}/$d" && cp -r "$d" "$dest/$d"; done
