#!/usr/bin/env bash
# Runs on the GPU machine, from the repository root, with out/device/ carried there (tools/device/package.sh):
# the test suite (backend-parity tests included), compute-sanitizer on every shipped scene, the benchmarks of
# BENCHMARKS.md (megakernel and wavefront), Nsight Compute reports, and the README's pictures. Logs go to $OUT.
# Usage: bash tools/device/h100.sh [check] [bench] [profile] [pictures]   (all when no argument is given)
set -uo pipefail
export LD_LIBRARY_PATH="$PWD/out/device/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export PT_SOURCE_DIR="$PWD" PT_PATHTRACER_BINARY="$PWD/out/device/bin/pathtracer"
PT="$PWD/out/device/bin/pathtracer"
OUT="${OUT:-/tmp/pt-out}"
SCRATCH=$(mktemp -d)
mkdir -p "$OUT"
steps="${*:-check bench profile pictures}"
nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.max.sm --format=csv,noheader
"$PT" devices

if [[ $steps == *check* ]]; then
  echo "== test suite on the GPU machine"
  out/device/bin/pt_tests --gtest_brief=1 >"$OUT/tests.log" 2>&1
  echo "pt_tests exit $?"; grep -E "PASSED|FAILED|SKIPPED|tests ran" "$OUT/tests.log" | tail -8
  grep -E "rmse cpu-gpu|wavefront-megakernel" "$OUT/tests.log" | head -20
  echo "== compute-sanitizer on every shipped scene (small sizes, both integrators, the render layers too)"
  for scene in scenes/*.json; do
    for integrator in megakernel wavefront; do
      for tool in memcheck racecheck initcheck; do
        compute-sanitizer --tool $tool --error-exitcode 9 "$PT" render "$scene" --backend cuda --integrator $integrator \
          --width 32 --height 24 --spp 2 --layers all -q -o "$SCRATCH/sanitize.exr" >"$SCRATCH/sanitizer.log" 2>&1
        status=$?
        [ $status -eq 0 ] || { echo "FAILED $tool $integrator $(basename "$scene"): exit $status"; tail -20 "$SCRATCH/sanitizer.log"; }
      done
    done
    echo "sanitized $(basename "$scene")"
  done
fi

bench() {  # scene, width, height, spp, runs
  for integrator in megakernel wavefront; do
    "$PT" bench "scenes/$1.json" --backend cuda --integrator $integrator --width "$2" --height "$3" --spp "$4" --runs "$5" 2>/dev/null |
      tee -a "$OUT/bench.txt"
  done
}
if [[ $steps == *bench* ]]; then
  echo "== benchmarks (median of runs after a warm-up, CUDA-event timing)"
  bench book1-final 1200 800 100 5
  bench seed-default 1920 1080 1000 3
  bench cornell-smoke 1024 1024 1000 3
  bench book2-final 800 800 1000 3
  bench cornell-box 600 600 1000 3
  bench seed-default 800 480 100 5
  bench tiny 640 480 256 5
fi

if [[ $steps == *profile* ]]; then
  echo "== Nsight Compute: the megakernel and the wavefront stages, book-1 final scene"
  ncu --launch-skip 3 --launch-count 1 --section SpeedOfLight --section Occupancy --section LaunchStats --section WarpStateStats \
    "$PT" render scenes/book1-final.json --backend cuda --spp 8 -q -o "$SCRATCH/ncu.pfm" >"$OUT/ncu-megakernel.txt" 2>&1
  grep -E "Duration|Registers Per|Achieved Occupancy|Theoretical Occupancy|Compute \(SM\) Throughput|Memory Throughput|Local Memory|Warp Cycles Per Issued" "$OUT/ncu-megakernel.txt" | head -12
  ncu --kernel-name regex:wavefront --launch-skip 10 --launch-count 6 --section SpeedOfLight --section Occupancy --section LaunchStats \
    "$PT" render scenes/book1-final.json --backend cuda --integrator wavefront --spp 8 -q -o "$SCRATCH/ncu.pfm" >"$OUT/ncu-wavefront.txt" 2>&1
  grep -E "wavefront_[a-z]+_kernel|Duration|Registers Per|Achieved Occupancy|Compute \(SM\) Throughput|Memory Throughput" "$OUT/ncu-wavefront.txt" | head -40
fi

if [[ $steps == *pictures* ]]; then
  echo "== pictures for the README"
  "$PT" render scenes/seed-default.json --backend cuda --spp 2000 -q -o "$SCRATCH/seed-default.png"
  "$PT" render scenes/book1-final.json --backend cuda --width 900 --height 600 --spp 1000 -q -o "$SCRATCH/book1-final.png"
  "$PT" render scenes/book2-final.json --backend cuda --width 600 --height 600 --spp 4000 -q -o "$SCRATCH/book2-final.png"
  "$PT" render scenes/cornell-box.json --backend cuda --spp 4000 -q -o "$SCRATCH/cornell-box.png"
  "$PT" render scenes/cornell-smoke.json --backend cuda --spp 4000 -q -o "$SCRATCH/cornell-smoke.png"
  "$PT" render scenes/tiny.json --backend cuda --width 320 --height 240 --spp 1024 -q -o "$SCRATCH/tiny.png"
  "$PT" render scenes/meshes.json --backend cuda --width 640 --height 360 --spp 1024 -q -o "$SCRATCH/meshes.png"
  tar -C "$SCRATCH" -cf "$OUT/pictures.tar" seed-default.png book1-final.png book2-final.png cornell-box.png cornell-smoke.png tiny.png meshes.png
  ls -la "$OUT"
fi
