#!/usr/bin/env bash
# Runs on the GPU machine with out/device/ carried (tools/device/package.sh, built with -DPT_CUDA_FMAD=OFF, and the
# same build with contraction on copied to out/device/bin/pathtracer-fmad): the checks and figures behind two defaults.
#  1. nvcc's contraction of multiply-adds: the GPU's integrator and CUDA tests (held bit for bit in this build), and
#     the time of the build with contraction against the one without, side by side (tools/device/side-by-side.sh).
#  2. Light sampling: time to equal error of auto, nee and none on every shipped scene
#     (bench/light_sampling_efficiency.py), and compute-sanitizer's memcheck of auto renders.
# Usage: bash tools/device/defaults.sh [tests] [speed] [lights] [sanitize]   (all four where none is named)
set -uo pipefail
export LD_LIBRARY_PATH="$PWD/out/device/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export PT_PATHTRACER_BINARY="$PWD/out/device/bin/pathtracer"
BIN="$PWD/out/device/bin"
OUT="${OUT:-/tmp/pt-out}"
mkdir -p "$OUT"
parts="${*:-tests speed lights sanitize}"
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | tee "$OUT/gpu.txt"
if [[ " $parts " == *" tests "* ]]; then
  "$BIN/pt_tests" --gtest_filter='*WavefrontMatchesMegakernelOnGpu*:*Cuda*:*GpuImageMatchesCpu*:LightThreshold.*:LightTable.*' 2>&1 |
    tee "$OUT/tests.txt" | grep -E '^\[  (PASSED|FAILED) |FAILED|differing' | head -40
fi
if [[ " $parts " == *" speed "* ]]; then
  SCENES="book1-final --width 1200 --height 800 --spp 100|cornell-smoke --width 1024 --height 1024 --spp 1000|meshes --width 800 --height 450 --spp 256" \
    bash tools/device/side-by-side.sh "$BIN/pathtracer-fmad" "$BIN/pathtracer" 2 2>&1 | tee "$OUT/fmad-side-by-side.txt"
fi
if [[ " $parts " == *" lights "* ]]; then
  python3 bench/light_sampling_efficiency.py "$BIN/pathtracer" --size 400x240 --spp 256 --runs 3 --rounds 3 -- --backend cuda 2>&1 |
    tee "$OUT/light-sampling-gpu.txt"
fi
if [[ " $parts " == *" sanitize "* ]]; then
  for scene in tiny environment normal-maps; do
    compute-sanitizer --tool memcheck --error-exitcode 9 "$BIN/pathtracer" render "scenes/$scene.json" --backend cuda --width 96 --height 64 \
      --spp 8 -q -o "$OUT/$scene-sanitized.pfm" 2>&1 | tail -2 | tee -a "$OUT/sanitize.txt"
    echo "$scene: memcheck status ${PIPESTATUS[0]}" | tee -a "$OUT/sanitize.txt"
  done
fi
