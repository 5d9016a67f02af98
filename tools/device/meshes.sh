#!/usr/bin/env bash
# Runs on the GPU machine with out/device/ carried (tools/device/package.sh): the mesh tests, compute-sanitizer on the
# mesh scenes, and the mesh benchmarks of BENCHMARKS.md ("Meshes"), on scenes made there by make_stress_scenes.py.
OUT="${OUT:-/tmp/pt-out}"; mkdir -p "$OUT"
set -u
export LD_LIBRARY_PATH=$PWD/out/device/lib PT_SOURCE_DIR=$PWD PT_PATHTRACER_BINARY=$PWD/out/device/bin/pathtracer
PT=out/device/bin/pathtracer
nvidia-smi --query-gpu=name --format=csv,noheader
python3 -c "import sys; sys.path.insert(0,'tools/scenes'); import make_stress_scenes as m; from pathlib import Path; p=Path('/tmp/ms'); p.mkdir(exist_ok=True); m.mesh_scenes(p)" || echo "no python"
# The real models of the tests (Debian's assimp-testmodels), where carried as out/assimp/.
[ -d out/assimp ] && [ ! -d /usr/share/assimp/models ] && mkdir -p /usr/share/assimp && cp -r out/assimp /usr/share/assimp/models
echo "== tests"
timeout 300 out/device/bin/pt_tests --gtest_brief=1 --gtest_filter='*Cuda*:*Gpu*:*BackendParity*:*IntegratorEquivalence*:*Mesh*:ModelFiles*:RealModels*' > $OUT/tests.log 2>&1; echo "exit $?"; grep -E "PASSED|FAILED|tests ran" $OUT/tests.log | tail -8
echo "== sanitizer"
for s in scenes/meshes.json scenes/tiny.json; do for i in megakernel wavefront; do
  compute-sanitizer --tool memcheck --error-exitcode 9 $PT render $s --backend cuda --integrator $i --width 64 --height 36 --spp 2 -q -o /tmp/s.pfm > /tmp/san.log 2>&1; echo "$s $i exit $?"; tail -3 /tmp/san.log | grep -v "^$" | head -2
done; done
echo "== bench"
for i in megakernel wavefront; do
  $PT bench scenes/meshes.json --backend cuda --integrator $i --width 1280 --height 720 --spp 256 --runs 3 2>/dev/null
  $PT bench /tmp/ms/bumpy-2m.json --backend cuda --integrator $i --width 1280 --height 720 --spp 64 --runs 3 2>/dev/null
  $PT bench /tmp/ms/bumpy-instances.json --backend cuda --integrator $i --width 1280 --height 720 --spp 64 --runs 3 2>/dev/null
done
for i in megakernel wavefront; do $PT bench /tmp/ms/bumpy-1m.json --backend cuda --integrator $i --width 1920 --height 1080 --spp 64 --runs 3 2>/dev/null; done
for f in /tmp/ms/bumpy-2m.json /tmp/ms/bumpy-instances.json; do $PT render $f --backend cuda --spp 16 -v -q -o /tmp/x.png 2>&1 | grep -E "scene load|flatten|BVH|upload" ; done
$PT render scenes/meshes.json --backend cuda --width 1280 --height 720 --spp 1024 -q -o $OUT/meshes.png; echo "render exit $?"
