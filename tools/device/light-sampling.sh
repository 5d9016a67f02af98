#!/usr/bin/env bash
# Runs on the GPU machine with out/device/ carried (tools/device/package.sh): the renders and timings of BENCHMARKS.md
# "Light sampling" (next-event estimation against none, stratified against independent samples) on the CUDA
# backend. The 256-spp images go to $OUT for their error against the references; a reference is rendered when asked.
# Usage: bash tools/device/light-sampling.sh [reference]
set -uo pipefail
export LD_LIBRARY_PATH="$PWD/out/device/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
PT="$PWD/out/device/bin/pathtracer"
OUT="${OUT:-/tmp/pt-out}"
mkdir -p "$OUT"
size="--width 256 --height 256"
for scene in cornell-box cornell-smoke book2-final; do
  for estimator in nee none; do
    for sampler in sobol independent; do
      "$PT" render "scenes/$scene.json" --backend cuda $size --spp 256 --seed 3 --light-sampling $estimator --sampler $sampler -q \
        -o "$OUT/$scene-$estimator-$sampler-256.pfm"
    done
    "$PT" bench "scenes/$scene.json" --backend cuda $size --spp 1024 --runs 3 --light-sampling $estimator 2>/dev/null | tee -a "$OUT/bench.txt"
  done
  if [[ "${1:-}" == reference ]]; then
    "$PT" render "scenes/$scene.json" --backend cuda $size --spp 32768 --seed 11 -q -o "$OUT/$scene-ref.pfm"
  fi
done
