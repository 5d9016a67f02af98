#!/usr/bin/env bash
# Runs on the GPU machine with out/device/ carried (tools/device/package.sh) and a second build to hold against it as
# out/base/pathtracer (for the compressed wide BVH: the device preset configured with -DPT_CUDA_COMPRESSED_BVH=ON,
# built and copied there): the GPU tests, compute-sanitizer on meshes, and the traversal figures of BENCHMARKS.md
# ("A compressed wide BVH on the GPU"), out/base against out/device side by side.
# Usage: bash tools/device/compressed-bvh.sh [tests] [sanitize] [speed]   (ROUNDS=N in the environment: rounds, 1)
OUT="${OUT:-/tmp/pt-out}"; mkdir -p "$OUT"
set -u
parts="${*:-tests sanitize speed}"
export LD_LIBRARY_PATH=$PWD/out/device/lib PT_SOURCE_DIR=$PWD PT_PATHTRACER_BINARY=$PWD/out/device/bin/pathtracer
PT=out/device/bin/pathtracer
nvidia-smi --query-gpu=name --format=csv,noheader
# The mesh scenes of BENCHMARKS.md, linked into scenes/ as ms-NAME so that side-by-side.sh finds them.
python3 -c "import sys; sys.path.insert(0,'tools/scenes'); import make_stress_scenes as m; from pathlib import Path; p=Path('/tmp/ms'); p.mkdir(exist_ok=True); m.mesh_scenes(p)"
for f in /tmp/ms/*; do ln -sf "$f" "scenes/$(basename "$f")"; done
if [[ " $parts " == *" tests "* ]]; then
  timeout 400 out/device/bin/pt_tests --gtest_brief=1 \
    --gtest_filter='*Cuda*:*Gpu*:*BackendParity*:*IntegratorEquivalence*:*Mesh*:Compressed*:BvhMatches*:*Wavefront*' > "$OUT/tests.log" 2>&1
  echo "tests exit $?"; grep -E "PASSED|FAILED|tests ran" "$OUT/tests.log" | tail -12
fi
if [[ " $parts " == *" sanitize "* ]]; then
  for s in meshes tiny bumpy-instances; do for i in megakernel wavefront; do
    compute-sanitizer --tool memcheck --error-exitcode 9 $PT render scenes/$s.json --backend cuda --integrator $i --width 64 --height 36 --spp 2 -q \
      -o /tmp/s.pfm > /tmp/san.log 2>&1; echo "memcheck $s $i exit $?"
  done; done
fi
if [[ " $parts " == *" speed "* ]]; then
  for s in heightfield-1m bumpy-1m bumpy-instances; do for i in wavefront megakernel; do
    $PT bench scenes/$s.json --backend cuda --integrator $i --width 1920 --height 1080 --spp 64 --runs 3 2>&1 | grep -oE 'scene .*rays/s|.*rror.*'
  done; done
  SCENES="heightfield-1m --width 1920 --height 1080 --spp 64|bumpy-1m --width 1920 --height 1080 --spp 64|bumpy-instances --width 1920 --height 1080 --spp 64|meshes --width 1280 --height 720 --spp 256|book1-final --width 1200 --height 800 --spp 100|cornell-smoke --width 1024 --height 1024 --spp 1000" \
    bash tools/device/side-by-side.sh out/base/pathtracer $PT "${ROUNDS:-1}"
fi
