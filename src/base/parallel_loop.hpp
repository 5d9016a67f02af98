// The parallel primitives of host code: a loop (the CPU backend, image encoding), body(i) for every i in [0, count),
// `grain` indices at a time, on a fixed number of threads, and two tasks at once (the BVH builder's subtrees). oneTBB's work-stealing scheduler in normal builds; plain
// std::threads taking chunks from an atomic counter in ThreadSanitizer builds, because Debian's libtbb is not
// instrumented and ThreadSanitizer cannot see its synchronisation (every render would be reported as a race).
#pragma once

#include <algorithm>
#include <atomic>
#include <thread>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/task_arena.h>

#include "kernel/platform.hpp"

namespace pt {

class ParallelLoop {
 public:
  explicit ParallelLoop(unsigned threads) : threads_(threads), arena_(static_cast<int>(threads)) {}

  unsigned threads() const { return threads_; }

  // body(first, end) for consecutive chunks of [0, count), each of at most `grain` indices.
  template <class F>
  void run_chunks(u32 count, u32 grain, const F& body) {
    if (count == 0) return;
#if PT_CPU_STD_THREADS
    std::atomic<u32> next{0};
    auto worker = [&] {
      for (u32 first = next.fetch_add(grain); first < count; first = next.fetch_add(grain)) body(first, std::min(count, first + grain));
    };
    std::vector<std::thread> pool;
    for (unsigned t = 1; t < threads_; ++t) pool.emplace_back(worker);
    worker();
    for (std::thread& t : pool) t.join();
#else
    arena_.execute(
        [&] { tbb::parallel_for(tbb::blocked_range<u32>(0, count, grain), [&](const tbb::blocked_range<u32>& r) { body(r.begin(), r.end()); }); });
#endif
  }

  // body(i) for every i in [0, count).
  template <class F>
  void run(u32 count, u32 grain, const F& body) {
    run_chunks(count, grain, [&](u32 first, u32 end) {
      for (u32 i = first; i < end; ++i) body(i);
    });
  }

 private:
  unsigned threads_;
  tbb::task_arena arena_;
};

// first() and second() at once (on oneTBB's default arena; nested calls share its threads), returning when both have.
template <class First, class Second>
void parallel_invoke(const First& first, const Second& second) {
#if PT_CPU_STD_THREADS
  std::thread other(second);
  first();
  other.join();
#else
  tbb::parallel_invoke(first, second);
#endif
}

}  // namespace pt
