#!/usr/bin/env bash
# Packs a SYCL build of the path tracer (AdaptiveCpp, `generic` target) for a GPU machine that has the NVIDIA driver and CUDA 13
# at /usr/local/cuda but no LLVM, clang or Debian packages: out/sycl-device/ (bin/, lib/, lib/hipSYCL/, libexec/clang,
# sycl-env.sh) and out/sycl-device.tar.xz. On the GPU machine: tar -xJf sycl-device.tar.xz && source sycl-device/sycl-env.sh.
#
# Usage: bash tools/device/package-sycl.sh <build dir> [AdaptiveCpp install prefix]
#   <build dir>: a build configured with -DPT_SYCL=ON -DACPP_TARGETS=generic (pathtracer, libpt_sycl.so, optionally
#   tests/pt_tests and tests/pt_fixed_point_tests). The prefix defaults to $ACPP_PREFIX or /opt/adaptivecpp, built by
#   tools/sycl/build-adaptivecpp.sh (whose patch lets ACPP_CLANG and ACPP_CUDA_PATH move clang and libdevice at run time).
#
# Layout: the runtime looks for its backend plugins in <dir of libacpp-rt.so>/hipSYCL and for its bitcode libraries in
# <dir of libacpp-common.so>/../lib/hipSYCL/bitcode, so lib/ keeps AdaptiveCpp's own lib/ layout. The CUDA backend plugin links the
# LLVM-to-PTX translator (and with it libLLVM-16 and its dependencies) at load time, and the translator runs clang 16 (libexec/clang,
# with libclang-cpp) for the final IR-to-PTX step. Every shared library these load is carried except the ones any glibc-based
# system with an NVIDIA driver has (glibc, libstdc++, libgcc_s, zlib, zstd, xz, ncurses' libtinfo, the driver's libcuda).
set -euo pipefail
cd "$(dirname "$0")/../.."
repo="$PWD"

