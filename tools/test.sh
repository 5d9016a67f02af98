#!/usr/bin/env bash
# The test command: installs what is missing, builds the release preset (the CUDA backend too wherever nvcc is
# found, so kernel code that breaks device rules fails here) and runs the suite, then runs it again under
# AddressSanitizer and UndefinedBehaviorSanitizer.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/install-deps.sh
jobs=$(nproc)
cmake --preset release
cmake --build build/release -j "$jobs"
ctest --preset release -j "$jobs"
cmake --preset asan
cmake --build build/asan -j "$jobs"
ctest --preset asan -j "$jobs"
