# Source (do not run) on the GPU machine after unpacking out/sycl-device.tar.xz (tools/device/package-sycl.sh), to run the
# SYCL build (AdaptiveCpp, `generic` target: kernels JIT-compiled from LLVM IR to PTX at run time) from the unpacked tree:
#   tar -xJf sycl-device.tar.xz -C /some/dir && source /some/dir/sycl-device/sycl-env.sh
#   pathtracer devices; pathtracer render scenes/book-1.json --backend sycl ...
# The package carries a copy of this file at its root, which finds the tree beside itself; sourced from elsewhere (the
# repository's tools/device/), set PT_SYCL_ROOT to the unpacked sycl-device folder first, or have out/sycl-device under $PWD.
#
# What it sets (each only where not set already, so a caller can choose):
#   PATH, LD_LIBRARY_PATH  the package's bin/ and lib/ (AdaptiveCpp's runtime, LLVM 16, clang 16's libraries, TBB, OpenEXR...)
#   ACPP_CLANG             the clang the PTX JIT runs (`clang -cc1 -x ir -S` for nvptx64); AdaptiveCpp would otherwise run
#                          /usr/lib/llvm-16/bin/clang++, fixed when it was built (honoured through adaptivecpp-cuda13.patch)
#   ACPP_CUDA_PATH         the CUDA root whose nvvm/libdevice/libdevice.*.bc the PTX JIT links (default /usr/local/cuda)
#   ACPP_APPDB_DIR         AdaptiveCpp's application database and persistent JIT cache (default $HOME/.acpp); here
#                          PT_SYCL_CACHE_DIR, or <package>/acpp-cache. Entries are per executable *path*
#                          (apps/<name>-<hash of the path>/jit-cache), so a cache is reused only when the package is unpacked
#                          at the same path again.
#   CUDA_CACHE_PATH        the driver's PTX-to-SASS cache (default $HOME/.nv/ComputeCache), kept beside the JIT cache
# A cold cache makes the first run of each kernel JIT-compile it (seconds, and AdaptiveCpp warns that new binaries were
# compiled); ACPP_RT_NO_JIT_CACHE_POPULATION=1 would stop the cache from being filled. The JIT writes its temporary .bc/.s files
# into the current directory, which therefore has to be writable.

_pt_sycl_root="${PT_SYCL_ROOT:-}"
if [ -z "$_pt_sycl_root" ]; then
  _pt_sycl_here="$(cd "$(dirname "${BASH_SOURCE[0]:-$0}")" && pwd)"
  if [ -d "$_pt_sycl_here/lib/hipSYCL" ]; then
    _pt_sycl_root="$_pt_sycl_here"
  elif [ -d "$PWD/out/sycl-device/lib/hipSYCL" ]; then
    _pt_sycl_root="$PWD/out/sycl-device"
  fi
  unset _pt_sycl_here
fi
if [ -z "$_pt_sycl_root" ] || [ ! -d "$_pt_sycl_root/lib/hipSYCL" ]; then
  echo "sycl-env.sh: cannot find the unpacked sycl-device tree; set PT_SYCL_ROOT" >&2
  unset _pt_sycl_root
  return 1 2>/dev/null || exit 1
fi
# No trailing slash or '.' in these paths: AdaptiveCpp derives its install root (bitcode libraries, plugins) lexically from
# the path libacpp-common.so was loaded from.
_pt_sycl_root="$(cd "$_pt_sycl_root" && pwd -P)"

export PT_SYCL_ROOT="$_pt_sycl_root"
export PATH="$_pt_sycl_root/bin${PATH:+:$PATH}"
export LD_LIBRARY_PATH="$_pt_sycl_root/lib:$_pt_sycl_root/lib/hipSYCL:$_pt_sycl_root/lib/hipSYCL/llvm-to-backend${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export ACPP_CLANG="${ACPP_CLANG:-$_pt_sycl_root/libexec/clang}"
export ACPP_CUDA_PATH="${ACPP_CUDA_PATH:-/usr/local/cuda}"
export ACPP_APPDB_DIR="${ACPP_APPDB_DIR:-${PT_SYCL_CACHE_DIR:-$_pt_sycl_root/acpp-cache}}"
export CUDA_CACHE_PATH="${CUDA_CACHE_PATH:-$ACPP_APPDB_DIR/nv-compute-cache}"
mkdir -p "$ACPP_APPDB_DIR" "$CUDA_CACHE_PATH"

if ! ls "$ACPP_CUDA_PATH"/nvvm/libdevice/libdevice.*.bc >/dev/null 2>&1 && [ -z "${ACPP_CUDA_LIBDEVICE_PATH:-}" ]; then
  echo "sycl-env.sh: no libdevice under $ACPP_CUDA_PATH/nvvm/libdevice; set ACPP_CUDA_PATH (CUDA root) or ACPP_CUDA_LIBDEVICE_PATH (the .bc file)" >&2
fi
unset _pt_sycl_root
