#!/usr/bin/env bash
# Runs on the GPU machine with out/device/ carried (tools/device/package.sh): where the wavefront's time goes under
# each light sampling choice, on the scenes whose only lamp is one small sphere, for one build or several side by
# side. Rounds of none, auto and nee in turns, the builds in turns within each; each line is `bench`'s median of 5
# with its per-stage shares.
# Usage: bash tools/device/light-stages.sh ROUNDS PATHTRACER...   (SCENES="seed-default tiny" by default)
set -uo pipefail
export LD_LIBRARY_PATH="$PWD/out/device/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
rounds="${1:-3}"
shift || true
builds="${*:-$PWD/out/device/bin/pathtracer}"
for round in $(seq "$rounds"); do
  for scene in ${SCENES:-seed-default tiny}; do
    for choice in none auto nee; do
      for build in $builds; do
        printf '%s %s %s round %s: ' "$(basename "$build")" "$scene" "$choice" "$round"
        "$build" bench "scenes/$scene.json" --backend cuda --integrator wavefront --width 400 --height 240 --spp 256 --runs 5 \
          --light-sampling "$choice" 2>/dev/null | tail -1 | sed -E 's/.*median of 5: ([0-9.]+ s).*\| ([0-9.]+ rays\/sample).*stages: /\1 \2 | /'
      done
    done
  done
done