[ $# -ge 1 ] || { echo "usage: $0 <build dir> [AdaptiveCpp install prefix]" >&2; exit 2; }
build="$(realpath "$1")"
acpp="$(realpath "${2:-${ACPP_PREFIX:-/opt/adaptivecpp}}")"
out="$repo/out/sycl-device"
tarball="$repo/out/sycl-device.tar.xz"

[ -x "$build/pathtracer" ] || { echo "no pathtracer in $build" >&2; exit 1; }
[ -f "$acpp/lib/libacpp-rt.so" ] || { echo "no AdaptiveCpp install at $acpp" >&2; exit 1; }

# The clang the installation was configured with (acpp-core.json's default-clang): the PTX JIT runs it.
clang_bin="$(sed -n 's/.*"default-clang" *: *"\([^"]*\)".*/\1/p' "$acpp/etc/AdaptiveCpp/acpp-core.json")"
clang_bin="$(readlink -f "${clang_bin:-/usr/lib/llvm-16/bin/clang++}")"
[ -x "$clang_bin" ] || { echo "clang not found: $clang_bin" >&2; exit 1; }

rm -rf "$out" "$tarball"
mkdir -p "$out/bin" "$out/lib" "$out/libexec"

# Programs.
cp "$build/pathtracer" "$out/bin/"
for t in "$build/tests/pt_tests" "$build/tests/pt_fixed_point_tests" "$build/pt_sycl_path_probe"; do
  if [ -x "$t" ]; then cp "$t" "$out/bin/"; fi
done
# The SYCL backend library, wherever the build put it (the loader's answer first).
pt_sycl="$(ldd "$build/pathtracer" | awk '$1 == "libpt_sycl.so" && $3 ~ /^\// {print $3}')"
[ -n "$pt_sycl" ] || pt_sycl="$(find "$build" -name libpt_sycl.so -print -quit)"
[ -f "$pt_sycl" ] || { echo "libpt_sycl.so not found (was the build configured with -DPT_SYCL=ON?)" >&2; exit 1; }
cp -L "$pt_sycl" "$out/lib/"
# Without their symbol tables the programs and the backend pack 2 MiB smaller: less to copy to the GPU machine.
strip --strip-unneeded "$out"/bin/* "$out/lib/libpt_sycl.so"

# AdaptiveCpp's runtime with its plugin folders (backends, LLVM-to-backend translators, bitcode), same layout as installed.
# Left out: libacpp-clang.so (the compiler plugin), the translators' stand-alone tools, headers and CMake files.
cp -L "$acpp/lib/libacpp-rt.so" "$acpp/lib/libacpp-common.so" "$out/lib/"
mkdir -p "$out/lib/hipSYCL/llvm-to-backend" "$out/lib/hipSYCL/bitcode"
for plugin in "$acpp"/lib/hipSYCL/librt-backend-*.so; do cp -L "$plugin" "$out/lib/hipSYCL/"; done
cp -L "$acpp"/lib/hipSYCL/llvm-to-backend/*.so "$out/lib/hipSYCL/llvm-to-backend/"
cp -L "$acpp"/lib/hipSYCL/bitcode/*.bc "$out/lib/hipSYCL/bitcode/"
[ -f "$out/lib/hipSYCL/librt-backend-cuda.so" ] || { echo "AdaptiveCpp at $acpp has no CUDA backend" >&2; exit 1; }
[ -f "$out/lib/hipSYCL/llvm-to-backend/libllvm-to-ptx.so" ] || { echo "AdaptiveCpp at $acpp has no LLVM-to-PTX translator" >&2; exit 1; }

# clang for the JIT's IR-to-PTX step; its RUNPATH ($ORIGIN/../lib) finds libclang-cpp and libLLVM in lib/.
cp -L "$clang_bin" "$out/libexec/clang"

# Every non-system shared library that these load, to a fixed point (ldd resolves through the package first).
system_lib='^(linux-vdso|ld-linux|libc|libm|libdl|libpthread|librt|libutil|libresolv|libmvec|libstdc\+\+|libgcc_s|libz|libzstd|liblzma|libtinfo|libcuda|libnvidia-[a-z-]*)\.so'
pkg_path="$out/lib:$out/lib/hipSYCL:$out/lib/hipSYCL/llvm-to-backend"
while :; do
  added=0
  while IFS= read -r elf; do
    while read -r name arrow path _; do
      [ "$arrow" = "=>" ] || continue
      [[ $name =~ $system_lib ]] && continue
      case "$path" in "$out"/*) continue ;; esac
      [ -e "$out/lib/$name" ] && continue
      [ -f "$path" ] || { echo "unresolved: $name (needed by ${elf#$out/})" >&2; exit 1; }
      cp -L "$path" "$out/lib/$name"
      added=1
    done < <(LD_LIBRARY_PATH="$pkg_path" ldd "$elf" 2>/dev/null || true)
  done < <(find "$out/bin" "$out/lib" "$out/libexec" -type f \( -name '*.so*' -o -perm -u+x \) ! -name '*.bc')
  [ $added -eq 1 ] || break
done

# Whatever still resolves outside the package must be a system library (libcuda.so.1 is missing on a machine without the driver).
bad=0
while IFS= read -r elf; do
  while read -r name arrow path _; do
    [ "$arrow" = "=>" ] || continue
    [[ $name =~ $system_lib ]] && continue
    case "$path" in "$out"/*) ;; *) echo "outside the package: $name => $path (needed by ${elf#$out/})" >&2; bad=1 ;; esac
  done < <(LD_LIBRARY_PATH="$pkg_path" ldd "$elf" 2>/dev/null || true)
done < <(find "$out/bin" "$out/lib" "$out/libexec" -type f \( -name '*.so*' -o -perm -u+x \) ! -name '*.bc')
[ $bad -eq 0 ] || exit 1

cp "$repo/tools/device/sycl-env.sh" "$out/sycl-env.sh"
{
  echo "pathtracer SYCL package: AdaptiveCpp generic target (LLVM IR JIT-compiled to PTX at run time)."
  echo "Packed $(date -u +%Y-%m-%dT%H:%M:%SZ) from $build, AdaptiveCpp $acpp, clang $clang_bin."
  echo "Use: source sycl-env.sh (sets LD_LIBRARY_PATH, ACPP_CLANG, ACPP_CUDA_PATH, ACPP_APPDB_DIR; see its comments)."
} >"$out/README.txt"

echo "== $out"
(cd "$out" && find . -type f -printf '%s\t%p\n' | sort -k2 | awk -F'\t' '{printf "%10d  %s\n", $1, $2}')
echo "unpacked: $(du -sb "$out" | cut -f1) bytes ($(du -sh "$out" | cut -f1))"
tar -C "$repo/out" -cf - sycl-device | xz -9 -T2 >"$tarball"
echo "compressed: $tarball $(stat -c %s "$tarball") bytes ($(du -h "$tarball" | cut -f1))"
size=$(stat -c %s "$tarball")
if [ "$size" -gt $((60 * 1024 * 1024)) ]; then
  echo "warning: the tarball is over 60 MiB, the most that travels to the GPU machine" >&2
fi
