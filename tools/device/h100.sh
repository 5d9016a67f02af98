#!/usr/bin/env bash
# Runs on the GPU machine, from the repository root, with out/device/ carried there (tools/device/package.sh):
# checks the CUDA backend (parity with the CPU, compute-sanitizer) and benchmarks it. Writes logs under $OUT.
# Usage: bash tools/device/h100.sh [check] [bench] [profile]   (all three when no argument is given)
set -uo pipefail
export LD_LIBRARY_PATH="$PWD/out/device/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
PT="$PWD/out/device/bin/pathtracer"
OUT="${OUT:-/tmp/pt-out}"
mkdir -p "$OUT"
steps="${*:-check bench profile}"
nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.max.sm --format=csv,noheader
"$PT" devices

if [[ $steps == *check* ]]; then
  echo "== tests"
  if [ -x out/device/bin/pathtracer_tests ]; then
    (cd "$PWD" && PT_SOURCE_DIR="$PWD" out/device/bin/pathtracer_tests --gtest_brief=1 2>&1 | tail -15)
  fi
  echo "== parity: the same scene, seed and settings on CPU and GPU"
  for scene in tiny cornell-smoke seed-default; do
    "$PT" render scenes/$scene.json --backend cpu --width 160 --height 120 --spp 64 -q -o "$OUT/$scene-cpu.pfm"
    "$PT" render scenes/$scene.json --backend cuda --width 160 --height 120 --spp 64 -q -o "$OUT/$scene-cuda.pfm"
    python3 tools/compare_pfm.py "$OUT/$scene-cpu.pfm" "$OUT/$scene-cuda.pfm"
  done
  echo "== compute-sanitizer on every shipped scene (tiny sizes)"
  for scene in scenes/*.json; do
    for tool in memcheck racecheck initcheck; do
      compute-sanitizer --tool $tool --error-exitcode 9 "$PT" render "$scene" --backend cuda --width 32 --height 24 --spp 2 -q \
        -o "$OUT/sanitize.pfm" >"$OUT/sanitizer-$tool.log" 2>&1
      echo "$tool $(basename "$scene"): exit $? $(grep -E 'ERROR SUMMARY' "$OUT/sanitizer-$tool.log" | head -1)"
    done
  done
fi

if [[ $steps == *bench* ]]; then
  echo "== benchmarks (median of runs after a warm-up, CUDA-event timing)"
  "$PT" bench scenes/book1-final.json --backend cuda --width 1200 --height 800 --spp 100 --depth 50 --runs 5 | tee -a "$OUT/bench.txt"
  "$PT" bench scenes/seed-default.json --backend cuda --width 1920 --height 1080 --spp 1000 --depth 50 --runs 3 | tee -a "$OUT/bench.txt"
  "$PT" bench scenes/cornell-smoke.json --backend cuda --width 1024 --height 1024 --spp 1000 --runs 3 | tee -a "$OUT/bench.txt"
  "$PT" bench scenes/book2-final.json --backend cuda --spp 100 --runs 3 | tee -a "$OUT/bench.txt"
  "$PT" bench scenes/cornell-box.json --backend cuda --spp 1000 --runs 3 | tee -a "$OUT/bench.txt"
fi

if [[ $steps == *profile* ]]; then
  echo "== Nsight Compute: one launch of the render kernel, book-1 final scene"
  ncu --launch-skip 3 --launch-count 1 --section SpeedOfLight --section Occupancy --section LaunchStats --section WarpStateStats \
    "$PT" render scenes/book1-final.json --backend cuda --spp 8 -q -o "$OUT/ncu.pfm" >"$OUT/ncu.txt" 2>&1
  grep -E "Duration|Registers Per|Achieved Occupancy|Theoretical Occupancy|Compute \(SM\) Throughput|Memory Throughput|Block Limit|Local Memory|Stall|Warp Cycles Per Issued" "$OUT/ncu.txt" | head -30
fi
