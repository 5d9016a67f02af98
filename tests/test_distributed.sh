#!/usr/bin/env bash
# Several devices and several MPI processes render one image, bitwise the same as one device; a process that fails
# stops the run with one error and no image, and one that stalls or dies has its rows rendered by the others. Usage: test_distributed.sh PATHTRACER SCENE CASE [MPIEXEC]
set -euo pipefail
pathtracer=$1 scene=$2 case=$3 mpiexec=${4:-mpirun}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
# CI runs as root, which mpirun refuses unless told; --oversubscribe lets 3 ranks share 2 cores. Single-copy
# transfers between processes (CMA) need ptrace rights that containers often withhold; copies through shared
# memory work everywhere.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_btl_vader_single_copy_mechanism=none
mpi() { local ranks=$1; shift; "$mpiexec" -np "$ranks" --oversubscribe "$@"; }
# 37 rows: bands of uneven height for any number of devices or ranks.
size=(--width 48 --height 37 --spp 6 -q)

# The processes of rank RANK of this case's MPI job: found by their rank and their working folder, so that the job
# of another case running at the same time (CTest runs tests side by side) is never taken for this one's.
rank_pids() {
  local pid
  for pid in $(pgrep -f "$pathtracer render"); do
    [ "$(readlink "/proc/$pid/cwd" 2>/dev/null)" = "$work" ] || continue
    if tr '\0' '\n' <"/proc/$pid/environ" 2>/dev/null | grep -qx "OMPI_COMM_WORLD_RANK=$1"; then echo "$pid"; fi
  done
}

same() {  # same IMAGE_A IMAGE_B WHAT
  if ! cmp -s "$1" "$2"; then echo "FAIL: $3: $2 differs from $1"; exit 1; fi
  echo "ok: $3"
}

