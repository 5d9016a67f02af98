// The wavefront schedule: generate, intersect, escaped, shade per material class, compact; then accumulate.
#include "backends/wavefront_schedule.hpp"

#include <algorithm>

namespace pt {

u32 wavefront_samples_per_batch(u32 pixels, u32 pool_capacity) {
  // The pool drains at the end of every batch; with batches of many pools' worth that tail is paid rarely.
  const u64 wanted_items = 32ull * pool_capacity;
  return static_cast<u32>(std::clamp<u64>((wanted_items + pixels - 1) / pixels, 1, 64));
}

void run_wavefront(WavefrontStages& stages, u32 first_sample, u32 sample_count) {
  const u32 pixels = stages.pixels(), pool_capacity = stages.pool_capacity(), samples_per_batch = stages.samples_per_batch();
  for (u32 batch_first = first_sample; batch_first < first_sample + sample_count; batch_first += samples_per_batch) {
    const u32 batch_samples = std::min(samples_per_batch, first_sample + sample_count - batch_first);
    const u32 items = pixels * batch_samples;
    stages.begin_batch(batch_first, batch_samples);
    u32 next_item = 0, live = 0;
    while (next_item < items || live > 0) {
      const u32 fresh = std::min(pool_capacity - live, items - next_item);
      if (fresh > 0) {
        stages.generate(live, fresh, next_item);
        next_item += fresh;
        live += fresh;
      }
      stages.intersect(live);
      const std::array<u32, kWavefrontCounters> queued = stages.take_counters();
      stages.escaped(queued[kCounterEscaped]);
      for (u32 m = 0; m < kMaterialClasses; ++m) stages.shade(m, queued[kCounterFirstMaterial + m]);
      live = stages.take_counters()[kCounterNextPaths];
      stages.swap_pools();
    }
    stages.accumulate(batch_samples);
  }
}

}  // namespace pt
