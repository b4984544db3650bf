#!/usr/bin/env bash
# Issue-31 runs on a GPU host, from the repository root, after the project's wheels are installed into
# $HOME/.cache/gpu_site (../shared/tools/gpu/fetch_wheels.sh parts p1-p3, then `install` here with the zarr wheels
# in .gpu_wheels/p4). Every policy sees the front head and the left wrist camera (96x72 RGB) and proprioception
# (--obs-mode sensors); evaluations are 100 held-out randomised episodes (--seed 50000; collection uses seed 7).
#
#   bash tools/gpu/long_horizon_run.sh install
#   bash tools/gpu/long_horizon_run.sh single GPU TASK [task flags...]    collect 800 -> train -> evaluate
#   bash tools/gpu/long_horizon_run.sh mimic GPU TASK [task flags...]     collect SRC (16) -> Mimic MIM (1024) -> train on
#                                                                         both -> evaluate (the PickCube recipe of
#                                                                         docs/learning.md; the task needs a Mimic variant)
#   bash tools/gpu/long_horizon_run.sh coherent GPU TASK [task flags...]  collect 600 -> split -> train one policy per
#                                                                         learned phase (PHASES, default pick,place)
#                                                                         -> evaluate composed (experts for the rest,
#                                                                         e.g. nav)
#   bash tools/gpu/long_horizon_run.sh ddp DATASET                       samples/s training on one GPU, then two
#   bash tools/gpu/long_horizon_run.sh bg NAME MODE ARGS...                the same, detached (setsid), log in
#                                                                         /tmp/w/NAME.log: calls stay short
#   knobs: EPS (demos), TB (training budget per policy [s], default 300; TB_<PHASE> per phase of a coherent
#          run), GPUS (train data-parallel over that many GPUs: torchrun + NCCL; pick them with CUDA_VISIBLE_DEVICES,
#          e.g. CUDA_VISIBLE_DEVICES=2,3 GPUS=2 ... coherent 0 TASK: GPU counts among the visible ones),
#          PHASES (a coherent run's learned phases, comma-separated: pick,place; StackCube-Phased: cube_2,cube_3),
#          PICK_GPU (a coherent run trains its first phase on that GPU while the others train on GPU),
#          EVAL_EPS (100), EVAL_SEEDS (evaluation seeds, default 50000; "50000 7" adds the collection's seed,
#          whose scenes recur where the row counts agree: a policy failing its own demos' scenes is not short of data),
#          REC (record that many evaluation worlds to $d/eval_<seed>.rrd; needs rerun-sdk staged by
#          tools/gpu/rerun_wheels.sh), W (work folder, /tmp/w),
#          OBS_KEYS (the policy's low-dim keys when the task names them otherwise than the vision preset, e.g.
#          StackCube: OBS_KEYS=joint_pos,gripper_pos ... single 0 GalbotG1-StackCube-v0 --head table),
#          CAMS (the policies' cameras, default front_head=96x72:rgb,left_wrist=96x72:rgb),
#          DEV=cpu (a tiny trial on the CPU: GPU is ignored), PY (python, default python3),
#          WAIT_FOR (a coherent run trains only once this file exists: a benchmark on those GPUs first)
# Each run ends with one JSON line: the evaluation's summary (success_rate, phases, termination_reasons).
set -uo pipefail
export PYTHONPATH=$HOME/.cache/gpu_site${REC:+:$HOME/.cache/rerun_site} PYTHONUNBUFFERED=1
W=${W:-/tmp/w}; mkdir -p "$W"
root=$PWD
N="${PY:-python3} -m newton_lab.cli"
CAM=(--cameras "${CAMS:-front_head=96x72:rgb,left_wrist=96x72:rgb}" --obs-mode sensors)
TRAIN=(--preset vision --image-keys front_head_rgb,left_wrist_rgb --bf16 --lr 3e-4
       ${OBS_KEYS:+--obs-keys "$OBS_KEYS"} ${GPUS:+--gpus "$GPUS"})
budget() { echo --time-budget-s "${1:-${TB:-300}}"; }
train_dev() { if [ -n "${GPUS:-}" ] && [ "${DEV:-cuda}" != cpu ]; then echo cuda; else dev "$1"; fi; }
dev() { if [ "${DEV:-cuda}" = cpu ]; then echo cpu; else echo "cuda:$1"; fi; }
EVAL=(--randomize --episodes "${EVAL_EPS:-100}" --num-envs "$(( ${EVAL_EPS:-100} < 100 ? ${EVAL_EPS:-100} : 100 ))"
      --max-steps 3000 --no-progress)
rec() { if [ -n "${REC:-}" ]; then echo --rerun-save "$1/eval_$2.rrd" --rerun-worlds "$REC" --rerun-image-every 5; fi; }
# collect EPISODES MAX_ENVS GPU TASK [task flags...]: expert demos from the policies' cameras into $d/demos.hdf5
collect() {
  local eps=$1 envs=$2 g=$3 task=$4; shift 4
  stamp "collect $eps of $task $* on $(dev "$g")"
  $N collect --task "$task" "$@" --episodes "$eps" --num-envs "$(( eps < envs ? eps : envs ))" --randomize --seed 7 \
    "${CAM[@]}" --dataset-path "$d/demos.hdf5" --device "$(dev "$g")" --no-progress --max-steps 3000 | tail -1 | cut -c1-300
}
stamp() { echo "== $(date -u +%T) $*"; }
# train_phase PHASE GPU: one policy on $d/split/PHASE.hdf5 (budget TB_PHASE or TB) into $d/PHASE_pol
train_phase() {
  local tb=TB_${1^^}
  while [ -n "${WAIT_FOR:-}" ] && [ ! -e "$WAIT_FOR" ]; do sleep 5; done  # e.g. a benchmark on these GPUs first
  stamp "train $1 on $(train_dev "$2")"
  $N train --dataset-path "$d/split/$1.hdf5" "${TRAIN[@]}" $(budget "${!tb:-}") --device "$(train_dev "$2")" \
    --output-dir "$d/${1}_pol" 2>&1 | tail -1
}
name_of() { echo "$1" | sed 's/GalbotG1-//; s/-v0//' | tr 'A-Z' 'a-z'; }

