#!/usr/bin/env bash
# Runs on the GPU machine with out/device/ carried (tools/device/package.sh): the adaptive-sampling tests on the GPU,
# and BENCHMARKS.md "Adaptive sampling": uniform against adaptive sampling to equal error on the CUDA backend
# (bench/adaptive_equal_error.py), each scene's reference rendered there first. References are left in $OUT.
# Usage: bash tools/device/adaptive.sh [tests] [bench]   (both when no argument is given)
set -uo pipefail
export LD_LIBRARY_PATH="$PWD/out/device/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export PT_SOURCE_DIR="$PWD" PT_PATHTRACER_BINARY="$PWD/out/device/bin/pathtracer"
PT="$PWD/out/device/bin/pathtracer"
OUT="${OUT:-/tmp/pt-out}"
mkdir -p "$OUT/references"
steps="${*:-tests bench}"
if [[ $steps == *tests* ]]; then
  out/device/bin/pt_tests --gtest_filter='AdaptiveSampling.*:ShippedScenes/IntegratorEquivalence.*Gpu*' 2>&1 | grep -E "^cuda|OK|FAILED|PASSED|SKIPPED" | tail -20
fi
if [[ $steps == *bench* ]]; then
  for scene in cornell-box cornell-smoke meshes; do
    python3 bench/adaptive_equal_error.py "$PT" "scenes/$scene.json" --size 1024x1024 --reference-spp 4096 --uniform-spp 256 \
      --adaptive 0.006:4096 --adaptive 0.012:4096 --runs 3 --references "$OUT/references" -- --backend cuda |
      tee -a "$OUT/adaptive.txt"
  done
fi
