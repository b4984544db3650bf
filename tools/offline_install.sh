#!/usr/bin/env bash
# Install newton_lab on a host that has Python and torch but no package index (a lent GPU machine, an air-gapped
# cluster node), when what can travel to it is limited in size per transfer.
#
#   here (a host with PyPI, from the repository root):
#     bash tools/offline_install.sh pack [--python 3.12] [--part-mb 60] [--skip "torch numpy ..."]
#                                        [--exclude rerun_cli] [--with "ultralytics==8.3.0 ..."]
#         resolves the project's pinned dependencies (and --with's) for that Python on manylinux x86_64 (the
#         versions of this checkout's .venv, so both hosts run the same), leaves out what the target already has
#         (--skip: pip names) and folders it never uses (--exclude: top-level folder names, e.g. rerun_cli, the
#         rerun viewer binary, on a host without a screen: recordings are written without it), installs the rest
#         into one folder, packs it with xz and splits it into .offline/p1, p2, ... (each at most --part-mb
#         MiB, default 56: a 64 MiB transfer keeps room for the repository; this script beside each part).
#   there (from the repository root; one transfer per part, in order):
#     bash .offline/pN/offline_install.sh stage      copies part N to ~/.cache/newton_lab_stage
#     bash .offline/pN/offline_install.sh install    (after the last part) unpacks into ~/.cache/newton_lab_site
#                                                    and lays this checkout out there as the package newton_lab
#     export PYTHONPATH=$HOME/.cache/newton_lab_site
#   then run `python3 -m newton_lab.cli ...` from any folder but the repository root (from the root, Python would
#   import the unpackaged source tree, where kernels/ tasks/ flows/ assets/ are not yet inside newton_lab).
#
# Why a script and not pip alone: pip can download wheels for another platform, but the host cannot reach an
# index, and one wheel (warp-lang) is larger than a transfer; packing the installed tree and splitting it is the
# generic answer. Nothing here is specific to one experiment.
set -euo pipefail
site=${NEWTON_LAB_SITE:-$HOME/.cache/newton_lab_site}
stage=${NEWTON_LAB_STAGE:-$HOME/.cache/newton_lab_stage}
SKIP_DEFAULT="torch numpy pillow h5py scipy pyarrow triton setuptools pip wheel"

pack() {
  local py=3.12 part_mb=56 skip=$SKIP_DEFAULT exclude="" with=""
  while [ $# -gt 0 ]; do
    case $1 in
      --python) py=$2; shift 2 ;;
      --part-mb) part_mb=$2; shift 2 ;;
      --skip) skip=$2; shift 2 ;;
      --exclude) exclude="$exclude $2"; shift 2 ;;
      --with) with="$with $2"; shift 2 ;;
      *) echo "unknown option $1 (valid: --python, --part-mb, --skip, --exclude, --with)" >&2; exit 2 ;;
    esac
  done
  local pip=${PIP:-.venv/bin/pip} work out=.offline
  [ -x "$pip" ] || { echo "no $pip: run 'make .venv/.installed' first (the pack pins the venv's versions)" >&2; exit 2; }
  work=$(mktemp -d); trap "rm -rf '$work'" EXIT
  local skip_re; skip_re=$(echo "$skip" | tr ' ' '\n' | sed '/^$/d' | tr 'A-Z_' 'a-z-' | paste -sd'|')
  # the project's own requirements at the venv's versions, without what the target has
  $pip freeze 2>/dev/null | grep -v '^-e\|@ file\|^newton[-_]lab' > "$work/freeze.txt"
  python3 - "$work" "$skip_re" "$with" <<'PY'
import re, sys, tomllib
work, skip = sys.argv[1], re.compile(rf"^({sys.argv[2]})$")
deps = tomllib.load(open("pyproject.toml", "rb"))["project"]["dependencies"]
name = lambda r: re.split(r"[<>=!~ ;\[]", r, maxsplit=1)[0].strip().lower().replace("_", "-")
keep = [d.split("#")[0].strip() for d in deps if not skip.match(name(d))]
keep += sys.argv[3].split()
open(f"{work}/reqs.txt", "w").write("\n".join(keep) + "\n")
pins = [l for l in open(f"{work}/freeze.txt") if not skip.match(name(l))]
open(f"{work}/constraints.txt", "w").write("".join(pins))
PY
  # Every distribution the venv installed for those requirements (their closure through the installed metadata),
  # pinned to the venv's version and downloaded without a second resolution: pip's resolver would look for the
  # skipped packages (torch) on the index for the target platform, where this pin may not exist.
  "$(dirname "$pip")/python" - "$work" "$skip_re" <<'PY'
