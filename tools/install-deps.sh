#!/usr/bin/env bash
# Installs the Debian 12 packages pathtracer builds with, Verilator for the intersection units' tests and Chromium
# with its WebDriver for the preview page's tests, as root;
# does nothing when they are all there.
#   install-deps.sh            what the release, debug, asan and tsan presets need (the build and the tests)
#   install-deps.sh fuzz       that and clang 16 with its runtimes, which the fuzz preset compiles with (libFuzzer)
#   install-deps.sh synthesis  that and Yosys, nextpnr and IceStorm, which synthesise the units (tools/hardware/synth.py)
#   install-deps.sh bench      that and Embree 3, which bench/embree_side_by_side.cpp compares our traversal with
set -euo pipefail
packages=(cmake ninja-build g++ libtbb-dev libfmt-dev libcli11-dev nlohmann-json3-dev libstb-dev libopenexr-dev zlib1g-dev
          libgtest-dev libbenchmark-dev libtinyobjloader-dev libtinygltf-dev assimp-testmodels libopenmpi-dev openmpi-bin
          python3 python3-dev python3-numpy python3-pytest pybind11-dev verilator
          libcpp-httplib-dev chromium chromium-driver python3-selenium)
for extra in "$@"; do
  case "$extra" in
    fuzz) packages+=(clang-16 libclang-rt-16-dev) ;;
    synthesis) packages+=(yosys nextpnr-ice40 fpga-icestorm) ;;
    bench) packages+=(libembree-dev) ;;
    *) echo "install-deps.sh: unknown set '$extra' (known: fuzz, synthesis, bench)" >&2; exit 2 ;;
  esac
done
missing=()
for p in "${packages[@]}"; do dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p"); done
if [ ${#missing[@]} -gt 0 ]; then
  echo "installing: ${missing[*]}"
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