case "${1:-}" in
install)
  python3 -m pip install -q --no-index --no-deps --no-compile --upgrade --target "$HOME/.cache/gpu_site" .gpu_wheels/p4/*.whl
  bash tools/gpu/lay_out_package.sh "$HOME/.cache/gpu_site"
  nvidia-smi --query-gpu=name --format=csv,noheader
  python3 -c "import torch, warp, newton, zarr; print('ok torch', torch.__version__, 'warp', warp.__version__)" ;;
single)
  g=$2; task=$3; shift 3; d=$W/$(name_of "$task")$(echo "$@" | tr -d ' -'); mkdir -p "$d"; cd "$W"
  collect "${EPS:-800}" 200 "$g" "$task" "$@"
  stamp "train"
  $N train --dataset-path "$d/demos.hdf5" "${TRAIN[@]}" $(budget) --device "$(train_dev "$g")" --output-dir "$d/pol" \
    2>&1 | tail -1
  for seed in ${EVAL_SEEDS:-50000}; do
    stamp "evaluate, seed $seed"
    $N evaluate --task "$task" "$@" "${CAM[@]}" --checkpoint "$d/pol/checkpoint.pt" "${EVAL[@]}" --seed "$seed" \
      $(rec "$d" "$seed") --device "$(dev "$g")" | tail -1
  done ;;
mimic)
  g=$2; task=$3; shift 3; d=$W/$(name_of "$task")$(echo "$@" | tr -d ' -')_mimic; mkdir -p "$d"; cd "$W"
  collect "${SRC:-16}" 16 "$g" "$task" "$@"
  stamp "mimic ${MIM:-1024} from them"
  $N mimic --dataset-path "$d/demos.hdf5" --output-path "$d/mimic.hdf5" --episodes "${MIM:-1024}" \
    --num-envs "$(( ${MIM:-1024} < 512 ? ${MIM:-1024} : 512 ))" --cameras "${CAM[1]}" \
    --seed 8 --device "$(dev "$g")" --no-progress | tail -1 | cut -c1-300
  stamp "train on both"
  $N train --dataset-path "$d/demos.hdf5" "$d/mimic.hdf5" "${TRAIN[@]}" $(budget) --device "$(train_dev "$g")" \
    --output-dir "$d/pol" 2>&1 | tail -1
  for seed in ${EVAL_SEEDS:-50000}; do
    stamp "evaluate, seed $seed"
    $N evaluate --task "$task" "$@" "${CAM[@]}" --checkpoint "$d/pol/checkpoint.pt" "${EVAL[@]}" --seed "$seed" \
      $(rec "$d" "$seed") --device "$(dev "$g")" | tail -1
  done ;;
coherent)
  g=$2; task=$3; shift 3; d=$W/$(name_of "$task")$(echo "$@" | tr -d ' -'); mkdir -p "$d"; cd "$W"
  collect "${EPS:-600}" 300 "$g" "$task" "$@"
  stamp "split"
  IFS=, read -r -a phases <<< "${PHASES:-pick,place}"
  rm -rf "$d/split"; $N split --dataset-path "$d/demos.hdf5" --out "$d/split" --phases "${PHASES:-pick,place}" \
    | cut -c1-300
  if [ -n "${PICK_GPU:-}" ]; then  # the first phase on its own GPU while the others train on this one
    train_phase "${phases[0]}" "$PICK_GPU" > "$d/${phases[0]}_train.log" 2>&1 &
    for p in "${phases[@]:1}"; do train_phase "$p" "$g"; done; wait; cat "$d/${phases[0]}_train.log"
  else
    for p in "${phases[@]}"; do train_phase "$p" "$g"; done
  fi
  ckpts=(); for p in "${phases[@]}"; do ckpts+=("$p=$d/${p}_pol/checkpoint.pt"); done
  for seed in ${EVAL_SEEDS:-50000}; do
    stamp "evaluate composed, seed $seed"
    $N evaluate --task "$task" "$@" "${CAM[@]}" --phase-checkpoint "${ckpts[@]}" "${EVAL[@]}" --seed "$seed" \
      $(rec "$d" "$seed") --device "$(dev "$g")" | tail -1
  done ;;
ddp)  # ddp DATASET: samples/s of one GPU and of two (the first two visible), TB seconds each (default 60)
  cd "$W"
  for n in 1 2; do
    stamp "train on $n GPU(s)"
    $N train --dataset-path "$2" "${TRAIN[@]}" $(budget "${TB:-60}") --device cuda --gpus "$n" --output-dir "$W/ddp$n" \
      2>&1 | tail -3
  done ;;
bg)
  log=$W/$2.log; shift 2
  setsid nohup bash "$root/tools/gpu/long_horizon_run.sh" "$@" > "$log" 2>&1 < /dev/null &
  echo "started: $log" ;;
*)
  sed -n 2,33p "$0"; exit 2 ;;
esac
