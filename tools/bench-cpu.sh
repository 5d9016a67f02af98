#!/usr/bin/env bash
# The CPU figures of BENCHMARKS.md: the seed's default scene at the seed implementation's settings (with peak
# memory), then megakernel against wavefront on four scenes. Run from the repository root after a release build.
set -euo pipefail
PT=${PT:-./build/release/pathtracer}
echo "== seed default scene, 800x480, 100 spp, depth 50, all cores"
/usr/bin/time -f "peak resident memory: %M KiB" "$PT" bench scenes/seed-default.json --backend cpu --integrator megakernel \
  --width 800 --height 480 --spp 100 --depth 50 --runs 3
echo "== megakernel against wavefront"
for args in "book1-final --width 600 --height 400 --spp 16" "seed-default --width 800 --height 480 --spp 16" \
            "cornell-smoke --width 256 --height 256 --spp 64" "book2-final --width 400 --height 400 --spp 32"; do
  set -- $args
  scene=$1
  shift
  for integrator in megakernel wavefront; do
    "$PT" bench "scenes/$scene.json" --backend cpu --integrator "$integrator" "$@" --runs 3 2>/dev/null
  done
done
