#!/usr/bin/env bash
# Builds the device preset (the release build with the CUDA backend, host code for x86-64-v3 so that it runs on
# whatever processor the GPU machine has) and gathers what a GPU machine without Debian's packages needs to run
# it: the binaries and the non-system shared libraries they load, under out/device/.
set -euo pipefail
cd "$(dirname "$0")/../.."
cmake --preset device >/dev/null
cmake --build build/device
rm -rf out/device
mkdir -p out/device/bin out/device/lib
cp build/device/pathtracer out/device/bin/
for t in build/device/tests/pt_tests build/device/tests/pt_fixed_point_tests; do [ -x "$t" ] && cp "$t" out/device/bin/; done
for binary in out/device/bin/*; do
  ldd "$binary" | awk '/=> \// {print $3}' | grep -E 'libtbb|libfmt|libOpenEXR|libstb|libImath|libIlmThread|libIex|libgtest|libbenchmark|libtinyobjloader|libtinygltf' | while read -r lib; do
    cp -L "$lib" out/device/lib/
  done
done
du -sh out/device
