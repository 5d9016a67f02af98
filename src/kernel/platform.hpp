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

// Adds to a counter shared by the threads of one stage and returns its old value (queue pushes). Relaxed: the
// stage's end (a kernel boundary, a parallel loop's join) orders everything after it.
PT_HD inline u32 atomic_fetch_add(u32* counter, u32 value) {
#if defined(__CUDA_ARCH__)
  return atomicAdd(counter, value);
#else
  return __atomic_fetch_add(counter, value, __ATOMIC_RELAXED);
#endif
}

}  // namespace pt
