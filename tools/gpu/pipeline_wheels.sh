#!/usr/bin/env bash
# Builds .gpu_wheels/p6/pipeline_site.tar.xz on a host with PyPI: Prefect, prefect-dask and Dask at this venv's
# versions (its `pip freeze` is the constraint), for Python 3.12 manylinux x86_64, installed into one folder and
# packed with xz, so that `newton-lab pipeline` runs on a GPU host without a package index. Left out: numpy and
# pillow (the GPU host has them), rerun-sdk and pyarrow (rerun-sdk's wheel alone is 170 MB, over what one delivery
# carries; `newton-lab pipeline --no-record` skips the evaluation recording, the one use of rerun there).
# On the GPU host: mkdir -p ~/.cache/pipeline_site && tar -C ~/.cache/pipeline_site -xJf .gpu_wheels/p6/pipeline_site.tar.xz
# and put ~/.cache/pipeline_site on PYTHONPATH after the project's site.
set -euo pipefail
out=.gpu_wheels/p6
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
pip=${PIP:-.venv/bin/pip}
$pip freeze 2>/dev/null | grep -v "^-e\|@ file\|^newton-lab\|^torch=" > "$work/constraints.txt"
PLAT=(--only-binary=:all: --python-version 3.12 --implementation cp --platform manylinux_2_28_x86_64
      --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 --platform manylinux1_x86_64)
$pip download -q "${PLAT[@]}" -c "$work/constraints.txt" -d "$work/wheels" prefect==3.8.8 prefect-dask==0.3.7 2>/dev/null
rm -f "$work"/wheels/{numpy,pillow,pyarrow,rerun_sdk}-*.whl
$pip install -q --no-deps --no-compile --ignore-requires-python "${PLAT[@]}" --target "$work/site" "$work"/wheels/*.whl
mkdir -p "$out"
tar -C "$work/site" -c . | xz -6 -T2 > "$out/pipeline_site.tar.xz"
du -h "$out/pipeline_site.tar.xz"
