// The wavefront integrator's schedule, shared by every backend: which stage runs over how many queue entries,
// batch after batch, with the path pool refilled from the batch's remaining work items.
#pragma once

#include <array>
#include <string>
#include <utility>
#include <vector>

#include "kernel/wavefront.hpp"

namespace pt {

// Stage names, in the order the per-stage times are reported.
inline constexpr std::array<const char*, 5> kWavefrontStageNames{"generate", "intersect", "escaped", "shade", "accumulate"};

// What a backend provides: each call runs one stage over a whole queue, adding its time to seconds_.
class WavefrontStages {
 public:
  virtual ~WavefrontStages() = default;
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
};


// Adds samples [first_sample, first_sample + sample_count) of every pixel to the film.
void run_wavefront(WavefrontStages& stages, u32 pixels, u32 pool_capacity, u32 samples_per_batch, u32 first_sample, u32 sample_count);

// Samples per batch so that a batch holds several pools' worth of paths (keeps the pool full) but its result
// buffer stays bounded.
u32 wavefront_samples_per_batch(u32 pixels, u32 pool_capacity);

}  // namespace pt
