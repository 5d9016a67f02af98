#!/usr/bin/env bash
# Measures what loading a scene costs: wall time, the "scene load" phase and peak memory of a tiny render of each
# file given, the median of RUNS runs (BENCHMARKS.md, "Scene loading"). Files: tools/scenes/make_stress_scenes.py.
#
# Usage: tools/bench-scene-load.sh PATHTRACER FILE... (environment: RUNS=3, TIMEOUT=120)
set -u
binary=$1
shift
runs=${RUNS:-3}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
median() { sort -g | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] }'; }
for file in "$@"; do
  : > "$out/wall"; : > "$out/rss"; : > "$out/load"
  for _ in $(seq "$runs"); do
    /usr/bin/time -v -o "$out/time" timeout "${TIMEOUT:-120}" "$binary" render "$file" --spp 1 --width 8 --height 8 -v -q \
      -o "$out/image.png" > /dev/null 2> "$out/err"
    code=$?
    awk -F': ' '/Elapsed \(wall clock\)/ { n = split($2, t, ":"); s = 0; for (i = 1; i <= n; ++i) s = s * 60 + t[i]; print s }' "$out/time" >> "$out/wall"
    awk -F': ' '/Maximum resident set size/ { printf "%.0f\n", $2 / 1024 }' "$out/time" >> "$out/rss"
    awk '/scene load/ { for (i = 1; i <= NF; ++i) if ($i ~ /^[0-9.]+$/) { print $i; exit } }' "$out/err" >> "$out/load"
  done
  printf '%s: exit %s, wall %s s, scene load %s, peak RSS %s MB | %s\n' "$(basename "$file")" "$code" "$(median < "$out/wall")" \
    "$(median < "$out/load")" "$(median < "$out/rss")" "$(grep -v '^ ' "$out/err" | head -c 160 | tr '\n' ' ')"
done