case "$case" in
  cpu-devices)
    for integrator in megakernel wavefront; do
      "$pathtracer" render "$scene" "${size[@]}" --integrator $integrator --threads 2 -o one.pfm
      "$pathtracer" render "$scene" "${size[@]}" --integrator $integrator --threads 2 --device cpu,cpu -o two.pfm
      "$pathtracer" render "$scene" "${size[@]}" --integrator $integrator --threads 3 --device cpu,cpu,cpu -o three.pfm
      "$pathtracer" render "$scene" "${size[@]}" --integrator $integrator --threads 2 --device all -o all.pfm
      same one.pfm two.pfm "two CPU devices, $integrator"
      same one.pfm three.pfm "three CPU devices, $integrator"
      same one.pfm all.pfm "--device all, $integrator"
    done
    ;;
  mpi-ranks)  # the ranks of the fourth argument's list, e.g. "2 3"
    for ranks in ${5:-2 3}; do
      for integrator in megakernel wavefront; do
        "$pathtracer" render "$scene" "${size[@]}" --integrator $integrator --threads 1 -o one.pfm
        mpi "$ranks" "$pathtracer" render "$scene" "${size[@]}" --integrator $integrator --threads 1 -o ranks.pfm
        same one.pfm ranks.pfm "$ranks ranks, $integrator"
      done
    done
    # Two CPU devices in each of two ranks: bands of bands.
    mpi 2 "$pathtracer" render "$scene" "${size[@]}" --threads 2 --device cpu,cpu -o nested.pfm
    same one.pfm nested.pfm "2 ranks of 2 CPU devices each"
    # Adaptive sampling: the stops travel with the bands' films, and the image is the one process's.
    adaptive=(--width 48 --height 37 --spp 48 --noise-threshold 0.03 -q)
    "$pathtracer" render "$scene" "${adaptive[@]}" --threads 1 -o adaptive-one.pfm
    mpi 2 "$pathtracer" render "$scene" "${adaptive[@]}" --threads 1 -o adaptive-ranks.pfm
    same adaptive-one.pfm adaptive-ranks.pfm "2 ranks, adaptive sampling"
    ;;
  mpi-failed-rank)
    # Rank 1 cannot read its scene: one error naming it, a failing status, and no image.
    status=0
    mpi 1 "$pathtracer" render "$scene" "${size[@]}" -o out.pfm : -np 1 "$pathtracer" render "$work/missing.json" "${size[@]}" -o out.pfm \
      2>err.txt || status=$?
    cat err.txt
    [ "$status" -ne 0 ] || { echo "FAIL: the run succeeded"; exit 1; }
    [ ! -e out.pfm ] || { echo "FAIL: an image was written"; exit 1; }
    [ "$(grep -c '^pathtracer: error:' err.txt)" -eq 1 ] || { echo "FAIL: not exactly one error"; exit 1; }
    grep -q '^pathtracer: error: rank 1 (host .*missing.json' err.txt || { echo "FAIL: the error does not name rank 1 and its scene"; exit 1; }
    echo "ok: a rank that cannot read its scene stops the run"
    ;;
  mpi-checkpoint)
    # Stopped early (the time limit, as an interrupt stops), saved by rank 0, resumed by two ranks: the same image.
    spp=(--width 48 --height 37 --spp 40 --threads 1)
    "$pathtracer" render "$scene" "${spp[@]}" -q -o one.pfm
    mpi 2 "$pathtracer" render "$scene" "${spp[@]}" --time-limit 0.001 --checkpoint film.ckpt -o part.pfm 2>err.txt
    grep -q "stopped by the time limit after .* of 40 samples per pixel; film saved to film.ckpt" err.txt ||
      { cat err.txt; echo "FAIL: not stopped early, or no checkpoint"; exit 1; }
    mpi 2 "$pathtracer" render "$scene" "${spp[@]}" -q --resume film.ckpt -o resumed.pfm
    same one.pfm resumed.pfm "stopped, saved and resumed across 2 ranks"
    ;;
  mpi-interrupt)
    # mpirun stopped (Ctrl-C or SIGTERM: it sends SIGTERM to every rank): rank 0 gives up the pass under way, saves the
    # checkpoint and writes the image of the passes before; two ranks resume it to the image of one uninterrupted process.
    # (Small and long: the interrupt comes at the first checkpoint, a pass in; each render of it costs 2-3 s.)
    spp=(--width 48 --height 37 --spp 3000 --threads 1)
    "$pathtracer" render "$scene" "${spp[@]}" -q -o one.pfm
    "$mpiexec" -np 2 --oversubscribe "$pathtracer" render "$scene" "${spp[@]}" --checkpoint film.ckpt --checkpoint-interval 0.1 \
      -o part.pfm 2>err.txt &
    launcher=$!
    for _ in $(seq 600); do [ -e film.ckpt ] && break; sleep 0.1; done
    # SIGTERM, which mpirun takes as it takes Ctrl-C: a background job of a script ignores SIGINT.
    kill -TERM $launcher
    wait $launcher || true
    grep -q "stopped by .* after .* of 3000 samples per pixel; film saved to film.ckpt" err.txt ||
      { cat err.txt; echo "FAIL: the interrupted run did not stop early and save"; exit 1; }
    [ -e part.pfm ] || { echo "FAIL: no image of the samples done"; exit 1; }
    mpi 2 "$pathtracer" render "$scene" "${spp[@]}" -q --resume film.ckpt -o resumed.pfm
    same one.pfm resumed.pfm "interrupted under mpirun, saved by rank 0, resumed across 2 ranks"
    ;;
  mpi-lost-rank)
    # A rank that stalls (SIGSTOP) or dies (SIGKILL, under mpirun --enable-recovery, which lets the job go on) once
    # the render is under way: rank 0 names it when its band is overdue, the others render its rows, and the image
    # is the one of an uninterrupted process; the run ends (the lost rank too) with status 0. It once hung forever.
    spp=(--width 96 --height 74 --spp 300 --threads 1)
    "$pathtracer" render "$scene" "${spp[@]}" -q -o one.pfm
    for fault in STOP KILL; do
      rm -f film.ckpt lost.pfm
      recovery=()
      [ $fault = KILL ] && recovery=(--enable-recovery)
      timeout 120 "$mpiexec" -np 2 --oversubscribe "${recovery[@]}" "$pathtracer" render "$scene" "${spp[@]}" --checkpoint film.ckpt \
        --checkpoint-interval 0.1 -o lost.pfm 2>err.txt &
      launcher=$!
      # After the first pass (the checkpoint is saved after each), so that the bands' costs are known.
      for _ in $(seq 600); do [ -e film.ckpt ] && break; sleep 0.1; done
      mapfile -t ranks < <(rank_pids 1)
      [ ${#ranks[@]} -eq 1 ] || { echo "FAIL: rank 1 not found"; kill -KILL $launcher; exit 1; }
      kill -$fault "${ranks[0]}"
      status=0
      wait $launcher || status=$?
      kill -KILL "${ranks[0]}" 2>/dev/null || true
      cat err.txt
      [ "$status" -eq 0 ] || { echo "FAIL: SIG$fault of rank 1: status $status"; exit 1; }
      grep -q '^pathtracer: warning: rank 1 (host .*) has not answered for .* s.*; the other ranks render its rows' err.txt ||
        { echo "FAIL: SIG$fault of rank 1 is not named"; exit 1; }
      same one.pfm lost.pfm "rank 1 lost to SIG$fault: its rows rendered by rank 0"
    done
    # Killed under plain mpirun, which then ends the job (SIGTERM to rank 0): rank 0 writes the image of the passes
    # done and the checkpoint, which one process resumes to the uninterrupted image.
    rm -f film.ckpt lost.pfm
    timeout 120 "$mpiexec" -np 2 --oversubscribe "$pathtracer" render "$scene" "${spp[@]}" --checkpoint film.ckpt --checkpoint-interval 0.1 \
      -o lost.pfm 2>err.txt &
    launcher=$!
    for _ in $(seq 600); do [ -e film.ckpt ] && break; sleep 0.1; done
    for pid in $(rank_pids 1); do kill -KILL "$pid"; done
    wait $launcher || true
    grep -q "stopped by SIGTERM after .* of 300 samples per pixel; film saved to film.ckpt" err.txt ||
      { cat err.txt; echo "FAIL: rank 0 did not save what it had when mpirun ended the job"; exit 1; }
    [ -e lost.pfm ] || { echo "FAIL: no image of the samples done"; exit 1; }
    "$pathtracer" render "$scene" "${spp[@]}" -q --resume film.ckpt -o resumed.pfm
    same one.pfm resumed.pfm "rank 1 killed under plain mpirun: rank 0's checkpoint resumed by one process"
    ;;
  *) echo "unknown case $case"; exit 2 ;;
esac
