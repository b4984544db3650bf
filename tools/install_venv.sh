#!/usr/bin/env bash
# Create the venv and install newton_lab with its pinned packages (`make` calls this once per change of
# pyproject.toml / setup.py). uv installs them (parallel downloads and unpacking: about 15 s on a 2-core
# machine where pip takes about 5 min) with pip's own configuration (index URLs, find-links, constraints),
# so both resolve the same versions; pip installs them when uv cannot be installed or fails.
#   usage: tools/install_venv.sh PYTHON VENV
set -euo pipefail
PY=${1:-python3}
VENV=${2:-.venv}
UV_VERSION=0.9.5
PACKAGES=(torch==2.13.0 -e '.[test]')
# robomimic's data loader only (its training extras pin packages that don't install here): the layout test
NO_DEPS=(robomimic==0.3.0 termcolor==3.3.0)

"$PY" -m venv "$VENV"
PIP=("$VENV/bin/pip" -qq)

uv_args() {  # pip's configured sources and constraints as uv options
    "$VENV/bin/pip" config list 2>/dev/null | while IFS='=' read -r key value; do
        value=${value#\'}; value=${value%\'}
        case "${key##*.}" in
            index-url|extra-index-url|find-links|constraint)
                for v in $value; do printf -- '--%s\n%s\n' "${key##*.}" "$v"; done ;;
        esac
    done
}

with_uv() {
    "${PIP[@]}" install "uv==$UV_VERSION" || return 1
    local uv="$VENV/bin/uv" args
    mapfile -t args < <(uv_args)
    export UV_LINK_MODE=copy  # no hard-link fallback notice across file systems
    "$uv" pip install -q -p "$VENV/bin/python" --index-strategy unsafe-best-match "${args[@]}" "${PACKAGES[@]}" &&
        "$uv" pip install -q -p "$VENV/bin/python" --index-strategy unsafe-best-match "${args[@]}" --no-deps \
            "${NO_DEPS[@]}"
}

with_pip() {
    "${PIP[@]}" install --upgrade pip
    "${PIP[@]}" install "${PACKAGES[@]}"
    "${PIP[@]}" install --no-deps "${NO_DEPS[@]}"
}

if [ "${NEWTON_LAB_INSTALLER:-uv}" = pip ] || ! with_uv; then
    [ "${NEWTON_LAB_INSTALLER:-uv}" = pip ] || echo "uv install failed; installing with pip (a few minutes)" >&2
    with_pip
fi

# Byte-compile the installed packages once. Where PYTHONDONTWRITEBYTECODE is set (as on the project's CI and dev
# machines) Python never writes .pyc files itself, so every process compiled torch, Newton, Warp and Prefect from
# source on import: 15.8 s for `import newton_lab.envs` on 2 cores, 10.2 s with the .pyc files in place. The test
# suite starts ~50 such processes. A few vendored files of other Python versions do not compile; that is harmless.
"$VENV/bin/python" -m compileall -q -j 0 "$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')" \
    > /dev/null 2>&1 || true
