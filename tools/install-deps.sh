#!/usr/bin/env bash
# Installs the Debian 12 packages pathtracer builds with, and the hardware tools (Verilator for the units' tests, Yosys
# and nextpnr for their synthesis), as root; does nothing when they are all there.
set -euo pipefail
packages=(cmake ninja-build g++ libtbb-dev libfmt-dev libcli11-dev nlohmann-json3-dev libstb-dev libopenexr-dev zlib1g-dev
          libgtest-dev libbenchmark-dev libtinyobjloader-dev libtinygltf-dev assimp-testmodels libopenmpi-dev openmpi-bin
          python3 verilator yosys nextpnr-ice40 fpga-icestorm)
missing=()
for p in "${packages[@]}"; do dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p"); done
if [ ${#missing[@]} -gt 0 ]; then
  echo "installing: ${missing[*]}"
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
