#!/usr/bin/env bash
# Runs on the GPU machine, from the repository root, with out/sycl-device.tar.xz carried there (made here by
# tools/device/package-sycl.sh from a -DPT_SYCL=ON -DACPP_TARGETS=generic build): the SYCL test suite on the GPU,
# compute-sanitizer on SYCL renders, the SYCL backend against the CUDA backend side by side, and the time from
# command to image. The JIT cache is kept in $PT_SYCL_CACHE_DIR (default /tmp/pt-sycl-cache) and warmed before any
# timing. CUDA_BINARY (default out/cuda-bin/pathtracer) is a CUDA build for the comparison; it loads its libraries
# from the SYCL package. `bdpt`: bidirectional path tracing through SYCL (compute-sanitizer, time to equal error;
# its tests are among `check`'s). Logs go to $OUT.
# Usage: bash tools/device/sycl.sh [check] [sanitize] [bench] [time] [hang] [probe] [profile] [bdpt]   (check sanitize bench time when no argument is given)
set -uo pipefail
OUT="${OUT:-/tmp/pt-out}"
mkdir -p "$OUT"
root=/tmp/pt-sycl
if [ ! -d "$root/sycl-device" ]; then
  mkdir -p "$root" && tar -xJf out/sycl-device.tar.xz -C "$root" || exit 1
fi
export PT_SYCL_CACHE_DIR="${PT_SYCL_CACHE_DIR:-/tmp/pt-sycl-cache}"
# shellcheck source=/dev/null
source "$root/sycl-device/sycl-env.sh" || exit 1
export PT_SOURCE_DIR="$PWD" PT_PATHTRACER_BINARY="$root/sycl-device/bin/pathtracer" ACPP_DEBUG_LEVEL=0
PT="$root/sycl-device/bin/pathtracer"
CUDA_PT="${CUDA_BINARY:-$PWD/out/cuda-bin/pathtracer}"
SCRATCH=$(mktemp -d)
cd "$SCRATCH" || exit 1  # the JIT writes its temporary files into the current directory
repo="$OLDPWD"
steps="${*:-check sanitize bench time}"
limit() {  # seconds, command...: runs the command with a time limit, printing its exit status and wall time
  local seconds=$1 start
  shift
  start=$(date +%s%N)
  timeout "$seconds" "$@" >"$SCRATCH/limited.log" 2>&1
  echo "exit $?, $(( ($(date +%s%N) - start) / 1000000 )) ms"
}
"$PT" devices
gpu=$("$PT" devices | awk -F'[ :]' '/^sycl [0-9]+: .*gpu/ {print $2; exit}')
echo "SYCL GPU device: ${gpu:-none}"
[ -n "$gpu" ] || exit 1

if [[ $steps == *check* ]]; then
  echo "== test suite (SYCL cases on the GPU: PT_TEST_SYCL_DEVICE=$gpu)"
  PT_TEST_SYCL_DEVICE=$gpu timeout 540 "$root/sycl-device/bin/pt_tests" --gtest_brief=1 --gtest_filter='*Sycl*:*sycl*' >"$OUT/sycl-tests.log" 2>&1
  echo "pt_tests exit $?"; grep -E "PASSED|FAILED|tests ran" "$OUT/sycl-tests.log" | tail -8
  grep -E "rmse|RMSE" "$OUT/sycl-tests.log" | head -20
fi

