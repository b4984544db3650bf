#!/usr/bin/env bash
# Builds .gpu_wheels/p5/yolo_site.tar.xz on a host with PyPI: Ultralytics and the needs the GPU host lacks
# (Python 3.12, manylinux x86_64), installed into one folder and packed with xz (the wheels alone are ~80 MB,
# over one delivery). Left out: torch, torchvision and numpy (the GPU host has them) and polars (54 MB; Ultralytics
# only reads results.csv with it when writing a checkpoint, and `newton-lab yolo-train` reads it with the csv module
# when polars is missing). tools/gpu/yolo_run.sh unpacks it on the GPU host.
set -euo pipefail
out=.gpu_wheels/p5
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
PIN=(ultralytics==8.4.190 ultralytics-thop==2.2.3 ultralytics-platform==0.1.99 opencv-python-headless==4.12.0.88
     matplotlib==3.11.2 contourpy==1.4.0 cycler==0.12.1 fonttools==4.68.0 kiwisolver==1.5.1 pyparsing==3.3.3
     python-dateutil==4.0.0 six==1.17.0 packaging==26.4 pillow==13.0.0 pyyaml==6.0.4 requests==2.34.2
     urllib3==2.8.0 idna==3.20 charset-normalizer==3.5.3 certifi==2026.10.19.post1 psutil==7.2.2
     nvidia-ml-py==13.615.71)
PLAT=(--only-binary=:all: --python-version 3.12 --implementation cp --platform manylinux_2_28_x86_64
      --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64)
pip=${PIP:-.venv/bin/pip}
$pip download -q --no-deps "${PLAT[@]}" -d "$work/wheels" "${PIN[@]}"
$pip install -q --no-deps --no-compile --ignore-requires-python "${PLAT[@]}" --target "$work/site" "$work"/wheels/*.whl
mkdir -p "$out"
tar -C "$work/site" -c . | xz -9 -T2 > "$out/yolo_site.tar.xz"
du -h "$out/yolo_site.tar.xz"
