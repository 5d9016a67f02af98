// The CPU device: host memory, and kernels run as parallel loops on a fixed number of threads (oneTBB's
// work-stealing scheduler). Images are tiled 8x8, one task a tile, so that each pixel is rendered by exactly one
// thread and the image is bitwise the same for any number of threads. Each scalar type's backend is compiled in a
// source file of its own (cpu_backend_*.cpp): GCC spends its inlining budget per translation unit, and with the
// fixed-point formats in the same unit it stopped inlining the float kernels' shading functions (5 % slower).
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstring>
#include <new>
#include <string>

#include <tbb/task_arena.h>

#include "backends/backend.hpp"
#include "base/parallel_loop.hpp"
#include "kernel/fixed_point.hpp"

namespace pt {

class CpuDevice {
 public:
  explicit CpuDevice(unsigned threads)
      : threads_(threads == 0 ? static_cast<unsigned>(tbb::this_task_arena::max_concurrency()) : threads), loop_(threads_) {}

  std::string kind() const { return "cpu"; }
  std::string description() const { return std::to_string(threads_) + (threads_ == 1 ? " thread" : " threads"); }
  bool host() const { return true; }
  // What `auto` takes here: on CPUs the megakernel is the faster (BENCHMARKS.md).
  Integrator preferred_integrator() const { return Integrator::kMegakernel; }
  bool memory_on_host() const { return true; }
  bool times_on_device() const { return false; }

  void* allocate(std::size_t bytes, const char*) { return ::operator new(std::max<std::size_t>(bytes, 1), kAlignment); }
  void release(void* pointer) { ::operator delete(pointer, kAlignment); }
  void copy_to_device(void* to, const void* from, std::size_t bytes, const char*) { std::memcpy(to, from, bytes); }
  void copy_to_host(void* to, const void* from, std::size_t bytes, const char*) { std::memcpy(to, from, bytes); }
  void clear(void* to, std::size_t bytes, const char*) { std::memset(to, 0, bytes); }
  void synchronise(const char*) {}

  template <class Kernel>
  void launch(const char*, u32 count, const Kernel& kernel) {
    run(count, kItemGrain, [&](u32 i) { kernel(i); });
  }

  template <class Kernel>
  void launch_image(const char*, u32 width, u32 height, const Kernel& kernel) {
    const u32 tiles_x = (width + kTile - 1) / kTile, tiles_y = (height + kTile - 1) / kTile;
    run(tiles_x * tiles_y, 1, [&](u32 tile) {
      const u32 x0 = (tile % tiles_x) * kTile, y0 = (tile / tiles_x) * kTile;
      for (u32 y = y0; y < std::min(height, y0 + kTile); ++y)
        for (u32 x = x0; x < std::min(width, x0 + kTile); ++x) kernel(x, y);
    });
  }

  // Launches run to completion before they return, so the wall clock times them.
  using Timer = std::chrono::steady_clock::time_point;
  Timer start_timer() const { return std::chrono::steady_clock::now(); }
  void stop_timer(Timer start, double* seconds) const { *seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); }

  u64 saturations() const { return saturations_.load(std::memory_order_relaxed); }

 private:
  static constexpr std::align_val_t kAlignment{64};  // a cache line: enough for every kernel struct
  static constexpr u32 kTile = 8;
  static constexpr u32 kItemGrain = 256;

  // Kernels count fixed-point saturations per thread; each chunk of a loop adds what its thread counted meanwhile.
  template <class Body>
  void run(u32 count, u32 grain, const Body& body) {
    loop_.run_chunks(count, grain, [&](u32 first, u32 end) {
      const u64 before = fixed_saturations_this_thread();
      for (u32 i = first; i < end; ++i) body(i);
      if (const u64 counted = fixed_saturations_this_thread() - before) saturations_.fetch_add(counted, std::memory_order_relaxed);
    });
  }

  unsigned threads_;
  ParallelLoop loop_;
  std::atomic<u64> saturations_{0};
};

}  // namespace pt
