# Builds AdaptiveCpp (SYCL) with its CUDA backend against CUDA 13 and Debian 12's LLVM 16, for the SYCL backend's `generic` target.
#
# Usage: bash tools/sycl/build-adaptivecpp.sh <AdaptiveCpp source dir> <install prefix>
#   The source is AdaptiveCpp commit 49544a4828da7383ae481a3fc5c5e480c8a4f142 (develop, Oct 2024); adaptivecpp-cuda13.patch (beside
#   this script) is applied to it in place, unless it already is. The build directory is <source>/build (BUILD_DIR overrides it);
#   JOBS (default 2) and NICE (default 10) keep the build gentle on a shared machine.
# Needs (Debian 12): apt-get install -y llvm-16-dev clang-16 libclang-16-dev libomp-16-dev libboost-context-dev
#   libboost-fiber-dev cmake ninja-build, and CUDA at /usr/local/cuda (CUDA_ROOT overrides it).
# Backends: OpenMP (CPU; always built) and CUDA; OpenCL, ROCm and Level Zero off. The `cuda` target (clang's CUDA mode) does not
# work with CUDA 13; only the `generic` target (single-pass compiler, kernels JIT-compiled from LLVM IR to PTX at run time) is meant
# to be used. At run time that JIT runs clang (`clang++ -cc1 ... -x ir -S`) and links CUDA's libdevice; the patch lets ACPP_CLANG,
# ACPP_CUDA_PATH and ACPP_CUDA_LIBDEVICE_PATH point them elsewhere than the paths fixed here (see tools/device/sycl-env.sh).
set -euo pipefail

if [ $# -ne 2 ]; then
  echo "usage: $0 <AdaptiveCpp source dir> <install prefix>" >&2
  exit 2
fi
src=$(realpath "$1")
prefix=$(realpath -m "$2")
here=$(cd "$(dirname "$0")" && pwd)
patch_file="$here/adaptivecpp-cuda13.patch"
build="${BUILD_DIR:-$src/build}"
jobs="${JOBS:-2}"
niceness="${NICE:-10}"
cuda="${CUDA_ROOT:-/usr/local/cuda}"
llvm=/usr/lib/llvm-16

[ -f "$src/CMakeLists.txt" ] && [ -d "$src/src/runtime/cuda" ] || { echo "not an AdaptiveCpp source tree: $src" >&2; exit 1; }
[ -x "$llvm/bin/clang++" ] || { echo "clang 16 missing: apt-get install -y clang-16 llvm-16-dev libclang-16-dev libomp-16-dev" >&2; exit 1; }
[ -x "$cuda/bin/nvcc" ] || { echo "CUDA not found at $cuda" >&2; exit 1; }

# The patch: applied once (a second run finds it applied and leaves the tree alone).
if patch -d "$src" -p1 -R --dry-run -s -f <"$patch_file" >/dev/null 2>&1; then
  echo "adaptivecpp-cuda13.patch: already applied"
else
  patch -d "$src" -p1 -N <"$patch_file"
fi

start=$(date +%s)
nice -n "$niceness" cmake -G Ninja -S "$src" -B "$build" \
  -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_INSTALL_PREFIX="$prefix" \
  -DCMAKE_C_COMPILER="$llvm/bin/clang" \
  -DCMAKE_CXX_COMPILER="$llvm/bin/clang++" \
  -DLLVM_DIR="$llvm/lib/cmake/llvm" \
  -DCLANG_EXECUTABLE_PATH="$llvm/bin/clang++" \
  -DACPP_COMPILER_FEATURE_PROFILE=full \
  -DWITH_CUDA_BACKEND=ON \
  -DCUDA_TOOLKIT_ROOT_DIR="$cuda" \
  -DWITH_ROCM_BACKEND=OFF \
  -DWITH_OPENCL_BACKEND=OFF \
  -DWITH_LEVEL_ZERO_BACKEND=OFF \
  -DDEFAULT_TARGETS=generic
nice -n "$niceness" cmake --build "$build" -j "$jobs"
nice -n "$niceness" cmake --install "$build"
end=$(date +%s)
echo "AdaptiveCpp installed in $prefix (configure + build + install: $((end - start)) s)"
