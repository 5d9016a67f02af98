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

}  // namespace pt
