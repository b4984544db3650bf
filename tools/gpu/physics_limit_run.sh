#!/usr/bin/env bash
# Issue-33 measurements on one GPU of a GPU host, from the repository root, after the project's wheels are installed
# into $HOME/.cache/gpu_site (`bash tools/gpu/long_horizon_run.sh install`). Each command's output goes to
# $W/p33/<step>.log (W: /tmp/w); the steps run one after the other on the same GPU, so no two timings overlap.
#
#   bash tools/gpu/physics_limit_run.sh GPU            every step below
#   bash tools/gpu/physics_limit_run.sh GPU STEP...    only those steps: bench table profile collect tasks camera
#   setsid nohup bash tools/gpu/physics_limit_run.sh 0 > /tmp/w/p33.log 2>&1 &     detached, so calls stay short
#
#   bench    newton-lab bench, PickCube, 4096 and 16384 envs (the env step against the bare solver)
#   table    tools/physics_table.py, PickCube: the task's physics against Newton's state exchange around every
#            substep, against all joints simulated (with that exchange: the physics before welding), the pyramidal
#            cone, and contact capacities cut to 32 a world (expert peak: 14), with 100 randomised expert episodes each
#   collect  newton-lab bench-collect, PickCube, 4096 envs, 16,384 demos into zarr packs: the defaults, the
#            interpreter's thread switch interval at 0.5 ms instead of 5 ms (the loop and the writer thread share the
#            GIL), and the defaults under cProfile (collect_profile.txt: where the loop's thread spends its time)
#   profile  tools/profile_step.py --full at 4096 envs: the stages of the welded solver model and the full robot's
#   tasks    tools/physics_table.py for StackCube, PickToShelf and SortToShelf against all joints simulated
#   camera   newton-lab bench with the front head camera, RGB 128x128, at 4096 envs
#   collect_ab  bench-collect of this checkout against BASE_SITE's package (another commit laid out by
#            tools/gpu/lay_out_package.sh), this one again, then this one with --trace (collect_trace.json.gz)
#   writer_ab  bench-collect with the writer thread against the writer process, twice each, alternating; then the
#            process with the expert's re-plans in batches of 256 rows (--replan-batch 256 --replan-wait 12) and of 128
#            (8), then the process under cProfile (writer_profile.txt)
#   writer_threads  bench-collect with the writer process at 8 chunk threads (the default on a host of 8 cores or
#            more) and at 24 (NEWTON_LAB_ZARR_PACK_THREADS), alternating with the writer thread; then 24 threads
#            with re-plans in batches of 256, and the writer process's own profile (writer_process_profile.txt)
#   writer_column  bench-collect with the writer process (each burst split into its arrays on arrival) against the
#            writer thread, twice each, alternating; then the writer process's own profile (writer_column_profile.txt)
set -uo pipefail
export PYTHONPATH=$HOME/.cache/gpu_site PYTHONUNBUFFERED=1
W=${W:-/tmp/w}; out=$W/p33; mkdir -p "$out"
g=${1:?GPU index}; shift
steps=("$@"); [ ${#steps[@]} -eq 0 ] && steps=(bench table collect profile tasks camera)
dev=${DEV:-cuda:$g}
N="${PY:-python3} -m newton_lab.cli"
tools=$PWD/tools
run() {  # run STEP COMMAND...: the command's output into $out/STEP.log, a line with its time here
  local step=$1; shift
  local t0=$SECONDS
  echo "== $(date -u +%T) $step: $*"
  (cd "$W" && "$@") > "$out/$step.log" 2>&1
  echo "== $(date -u +%T) $step done, rc $?, $((SECONDS - t0)) s"
}
profile_text() {  # profile_text STATS TEXT: a cProfile file's 40 costliest calls, cumulative and own time
  ${PY:-python3} -c "import pstats, sys; s = pstats.Stats(sys.argv[1]); s.sort_stats('cumulative').print_stats(40); \
s.sort_stats('tottime').print_stats(40)" "$1" > "$2" 2>&1
}
BC="bench-collect --task GalbotG1-PickCube-v0 --num-envs 4096 --episodes 16384 --prefill 0 --device $dev"
twice_each() {  # twice_each TAG WRITER...: bench-collect with each --writer in turn, two rounds ($out/TAG_WRITER_K.log)
  local tag=$1 k w; shift
  for k in 1 2; do
    for w in "$@"; do run "${tag}_${w}_$k" $N $BC --writer "$w" --dataset-path "$W/${tag}_${w}_$k.zarr"; done
  done
}
nvidia-smi --query-gpu=index,name --format=csv,noheader | sed -n "$((g + 1))p"
for step in "${steps[@]}"; do
  case $step in
  bench)
    run bench bash -c "$N bench --task GalbotG1-PickCube-v0 --num-envs 4096 --device $dev \
      && $N bench --task GalbotG1-PickCube-v0 --num-envs 16384 --device $dev" ;;
  table)
    run table ${PY:-python3} "$tools/physics_table.py" --device "$dev" --num-envs 4096 --steps 200 --episodes 100 \
      --tasks GalbotG1-PickCube-v0 --variant sync_every_substep=True \
      --variant weld_idle_joints=False,sync_every_substep=True --variant cone=pyramidal --variant contacts_per_world=32 \
      --variant cone=pyramidal,contacts_per_world=32 ;;
  collect)
    rm -rf "$W"/bc33*.zarr*
    bc="$N $BC"
    run collect $bc --dataset-path "$W/bc33.zarr"
    run collect_switch ${PY:-python3} -c "import sys; sys.setswitchinterval(5e-4); from newton_lab.cli import main; \
sys.exit(main(sys.argv[1:]))" ${bc#*-m newton_lab.cli } --dataset-path "$W/bc33s.zarr"
    run collect_cprofile ${PY:-python3} -m cProfile -o "$out/collect.prof" -m newton_lab.cli ${bc#*-m newton_lab.cli } \
      --dataset-path "$W/bc33c.zarr"
    profile_text "$out/collect.prof" "$out/collect_profile.txt" ;;
  profile)
    run profile ${PY:-python3} "$tools/profile_step.py" --full --num-envs 4096 --device "$dev" ;;
  tasks)
    run tasks ${PY:-python3} "$tools/physics_table.py" --device "$dev" --num-envs 4096 --steps 200 --episodes 100 \
      --tasks GalbotG1-StackCube-v0 GalbotG1-PickToShelf-v0 GalbotG1-SortToShelf-v0 \
      --variant weld_idle_joints=False,sync_every_substep=True --variant cone=pyramidal ;;
  camera)
    run camera $N bench --task GalbotG1-PickCube-v0 --num-envs 4096 --device "$dev" --camera front_head \
      --resolution 128 128 ;;
  collect_ab)
    # this checkout's collection against the package laid out in $BASE_SITE (another commit's, by
    # lay_out_package.sh): new / base / new again, then a traced run of this one
    rm -rf "$W"/bco*.zarr*  # the four runs' datasets
    run ab_new $N $BC --dataset-path "$W/bco_new.zarr"
    run ab_base env PYTHONPATH="${BASE_SITE:?BASE_SITE: the other commit laid out}:$PYTHONPATH" $N $BC \
      --dataset-path "$W/bco_base.zarr"
    run ab_new2 $N $BC --dataset-path "$W/bco_new2.zarr"
    run ab_trace $N $BC --dataset-path "$W/bco_trace.zarr" --trace "$out/collect_trace.json.gz" ;;
  writer_ab)
    rm -rf "$W"/bcw*.zarr* "$W"/wr_*.zarr*
    twice_each wr thread process
    run wr_replan256 $N $BC --writer process --replan-batch 256 --replan-wait 12 --dataset-path "$W/bcw_r256.zarr"
    run wr_replan128 $N $BC --writer process --replan-batch 128 --replan-wait 8 --dataset-path "$W/bcw_r128.zarr"
    run wr_cprofile ${PY:-python3} -m cProfile -o "$out/writer.prof" -m newton_lab.cli $BC --writer process \
      --dataset-path "$W/bcw_c.zarr"
    profile_text "$out/writer.prof" "$out/writer_profile.txt"
    grep -h "demos/s\|stages\|hand-over\|physics-bound" "$out"/wr_*.log ;;
  writer_threads)
    rm -rf "$W"/bcx*.zarr*
    for k in 1 2; do
      run "wx_process8_$k" $N $BC --writer process --dataset-path "$W/bcx_p8_$k.zarr"
      run "wx_process24_$k" env NEWTON_LAB_ZARR_PACK_THREADS=24 $N $BC --writer process \
        --dataset-path "$W/bcx_p24_$k.zarr"
      run "wx_thread_$k" $N $BC --writer thread --dataset-path "$W/bcx_t_$k.zarr"
    done
    run wx_process24_r256 env NEWTON_LAB_ZARR_PACK_THREADS=24 $N $BC --writer process --replan-batch 256 \
      --replan-wait 12 --dataset-path "$W/bcx_p24r.zarr"
    run wx_profile env NEWTON_LAB_WRITER_PROFILE="$out/writer_process.prof" $N $BC --writer process \
      --dataset-path "$W/bcx_prof.zarr"
    profile_text "$out/writer_process.prof" "$out/writer_process_profile.txt"
    for f in "$out"/wx_*.log; do echo "## $(basename "$f")"; grep -h "demos/s\|stages\|hand-over" "$f"; done ;;
  writer_column)
    rm -rf "$W"/bcy*.zarr* "$W"/wy_*.zarr*
    twice_each wy process thread
    run wy_profile env NEWTON_LAB_WRITER_PROFILE="$out/writer_column.prof" $N $BC --writer process \
      --dataset-path "$W/bcy_prof.zarr"
    profile_text "$out/writer_column.prof" "$out/writer_column_profile.txt"
    for f in "$out"/wy_*.log; do
      echo "## $(basename "$f")"; grep -h "demos/s\|stages\|hand-over\|physics-bound" "$f"
    done ;;
  *) echo "unknown step $step (bench table collect profile tasks camera collect_ab writer_ab writer_threads" \
       "writer_column)"; exit 2 ;;
  esac
done
