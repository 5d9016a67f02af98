#!/usr/bin/env bash
# Runs on the GPU machine with out/device/ carried (tools/device/package.sh): the renders and timings of BENCHMARKS.md
# "Light sampling" (next-event estimation against none, stratified against independent samples) on the CUDA
# backend, with the error of each 256-spp image against the reference in REFS (tools/rmse.py), when there is one.
# Usage: bash tools/device/light-sampling.sh [REFS]   (REFS: a folder of SCENE-ref.pfm, 256x256)
set -uo pipefail
export LD_LIBRARY_PATH="$PWD/out/device/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
PT="$PWD/out/device/bin/pathtracer"
OUT="${OUT:-/tmp/pt-out}"
REFS="${1:-}"
IMAGES=$(mktemp -d)
mkdir -p "$OUT"
size="--width 256 --height 256"
for scene in cornell-box cornell-smoke book2-final; do
  for estimator in nee none; do
    for sampler in sobol independent; do
      "$PT" render "scenes/$scene.json" --backend cuda $size --spp 256 --seed 3 --light-sampling $estimator --sampler $sampler -q \
        -o "$IMAGES/$scene-$estimator-$sampler-256.pfm"
    done
    "$PT" bench "scenes/$scene.json" --backend cuda $size --spp 1024 --runs 3 --light-sampling $estimator 2>/dev/null | tee -a "$OUT/bench.txt"
  done
  if [[ -n "$REFS" && -f "$REFS/$scene-ref.pfm" ]]; then
    python3 tools/rmse.py "$REFS/$scene-ref.pfm" "$IMAGES/$scene"-*.pfm | tee -a "$OUT/rmse.txt"
  fi
done
