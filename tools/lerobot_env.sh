#!/usr/bin/env bash
# An overlay environment in which LeRobot's own dataset loader (lerobot.datasets.lerobot_dataset.LeRobotDataset)
# reads `newton-lab export` folders: make test and tests/test_lerobot_loader.py build it (this script) and load every
# export kind through it on each test run, CI included. Prints the overlay's Python (bin/lerobot-python) on success.
#   usage: tools/lerobot_env.sh [PROJECT_PYTHON] [OVERLAY]      (defaults: .venv/bin/python .venv-lerobot)
#
# What it holds, and why:
# - A venv whose .pth file puts the project's site-packages after its own: torch 2.13.0+cpu, av (PyAV), pyarrow and
#   numpy come from the project, nothing of the project is changed. ~150 MB; 13-17 s to build on 2 cores (uv cache
#   warm or cold; most of it byte-compiling and the final import check), then reused until this script or the
#   project's Python, torch or av changes.
# - lerobot==0.4.4 (the newest release for Python 3.11) installed --no-deps: its torch<2.11 and rerun-sdk<0.27 pins
#   are packaging pins; the loader runs on torch 2.13 and never imports rerun. With it, --no-deps too, exactly what
#   the loader imports: datasets, huggingface-hub, hf-xet, fsspec, accelerate (lerobot.utils.utils imports it),
#   safetensors, pandas, dill, multiprocess, xxhash, aiohttp and its needs. Not needed: draccus, deepdiff, einops,
#   imageio, opencv, wandb, diffusers, rerun (`pip install lerobot==0.4.4` pulls 113 packages, a CUDA torch, 8 GB).
# - torchvision==0.28.0 (the release paired with torch 2.13), Python part only. lerobot imports it, and its loader
#   calls only transforms.ToTensor (pure Python). The one Linux x86_64 wheel on PyPI is a CUDA build whose C++
#   extensions (_C.so, image.so) link libtorch_cuda / libc10_cuda, which the CPU torch lacks; download.pytorch.org
#   (the CPU wheels) is not reachable from CI. torchvision loads those extensions optionally and guards every op
#   registration on them (extension._has_ops()) except two fake-tensor registrations (nms, qnms) in
#   _meta_registrations.py, which then raise "operator torchvision::nms does not exist" on import. The overlay drops
#   the CUDA-linked extensions and puts the same _has_ops() guard on those two registrations; torchvision's ops then
#   raise its own "Couldn't load custom C++ ops" if called (the loader calls none).
# - torchcodec==0.13.0, the video decoder of LeRobot 0.4.4 (torchvision 0.28 has no VideoReader, so LeRobot's
#   "pyav" backend fails): the last CPU-only release (0.14+ need CUDA's libnvrtc). It dlopens FFmpeg's shared
#   libraries by their standard names (4 to 8 supported; libavutil.so.60, libavcodec.so.62, ... for FFmpeg 8). The
#   machine has none; PyAV's wheel ships FFmpeg 8's under hashed names in site-packages/av.libs. ffmpeg/ links them
#   (and their own needs) under their standard names and bin/lerobot-python puts that folder on LD_LIBRARY_PATH:
#   torchcodec and PyAV then share one FFmpeg, the one that encoded the export.
# The build ends by importing LeRobotDataset, torchcodec's VideoDecoder and ToTensor; any failure exits non-zero
# with the reason, and the test fails with it (it is never skipped).
set -euo pipefail
PY=${1:-.venv/bin/python}
OVERLAY=${2:-.venv-lerobot}
PINS=(lerobot==0.4.4 datasets==4.8.5 huggingface-hub==0.35.3 hf-xet==1.8.0 fsspec==2026.2.0 accelerate==1.15.0
      safetensors==0.8.0 pandas==3.1.1 dill==0.4.1 multiprocess==0.70.19 xxhash==4.1.0 aiohttp==3.14.5
      aiohappyeyeballs==2.7.1 aiosignal==1.4.0 frozenlist==1.8.0 multidict==7.2.1 propcache==0.5.4 yarl==1.25.1
      torchcodec==0.13.0 torchvision==0.28.0)
FFMPEG_LIBS=(avutil avcodec avformat avdevice avfilter swscale swresample)

