#!/usr/bin/env bash
# Two builds of pathtracer compared side by side on this machine, in rounds of old, new, new, old (so that drift of the
# machine's speed falls on both): single-thread short renders, the ratio new/old of each round's sums, then the
# median and quartiles of the ratios. Usage: bash tools/bench-abba.sh OLD_BINARY NEW_BINARY [ROUNDS] [SCENE] [INTEGRATOR]
set -euo pipefail
old=$1 new=$2 rounds=${3:-16} scene=${4:-seed-default} integrator=${5:-megakernel}
args=(scenes/$scene.json --backend cpu --threads 1 --integrator "$integrator" --width 400 --height 240 --spp 16 --runs 1)
seconds() { "$1" bench "${args[@]}" 2>/dev/null | grep -oE 'median of [0-9]+: [0-9.]+ s' | awk '{print $4}'; }
for _ in $(seq "$rounds"); do
  a=$(seconds "$old") b=$(seconds "$new") b2=$(seconds "$new") a2=$(seconds "$old")
  awk -v a="$a" -v b="$b" -v b2="$b2" -v a2="$a2" 'BEGIN { printf "%.4f\n", (b + b2) / (a + a2) }'
done | sort -n | awk '{ r[NR] = $1 } END { printf "rounds %d, new/old: median %.3f, quartiles %.3f %.3f\n", NR, r[int((NR + 1) / 2)], r[int(NR / 4) + 1], r[int(3 * NR / 4)] }'
