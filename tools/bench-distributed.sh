#!/usr/bin/env bash
# The cost of rendering in bands, side by side in rounds of A, B, B, A (so that drift of the machine's speed falls
# on both), reported as the median of the rounds' ratios B/A:
#   cpu: one process of 2 threads (A) against 2 MPI ranks of 1 thread (B) on the seed scene at its own settings;
#        the render passes' seconds ("wrote ...: N s", rank 0) and the whole command's wall time.
#   gpu: one GPU through the plain path (--device 0, A) against the several-device path with that one GPU
#        (--device all, B), `bench`'s wall-clock median of each; first, the images of --device 0, all and 0,0
#        (two workers on one GPU: the band copies) compared byte for byte.
# Usage: bash tools/bench-distributed.sh cpu|gpu [PATHTRACER] [ROUNDS]
set -euo pipefail
cd "$(dirname "$0")/.."
mode=$1 pt=${2:-build/release/pathtracer} rounds=${3:-5}
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_btl_vader_single_copy_mechanism=none
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT

# Prints "RENDER_SECONDS WALL_SECONDS" of one run.
cpu_run() {
  local start end
  start=$(date +%s.%N)
  if [ "$1" = A ]; then
    "$pt" render scenes/seed-default.json --threads 2 -o "$scratch/a.pfm" 2>"$scratch/log"
  else
    mpirun -np 2 --oversubscribe "$pt" render scenes/seed-default.json --threads 1 -o "$scratch/b.pfm" 2>"$scratch/log"
  fi
  end=$(date +%s.%N)
  echo "$(grep -oE '^wrote [^:]+: [0-9.]+ s' "$scratch/log" | awk '{print $3}') $(echo "$end - $start" | bc)"
}

gpu_run() {
  local device=0
  [ "$1" = B ] && device=all
  "$pt" bench scenes/seed-default.json --backend cuda --device $device --width 1920 --height 1080 --spp 1000 --runs 5 2>/dev/null |
    grep -oE 'wall-clock median [0-9.]+ s' | awk '{print $3, $3}'
}

if [ "$mode" = gpu ]; then  # first, the same image through each path (both integrators)
  for integrator in megakernel wavefront; do
    for device in 0 all 0,0; do
      "$pt" render scenes/seed-default.json --backend cuda --integrator $integrator --device $device --width 640 --height 360 --spp 64 -q \
        -o "$scratch/$integrator-${device/,/-}.pfm"
    done
    cmp "$scratch/$integrator-0.pfm" "$scratch/$integrator-all.pfm" && cmp "$scratch/$integrator-0.pfm" "$scratch/$integrator-0-0.pfm" &&
      echo "$integrator: --device 0, all and 0,0 bitwise equal"
  done
fi
for _ in $(seq "$rounds"); do
  a=$(${mode}_run A) b=$(${mode}_run B) b2=$(${mode}_run B) a2=$(${mode}_run A)
  echo "$a $b $b2 $a2" | awk '{ printf "A %s %s  B %s %s  B %s %s  A %s %s  ratio render %.4f wall %.4f\n",
    $1, $2, $3, $4, $5, $6, $7, $8, ($3 + $5) / ($1 + $7), ($4 + $6) / ($2 + $8) }'
done | tee "$scratch/rounds"
sort -k15 -n "$scratch/rounds" | awk '{ r[NR] = $15 } END { printf "B/A render passes: median %.3f over %d rounds\n", r[int((NR + 1) / 2)], NR }'
sort -k17 -n "$scratch/rounds" | awk '{ w[NR] = $17 } END { printf "B/A whole command: median %.3f\n", w[int((NR + 1) / 2)] }'
[ "$mode" = cpu ] && { cmp "$scratch/a.pfm" "$scratch/b.pfm" && echo "images bitwise equal"; }
true
