// The one marker for per-ray code that must compile for every backend (host, CUDA device, SYCL device).
#pragma once

#include <cstdint>

// In a SYCL translation unit (the SYCL header defines SYCL_LANGUAGE_VERSION) atomics go through sycl::atomic_ref.
#if defined(SYCL_LANGUAGE_VERSION) && !defined(__CUDACC__)
#include <sycl/sycl.hpp>
#define PT_SYCL_KERNELS 1
// AdaptiveCpp's single-pass compiler: one compilation for the host and every device, with run-time-folded
// branches per target (__acpp_if_target_device).
#if ACPP_LIBKERNEL_COMPILER_SUPPORTS_SSCP
#define PT_ACPP_SINGLE_PASS 1
#endif
#endif

#if defined(__CUDACC__)
#define PT_HD __host__ __device__
#else
#define PT_HD
#endif

// Keeps a large step that only some paths take out of its caller in code for host CPUs, where inlining it slowed
// every path (next-event estimation's shadow ray: BENCHMARKS.md, "Light sampling"). Compilers for GPUs, CUDA's and
// SYCL's, decide for themselves.
#if defined(__CUDACC__) || defined(PT_SYCL_KERNELS)
#define PT_HOST_NOINLINE
#else
#define PT_HOST_NOINLINE __attribute__((noinline))
#endif

// Keeps a function out of line on every target. Bidirectional path tracing calls the BVH walk, the hit description and
// the material evaluation from many places in one kernel; inlined at each, its code overflowed the GPU's instruction
// cache (three quarters of its warps' stalls waiting for instructions: BENCHMARKS.md, "Bidirectional path tracing").
#if defined(__CUDACC__)
#define PT_NOINLINE __noinline__
#else
#define PT_NOINLINE __attribute__((noinline))
#endif

namespace pt {

using u8 = std::uint8_t;
using u32 = std::uint32_t;
using u64 = std::uint64_t;
using i32 = std::int32_t;

// Adds to a counter shared by the threads of one stage and returns its old value (queue pushes). Relaxed: the
// stage's end (a kernel boundary, a parallel loop's join) orders everything after it.
PT_HD inline u32 atomic_fetch_add(u32* counter, u32 value) {
#if defined(__CUDA_ARCH__)
  return atomicAdd(counter, value);
#elif defined(PT_SYCL_KERNELS)
  return sycl::atomic_ref<u32, sycl::memory_order::relaxed, sycl::memory_scope::device>(*counter).fetch_add(value);
#else
  return __atomic_fetch_add(counter, value, __ATOMIC_RELAXED);
#endif
}

// Adds to a 64-bit sum shared by the threads of one stage (light tracing's splats, kernel/bidirectional.hpp). Relaxed,
// as above; integer sums do not depend on the order of the additions.
PT_HD inline void atomic_fetch_add_u64(u64* sum, u64 value) {
#if defined(__CUDA_ARCH__)
  atomicAdd(reinterpret_cast<unsigned long long*>(sum), static_cast<unsigned long long>(value));
#elif defined(PT_SYCL_KERNELS)
  sycl::atomic_ref<u64, sycl::memory_order::relaxed, sycl::memory_scope::device>(*sum).fetch_add(value);
#else
  __atomic_fetch_add(sum, value, __ATOMIC_RELAXED);
#endif
}

// Index of the lowest set bit of a non-zero mask.
PT_HD inline u32 lowest_set_bit(u32 mask) {
#if defined(__CUDA_ARCH__)
  return static_cast<u32>(__ffs(static_cast<int>(mask)) - 1);
#else
  return static_cast<u32>(__builtin_ctz(mask));
#endif
}

// Takes a slot at the end of a queue whose length is *counter. On a GPU the threads of a warp that push onto
// the same queue together make one atomic addition between them (a queue counter is hit by every thread of a
// stage, and same-address atomics serialise); elsewhere it is one relaxed atomic per push.
PT_HD inline u32 queue_push(u32* counter) {
#if defined(__CUDA_ARCH__)
  const unsigned active = __activemask();
  const unsigned same_queue = __match_any_sync(active, reinterpret_cast<unsigned long long>(counter));
  const unsigned lane = (threadIdx.x + blockDim.x * (threadIdx.y + blockDim.y * threadIdx.z)) & 31u;  // warps follow the linear index
  const int leader = __ffs(same_queue) - 1;
  u32 first = 0;
  if (static_cast<int>(lane) == leader) first = atomicAdd(counter, static_cast<u32>(__popc(same_queue)));
  first = __shfl_sync(same_queue, first, leader);
  return first + static_cast<u32>(__popc(same_queue & ((1u << lane) - 1u)));
#else
  return atomic_fetch_add(counter, 1);
#endif
}

}  // namespace pt