import re, sys
from importlib import metadata
from packaging.requirements import Requirement
work, skip = sys.argv[1], re.compile(rf"^({sys.argv[2]})$")
norm = lambda n: re.sub(r"[-_.]+", "-", n).lower()
todo = [Requirement(l) for l in open(f"{work}/reqs.txt").read().split("\n") if l.strip()]
seen, pins = set(), []
while todo:
    req = todo.pop()
    n = norm(req.name)
    if n in seen or skip.match(n):
        continue
    seen.add(n)
    try:
        dist = metadata.distribution(req.name)
    except metadata.PackageNotFoundError:  # a --with requirement: resolved by pip below
        continue
    pins.append(f"{req.name}=={dist.version}")
    for extra in req.extras or {""}:
        for r in map(Requirement, dist.requires or []):
            if r.marker is None or r.marker.evaluate({"extra": extra}):
                todo.append(r)
open(f"{work}/closure.txt", "w").write("\n".join(sorted(pins)) + "\n")
PY
  local plat=(--only-binary=:all: --python-version "$py" --implementation cp --platform manylinux_2_28_x86_64
              --platform manylinux_2_27_x86_64 --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64
              --platform manylinux1_x86_64)
  $pip download -q --no-deps "${plat[@]}" -r "$work/closure.txt" -d "$work/wheels"
  [ -z "$with" ] || $pip download -q "${plat[@]}" $with -c "$work/constraints.txt" -d "$work/wheels"
  for w in "$work"/wheels/*.whl; do  # what the target has (and its CUDA stack) stays there
    n=$(basename "$w" | cut -d- -f1 | tr 'A-Z_' 'a-z-')
    if [[ $n =~ ^($skip_re)$ || $n == nvidia-* ]]; then rm "$w"; fi
  done
  $pip install -q --no-deps --no-compile --ignore-requires-python "${plat[@]}" --target "$work/site" "$work"/wheels/*.whl
  rm -rf "$out"; mkdir -p "$out"
  for e in $exclude; do rm -rf "${work:?}/site/$e"; done
  tar -C "$work/site" -c . | xz -${XZ_LEVEL:-3} -T0 > "$work/site.tar.xz"
  split -b "${part_mb}m" -d -a 2 "$work/site.tar.xz" "$work/site.tar.xz."
  local i=1
  for part in "$work"/site.tar.xz.[0-9]*; do
    mkdir -p "$out/p$i" && mv "$part" "$out/p$i/" && cp "$0" "$out/p$i/offline_install.sh"; i=$((i + 1))
  done
  grep -qx '/.offline/' .git/info/exclude 2>/dev/null || echo '/.offline/' >> .git/info/exclude
  du -sh "$out"/p* | sed "s|^|part |"
  echo "deliver $out/p1 ... p$((i - 1)) in order; each: bash $out/pN/offline_install.sh stage; after the last: install"
}

case "${1:-}" in
pack) shift; pack "$@" ;;
stage)
  mkdir -p "$stage" && cp "$(dirname "$0")"/site.tar.xz.* "$stage/" && ls "$stage" ;;
install)
  [ -f pyproject.toml ] || { echo "run install from the repository root" >&2; exit 2; }
  rm -rf "$site" && mkdir -p "$site"
  cat "$stage"/site.tar.xz.* | xz -d | tar -C "$site" -x
  # the project as the package setup.py installs: kernels/ tasks/ flows/ assets/ mapped into newton_lab.*
  cp -r newton_lab "$site/newton_lab"
  for d in kernels tasks flows assets; do rm -rf "${site:?}/newton_lab/$d" && cp -r "$d" "$site/newton_lab/$d"; done
  PYTHONPATH=$site python3 -c "import warp, newton, torch; print('newton_lab installed in $site: warp', warp.__version__, 'newton', newton.__version__, 'torch', torch.__version__)" ;;
relayout)  # after editing the checkout: refresh only the project's package in the installed site
  [ -d "$site" ] || { echo "nothing installed in $site: run install first" >&2; exit 2; }
  rm -rf "$site/newton_lab" && cp -r newton_lab "$site/newton_lab"
  for d in kernels tasks flows assets; do rm -rf "${site:?}/newton_lab/$d" && cp -r "$d" "$site/newton_lab/$d"; done ;;
*)
  sed -n 2,22p "$0"; exit 2 ;;
esac