if [[ $steps == *sanitize* ]]; then
  echo "== compute-sanitizer memcheck on SYCL renders (small sizes, both integrators)"
  for scene in "$repo"/scenes/*.json; do
    for integrator in megakernel wavefront; do
      compute-sanitizer --tool memcheck --error-exitcode 9 "$PT" render "$scene" --backend sycl --sycl-device "$gpu" \
        --integrator $integrator --width 32 --height 24 --spp 2 -q -o "$SCRATCH/sanitize.pfm" >"$SCRATCH/sanitizer.log" 2>&1
      status=$?
      [ $status -eq 0 ] || { echo "FAILED memcheck $integrator $(basename "$scene"): exit $status"; tail -5 "$SCRATCH/sanitizer.log"; }
    done
    echo "sanitized $(basename "$scene")"
  done
fi

median() {  # binary, backend arguments..., scene arguments...: the median seconds of bench (none past 120 s)
  timeout 120 "$@" --runs 3 2>/dev/null | grep -oE 'median of [0-9]+: [0-9.]+ s' | awk '{print $4}'
}
if [[ $steps == *bench* ]]; then
  echo "== SYCL against CUDA, side by side (CUDA, SYCL, SYCL, CUDA per line; bench medians, device-event timing)"
  printf '%-14s %-10s %-10s %-10s %s\n' scene integrator cuda_s sycl_s sycl/cuda
  for line in "book1-final --width 1200 --height 800 --spp 100" "seed-default --width 1920 --height 1080 --spp 1000" \
              "cornell-smoke --width 1024 --height 1024 --spp 1000"; do
    set -- $line
    scene=$1
    shift
    for integrator in megakernel wavefront; do
      args=("$repo/scenes/$scene.json" "$@" --integrator $integrator)
      a=$(median "$CUDA_PT" bench "${args[@]}" --backend cuda)
      b=$(median "$PT" bench "${args[@]}" --backend sycl --sycl-device "$gpu")
      b2=$(median "$PT" bench "${args[@]}" --backend sycl --sycl-device "$gpu")
      a2=$(median "$CUDA_PT" bench "${args[@]}" --backend cuda)
      awk -v s="$scene" -v i=$integrator -v a="$a" -v a2="$a2" -v b="$b" -v b2="$b2" \
        'BEGIN { c = (a + a2) / 2; y = (b + b2) / 2; printf "%-14s %-10s %-10.4f %-10.4f %.3f\n", s, i, c, y, y / c }' | tee -a "$OUT/sycl-bench.txt"
    done
  done
fi

if [[ $steps == *time* ]]; then
  echo "== time to image: book-1 1200x800 100 spp to PNG (three runs each; the JIT cache is warm)"
  for backend in cuda sycl; do
    binary=$PT; [ $backend = cuda ] && binary=$CUDA_PT
    for i in 1 2 3; do
      /usr/bin/time -f "$backend: %e s wall" "$binary" render "$repo/scenes/book1-final.json" --backend $backend --width 1200 --height 800 \
        --spp 100 -o "$SCRATCH/book1.png" -v 2>"$SCRATCH/time.log"
      grep -E "wall|device start|waiting|render|total" "$SCRATCH/time.log" | tr '\n' ' '; echo
    done
  done
fi

if [[ $steps == *hang* ]]; then
  echo "== the megakernel launch that does not end (book-1 1200x800): spp against outcome, GPU load while it runs"
  for spp in 20 40 50 60 100; do
    for integrator in megakernel wavefront; do
      echo -n "$integrator $spp spp: "
      limit 30 "$PT" render "$repo/scenes/book1-final.json" --backend sycl --sycl-device "$gpu" --integrator $integrator \
        --width 1200 --height 800 --spp $spp -q -o "$SCRATCH/hang.pfm"
    done
  done
  ( sleep 10; nvidia-smi --query-gpu=utilization.gpu,clocks.sm --format=csv,noheader ) &
  ACPP_DEBUG_LEVEL=3 limit 20 "$PT" render "$repo/scenes/book1-final.json" --backend sycl --sycl-device "$gpu" --integrator megakernel \
    --width 1200 --height 800 --spp 100 -q -o "$SCRATCH/hang.pfm"
  wait
  echo "dispatches logged: $(grep -c 'inorder_executor: Dispatching' "$SCRATCH/limited.log")"
  grep -v ptx90 "$SCRATCH/limited.log" | tail -3 | cut -c1-200
fi

if [[ $steps == *probe* ]]; then
  echo "== the megakernel launches that do not end, found and traced (book-1 1200x800; tools/sycl/path_probe.cpp)"
  PROBE="$root/sycl-device/bin/pt_sycl_path_probe"
  timeout 300 "$PROBE" find "$repo/scenes/book1-final.json" 1200 800 0 99 5 >"$OUT/probe-find.log" 2>&1
  echo "find: exit $?"; grep -v "^stuck" "$OUT/probe-find.log" | tail -4; grep -c "^stuck" "$OUT/probe-find.log"
  grep "^stuck" "$OUT/probe-find.log" | head -6 | while read -r _ x y s; do
    timeout 60 "$PROBE" trace "$repo/scenes/book1-final.json" 1200 800 "$x" "$y" "$s" 5 >"$OUT/probe-trace-$x-$y-$s.log" 2>&1
    echo "trace $x $y sample $s: exit $?"
  done
fi

if [[ $steps == *profile* ]]; then
  echo "== the wavefront's intersect stage, CUDA against SYCL (Nsight Compute; seed default 1920x1080, 4 spp, third launch)"
  for backend in cuda sycl; do
    binary=$PT; extra=(--sycl-device "$gpu"); [ $backend = cuda ] && binary=$CUDA_PT && extra=()
    ncu --kernel-name-base mangled --kernel-name regex:WavefrontIntersect --launch-skip 2 --launch-count 1 --section SpeedOfLight \
      --section Occupancy --section LaunchStats --section WarpStateStats --section MemoryWorkloadAnalysis "$binary" render "$repo/scenes/seed-default.json" \
      --backend $backend "${extra[@]}" --integrator wavefront --width 1920 --height 1080 --spp 4 -q -o "$SCRATCH/ncu.pfm" >"$OUT/ncu-intersect-$backend.txt" 2>&1
    echo "-- $backend"
    grep -E "^  [A-Za-z_].*\(|Duration|Registers Per|Achieved Occupancy|Theoretical Occupancy|Block Limit Registers|Compute \(SM\) Throughput|Memory Throughput|L1/TEX Hit|L2 Hit|Warp Cycles Per Issued|Local Memory|Executed Ipc" "$OUT/ncu-intersect-$backend.txt" | cut -c1-110 | head -16
  done
fi

if [[ $steps == *bdpt* ]]; then
  echo "== bdpt through SYCL: compute-sanitizer memcheck on a render, and its time to equal error against SYCL's default integrator"
  compute-sanitizer --tool memcheck --error-exitcode 9 "$PT" render "$repo/scenes/caustics.json" --backend sycl --sycl-device "$gpu" --integrator bdpt \
    --width 32 --height 18 --spp 1 -q -o "$SCRATCH/sanitize.pfm" >"$OUT/sycl-bdpt-memcheck.log" 2>&1
  echo "memcheck exit $?"; tail -2 "$OUT/sycl-bdpt-memcheck.log"
  (cd "$repo" && python3 bench/light_sampling_efficiency.py "$PT" --option integrator --choices auto,bdpt --best-of auto --size 400x240 --spp 64 \
    --runs 3 --rounds 2 --scenes scenes/caustics.json,scenes/cornell-glass.json,scenes/light-through-gap.json,scenes/cornell-box.json,scenes/book1-final.json \
    -- --backend sycl --sycl-device "$gpu") | tee "$OUT/sycl-bdpt-efficiency.md"
fi
