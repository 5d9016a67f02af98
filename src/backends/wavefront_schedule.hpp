// The wavefront integrator's schedule, shared by every backend: which stage runs over how many queue entries,
// batch after batch, with the path pool refilled from the batch's remaining work items.
#pragma once

#include <array>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "kernel/wavefront.hpp"

namespace pt {

// Stage names, in the order the per-stage times are reported.
inline constexpr std::array<const char*, 5> kWavefrontStageNames{"generate", "intersect", "escaped", "shade", "accumulate"};

// Paths in flight: a GPU needs about a million to fill its threads; a CPU a pool that stays near its caches.
inline constexpr u32 kGpuWavefrontPool = 1u << 20;
inline constexpr u32 kHostWavefrontPool = 1u << 16;

// Samples per batch so that a batch holds several pools' worth of paths (keeps the pool full) but its result
// buffer stays bounded.
u32 wavefront_samples_per_batch(u32 pixels, u32 pool_capacity);

// What a backend provides: each call runs one stage over a whole queue, adding its time to seconds_. The base
// keeps the geometry of the schedule (image size, pool capacity, samples per batch), set once.
class WavefrontStages {
 public:
  WavefrontStages(u32 pixels, u32 pool_capacity)
      : pixels_(pixels), pool_capacity_(pool_capacity), samples_per_batch_(wavefront_samples_per_batch(pixels, pool_capacity)) {}
  virtual ~WavefrontStages() = default;
  u32 pixels() const { return pixels_; }
  u32 pool_capacity() const { return pool_capacity_; }
  u32 samples_per_batch() const { return samples_per_batch_; }
  virtual void begin_batch(u32 first_sample, u32 sample_count) = 0;
  virtual void generate(u32 first_slot, u32 count, u32 first_item) = 0;
  virtual void intersect(u32 count) = 0;
  virtual void escaped(u32 count) = 0;
  virtual void shade(u32 material_class, u32 count) = 0;
  virtual void accumulate(u32 sample_count) = 0;
  // Reads the queue counters and sets them to zero.
  virtual std::array<u32, kWavefrontCounters> take_counters() = 0;
  virtual void swap_pools() = 0;

  // Seconds spent in each stage so far, named in kWavefrontStageNames order.
  std::vector<std::pair<std::string, double>> stage_seconds() const {
    std::vector<std::pair<std::string, double>> out;
    for (std::size_t i = 0; i < kWavefrontStageNames.size(); ++i) out.emplace_back(kWavefrontStageNames[i], seconds_[i]);
    return out;
  }
  double total_seconds() const {
    double total = 0;
    for (double s : seconds_) total += s;
    return total;
  }

 protected:
  std::array<double, kWavefrontStageNames.size()> seconds_{};

 private:
  u32 pixels_, pool_capacity_, samples_per_batch_;
};


// The wavefront's arrays for the stages' pool, each taken from `allocate(bytes)` (device memory on a GPU): both
// pools, the hits, the escaped and material queues, the counters, and one result per work item of a batch. The
// caller clears the counters.
template <class T, class Allocate>
void allocate_wavefront(const WavefrontStages& stages, WavefrontView<T>& view, Allocate&& allocate) {
  const u32 capacity = stages.pool_capacity();
  auto array = [&](auto*& pointer, std::size_t count) {
    using U = std::remove_reference_t<decltype(*pointer)>;
    pointer = static_cast<U*>(allocate(count * sizeof(U)));
  };
  for (PathPool<T>* pool_of : {&view.current, &view.next}) {
    PathPool<T>& pool = *pool_of;
    array(pool.origin, capacity);
    array(pool.direction, capacity);
    array(pool.time, capacity);
    array(pool.radiance, capacity);
    array(pool.throughput, capacity);
    array(pool.bounce, capacity);
    array(pool.item, capacity);
  }
  array(view.hit_t, capacity);
  array(view.hit_b1, capacity);
  array(view.hit_b2, capacity);
  array(view.hit_primitive, capacity);
  array(view.escaped, capacity);
  for (u32 m = 0; m < kMaterialClasses; ++m) array(view.material_queue[m], capacity);
  array(view.counters, kWavefrontCounters);
  view.pixels = stages.pixels();
  array(view.results, static_cast<std::size_t>(stages.pixels()) * stages.samples_per_batch());
}

// Adds samples [first_sample, first_sample + sample_count) of every pixel to the film.
void run_wavefront(WavefrontStages& stages, u32 first_sample, u32 sample_count);

}  // namespace pt
