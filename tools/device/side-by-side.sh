#!/usr/bin/env bash
# Two builds timed side by side on the GPU machine, alternating (old, new, new, old per round) so that drift of the
# machine's speed falls on both: `bench --runs 3` medians of two GPU lines of BENCHMARKS.md (book-1, Cornell smoke), both integrators.
# Usage: bash tools/device/side-by-side.sh OLD_BINARY NEW_BINARY [ROUNDS]   (from the repository root, after
# tools/device/package.sh; the binaries load their libraries from out/device/lib). SCENES, where set, replaces the
# two lines: "scene and bench arguments" separated by '|', e.g. SCENES="cornell-box --spp 1000|tiny --spp 64".
set -uo pipefail
old=$1 new=$2 rounds=${3:-2}
export LD_LIBRARY_PATH="$PWD/out/device/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
median() {  # binary, scene, size and spp arguments...: prints the median seconds of bench
  local binary=$1
  shift
  "$binary" bench "$@" --backend cuda --runs 3 2>/dev/null | grep -oE 'median of [0-9]+: [0-9.]+ s' | awk '{print $4}'
}
printf '%-16s %-10s %-6s %-10s %-10s %s\n' scene integrator round old_s new_s new/old
IFS='|' read -r -a lines <<<"${SCENES:-book1-final --width 1200 --height 800 --spp 100|cornell-smoke --width 1024 --height 1024 --spp 1000}"
for line in "${lines[@]}"; do
  set -- $line
  scene=$1
  shift
  for integrator in wavefront megakernel; do
    for round in $(seq "$rounds"); do
      a=$(median "$old" "scenes/$scene.json" "$@" --integrator $integrator)
      b=$(median "$new" "scenes/$scene.json" "$@" --integrator $integrator)
      b2=$(median "$new" "scenes/$scene.json" "$@" --integrator $integrator)
      a2=$(median "$old" "scenes/$scene.json" "$@" --integrator $integrator)
      awk -v s="$scene" -v i=$integrator -v r="$round" -v a="$a" -v a2="$a2" -v b="$b" -v b2="$b2" \
        'BEGIN { o = (a + a2) / 2; n = (b + b2) / 2; printf "%-16s %-10s %-6s %-10.4f %-10.4f %.3f\n", s, i, r, o, n, n / o }'
    done
  done
done