[ -x "$PY" ] || { echo "error: $PY is not a Python; run 'make test' (or tools/install_venv.sh) first" >&2; exit 2; }
PY=$(cd "$(dirname "$PY")" && pwd)/$(basename "$PY")  # absolute, not resolved: a venv's python is a symlink
mkdir -p "$(dirname "$OVERLAY")"
OVERLAY=$(cd "$(dirname "$OVERLAY")" && pwd)/$(basename "$OVERLAY")
PROJECT_SITE=$("$PY" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
AV_LIBS=$PROJECT_SITE/av.libs
VERSIONS=$("$PY" -c 'import sys; from importlib.metadata import version as v; print(sys.version.split()[0], v("torch"), v("av"))')
KEY="$(sha256sum "$0" | cut -c1-16) $VERSIONS $PROJECT_SITE"  # a change of any rebuilds the overlay

exec 9>"$OVERLAY.lock"
flock 9  # one build at a time (two pytest runs may ask together)
if [ "$(cat "$OVERLAY/.built" 2>/dev/null)" = "$KEY" ]; then
    echo "lerobot overlay: $OVERLAY is up to date" >&2
    echo "$OVERLAY/bin/lerobot-python"
    exit 0
fi

if [ -e "$OVERLAY" ] && [ ! -e "$OVERLAY/.lerobot-overlay" ]; then  # never delete a folder it did not build
    echo "error: $OVERLAY exists and is not an overlay this script built; move it away or pass another OVERLAY" >&2
    exit 2
fi
rm -rf "$OVERLAY"
trap 'rm -rf "$OVERLAY"; echo "error: the LeRobot overlay $OVERLAY could not be built (reason above);" \
    "fix that and run tools/lerobot_env.sh again" >&2' ERR
"$PY" -m venv --without-pip "$OVERLAY"
echo "built by tools/lerobot_env.sh; rebuilt (deleted first) when its key in .built changes" > "$OVERLAY/.lerobot-overlay"
SITE=$("$OVERLAY/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
echo "$PROJECT_SITE" > "$SITE/_newton_lab_project.pth"

UV=$(dirname "$PY")/uv
if [ -x "$UV" ] || UV=$(command -v uv); then  # with pip's configured sources, as tools/install_venv.sh does
    args=()
    while IFS='=' read -r key value; do
        value=${value#\'}; value=${value%\'}
        case "${key##*.}" in
            index-url|extra-index-url|find-links) for v in $value; do args+=("--${key##*.}" "$v"); done ;;
        esac
    done < <("$PY" -m pip config list 2>/dev/null || true)
    UV_LINK_MODE=copy "$UV" pip install -q -p "$OVERLAY/bin/python" --index-strategy unsafe-best-match \
        "${args[@]}" --no-deps --compile-bytecode "${PINS[@]}"
else
    "$PY" -m pip -qq --python "$OVERLAY/bin/python" install --no-deps --no-warn-conflicts "${PINS[@]}"
fi

# torchvision: its Python part only (see above)
rm -rf "$SITE/torchvision/_C.so" "$SITE/torchvision/image.so" "$SITE/torchvision.libs"
"$OVERLAY/bin/python" - "$SITE/torchvision/_meta_registrations.py" <<'EOF'
import sys
path = sys.argv[1]
text = open(path).read()
for op in ("nms", "qnms"):
    line = f'@torch.library.register_fake("torchvision::{op}")'
    if text.count(line) != 1:
        sys.exit(f"{path}: expected one '{line}' (torchvision 0.28.0); update tools/lerobot_env.sh")
    text = text.replace(line, f"@(torch.library.register_fake('torchvision::{op}') "
                              "if torchvision.extension._has_ops() else (lambda fn: fn))")
with open(path + ".new", "w") as f:  # a new file, never the installer cache's hard-linked one
    f.write(text)
__import__("os").replace(path + ".new", path)
EOF

# FFmpeg 8 under its standard names, from PyAV's wheel (see above)
mkdir "$OVERLAY/ffmpeg"
ln -s "$AV_LIBS"/* "$OVERLAY/ffmpeg/"  # their own needs too: the loader's $ORIGIN is the link's folder
for name in "${FFMPEG_LIBS[@]}"; do
    lib=$(compgen -G "$AV_LIBS/lib$name-*.so.*" | head -n 1 || true)
    [ -n "$lib" ] || { echo "error: $AV_LIBS has no lib$name; reinstall av (PyAV bundles FFmpeg)" >&2; false; }
    base=${lib##*/}; rest=${base#*.so.}  # lib<name>-<hash>.so.<major>.<minor>.<micro>
    ln -s "$lib" "$OVERLAY/ffmpeg/lib$name.so.${rest%%.*}"
done
cat > "$OVERLAY/bin/lerobot-python" <<EOF
#!/bin/sh
# The LeRobot overlay's Python (tools/lerobot_env.sh): FFmpeg's shared libraries, for torchcodec, on the loader path.
LD_LIBRARY_PATH="$OVERLAY/ffmpeg\${LD_LIBRARY_PATH:+:\$LD_LIBRARY_PATH}" exec "$OVERLAY/bin/python" "\$@"
EOF
chmod +x "$OVERLAY/bin/lerobot-python"

"$OVERLAY/bin/lerobot-python" -c '
import numpy as np, torchcodec, torchvision
from torchcodec.decoders import VideoDecoder  # loads torchcodec core against the FFmpeg libraries above
from torchvision.transforms import ToTensor
from lerobot.datasets.lerobot_dataset import LeRobotDataset
assert ToTensor()(np.zeros((2, 3, 3), np.uint8)).shape == (3, 2, 3)
print("lerobot overlay: built with lerobot 0.4.4, torchcodec", torchcodec.__version__, "on the FFmpeg of PyAV,",
      "torchvision", torchvision.__version__, "(Python part)", file=__import__("sys").stderr)
'
echo "$KEY" > "$OVERLAY/.built"
trap - ERR
echo "$OVERLAY/bin/lerobot-python"
