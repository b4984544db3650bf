#!/usr/bin/env bash
# rerun-sdk for a GPU host without a package index, so that `newton-lab evaluate --rerun-save` can record what a
# learned policy does there (failed places, say) and the .rrd comes back to look at. rerun-sdk's wheel is 170 MB
# and pyarrow's 55 MB, over the 64 MiB one delivery carries: they are installed into one folder here, packed with
# xz and split into parts of 60 MB (.gpu_wheels/r1, r2, ...), each with this script as its stager.
#
#   here:      bash tools/gpu/rerun_wheels.sh                 (on a host with PyPI, from the project root)
#   GPU host:  one call per part, carrying .gpu_wheels/rN:    bash .gpu_wheels/rN/rerun_wheels.sh stage
#              then, in the last call:                        bash .gpu_wheels/rN/rerun_wheels.sh install
#              and put ~/.cache/rerun_site on PYTHONPATH after the project's site.
# numpy and pillow are left out (the GPU host has them).
set -euo pipefail
case "${1:-build}" in
stage)
  mkdir -p "$HOME/.cache/rerun_stage" && cp "$(dirname "$0")"/rerun_site.tar.xz.* "$HOME/.cache/rerun_stage/"
  ls "$HOME/.cache/rerun_stage" ;;
install)
  mkdir -p "$HOME/.cache/rerun_site"
  cat "$HOME"/.cache/rerun_stage/rerun_site.tar.xz.* | xz -d | tar -C "$HOME/.cache/rerun_site" -x
  PYTHONPATH="$HOME/.cache/rerun_site" python3 -c "import rerun; print('rerun', rerun.__version__)" ;;
build)
  work=$(mktemp -d)
  trap 'rm -rf "$work"' EXIT
  pip=${PIP:-.venv/bin/pip}
  version=$($pip show rerun-sdk | sed -n 's/^Version: //p')
  PLAT=(--only-binary=:all: --python-version 3.12 --implementation cp --platform manylinux_2_28_x86_64
        --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64)
  $pip download -q "${PLAT[@]}" -d "$work/wheels" "rerun-sdk==$version" 2>/dev/null
  rm -f "$work"/wheels/{numpy,pillow}-*.whl
  $pip install -q --no-deps --no-compile --ignore-requires-python "${PLAT[@]}" --target "$work/site" "$work"/wheels/*.whl
  tar -C "$work/site" -c . | xz -6 -T2 > "$work/rerun_site.tar.xz"
  rm -rf .gpu_wheels/r[0-9]*
  split -b 60m -d "$work/rerun_site.tar.xz" "$work/rerun_site.tar.xz."
  i=1
  for part in "$work"/rerun_site.tar.xz.[0-9]*; do
    mkdir -p ".gpu_wheels/r$i" && mv "$part" ".gpu_wheels/r$i/" && cp "$0" ".gpu_wheels/r$i/rerun_wheels.sh"
    i=$((i + 1))
  done
  du -sh .gpu_wheels/r[0-9]* ;;
*)
  sed -n 2,11p "$0"; exit 2 ;;
esac
