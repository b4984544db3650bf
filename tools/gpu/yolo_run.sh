#!/usr/bin/env bash
# YOLO-seg on one GPU, from the repository root of the GPU host (after the project's own wheels are installed into
# $HOME/.cache/gpu_site): unpack Ultralytics (.gpu_wheels/p5/yolo_site.tar.xz, built by tools/gpu/yolo_wheels.sh),
# export a training set and a held-out set (other seed, randomised colours), train YOLO11n-seg from its config,
# score mask mAP50 / mAP50-95 on the held-out set, predict on fresh renders and copy the results into $OUT.
#
#   usage: bash tools/gpu/yolo_run.sh [all|data|fit]     (data: the two exports; fit: train, score, predict)
#   knobs: TRAIN_N (2000 images), HELD_N (400), TRAIN_ENVS (64), HELD_ENVS (25), DEVICE (cuda:0), TRAIN_S
#          (training budget [s]; default: what is left of TOTAL_S = 460 s after the exports, less 90 s, >= 120 s)
set -euo pipefail
root=$PWD
what=${1:-all}
case "$what" in all|data|fit) ;; *) echo "usage: bash tools/gpu/yolo_run.sh [all|data|fit]" >&2; exit 2 ;; esac
T0=$(date +%s)
stage() { echo "== $(date -u +%T) +$(( $(date +%s) - T0 ))s $*"; }
OUT=${OUT:-$root/yolo_out}
W=$HOME/.cache/yolo_work
DEVICE=${DEVICE:-cuda:0}
mkdir -p "$OUT" "$W"

stage "python path: this tree's newton_lab, the project's wheels, Ultralytics"
src=$HOME/.cache/yolo_src
bash "$root/tools/gpu/lay_out_package.sh" "$src"
yl=$HOME/.cache/yolo_site
if [ ! -f "$yl/.unpacked" ]; then
  rm -rf "$yl" && mkdir -p "$yl" && tar -C "$yl" -xJf .gpu_wheels/p5/yolo_site.tar.xz && touch "$yl/.unpacked"
fi
export PYTHONPATH=$src:$HOME/.cache/gpu_site:$yl
export YOLO_OFFLINE=1 YOLO_CONFIG_DIR=$HOME/.cache/yolo_config MPLBACKEND=Agg
mkdir -p "$YOLO_CONFIG_DIR"
cd "$W"  # python -m from the repository root would import its unpackaged newton_lab/ (no kernels/, tasks/)
N="python3 -m newton_lab.cli"
nvidia-smi --query-gpu=name,memory.total --format=csv,noheader
python3 -c "import torch, torchvision, cv2, ultralytics, numpy as np
print('torch', torch.__version__, 'torchvision', torchvision.__version__, 'cv2', cv2.__version__,
      'ultralytics', ultralytics.__version__, 'numpy', np.__version__)"

if [ "$what" = all ] || [ "$what" = data ]; then
  rm -rf "$W/train" "$W/heldout"
  stage "export: ${TRAIN_N:-2000} training images (seed 0, --randomize; includes Warp's first compile)"
  $N yolo-export --num-images "${TRAIN_N:-2000}" --num-envs "${TRAIN_ENVS:-64}" --randomize --seed 0 \
    --split 0.85 0.15 0 \
    --preview 3 --device "$DEVICE" --output-dir "$W/train" 2>&1 | tail -1 | cut -c1-400
  stage "export: ${HELD_N:-400} held-out images (seed 1000, --randomize)"
  $N yolo-export --num-images "${HELD_N:-400}" --num-envs "${HELD_ENVS:-25}" --randomize --seed 1000 \
    --split 0 1 0 \
    --preview 2 --device "$DEVICE" --output-dir "$W/heldout" 2>&1 | tail -1 | cut -c1-400
fi

if [ "$what" = all ] || [ "$what" = fit ]; then
  rm -rf "$W/run" "$W/pred"
  # unset TRAIN_S: what is left of TOTAL_S (460 s) after the exports, less 90 s for start-up, scoring and predicting
  left=$(( ${TOTAL_S:-460} - ($(date +%s) - T0) - 90 ))
  TRAIN_S=${TRAIN_S:-$(( left > 120 ? left : 120 ))}
  stage "train: yolo11n-seg.yaml from scratch, ${TRAIN_S} s budget"
  $N yolo-train --dataset "$W/train" --heldout "$W/heldout" --device "$DEVICE" --time-budget-s "$TRAIN_S" \
    --epochs 200 --batch-size 64 --workers 12 --output-dir "$W/run" > "$W/train.log" 2>&1 \
    || { tail -30 "$W/train.log"; exit 1; }
  grep -E "^\s+(all|Class)\s" "$W/train.log" | tail -2 || true
  tail -1 "$W/train.log"
  stage "predict: 8 fresh renders, 2 rows at steps 0 50 100 150 (seed 5000, --randomize)"
  $N yolo-predict --weights "$W/run/weights/best.pt" --num-images 8 --num-envs 2 --capture-every 50 --seed 5000 \
    --randomize --device "$DEVICE" --output-dir "$W/pred" 2>&1 | tail -1
  cp "$W/run/metrics.json" "$OUT/metrics.json"
  cp "$W/run/run/results.csv" "$OUT/results.csv" 2>/dev/null || true
  cp "$W/pred/predictions.json" "$OUT/predictions.json"
  cp "$W/pred/overlays.png" "$OUT/overlays.png"
fi
for k in 0 1 2; do cp "$W/train/preview/00000$k.png" "$OUT/labels_train_$k.png" 2>/dev/null || true; done
cp "$W/heldout/preview/000000.png" "$OUT/labels_heldout_0.png" 2>/dev/null || true
ls -la "$OUT"
stage "done"
