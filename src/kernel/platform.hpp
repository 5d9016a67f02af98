// The one marker for per-ray code that must compile for every backend (host, CUDA device, SYCL device).
#pragma once

#include <cstdint>

#if defined(__CUDACC__)
#define PT_HD __host__ __device__
#else
#define PT_HD
#endif

namespace pt {

using u32 = std::uint32_t;
using u64 = std::uint64_t;
using i32 = std::int32_t;

// Marks a code path the caller guarantees is never taken (an index outside a variant, say):
// in kernels there are no exceptions, so the compiler is simply told the path does not exist.
[[noreturn]] PT_HD inline void unreachable() { __builtin_unreachable(); }

}  // namespace pt
