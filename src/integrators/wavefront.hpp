// The wavefront integrator on any device: its path pool and queues in device memory, and its schedule (generate,
// intersect, escaped, shade per material class, compact; then accumulate), batch after batch, with the pool refilled
// from the batch's remaining work items. Each stage is one launch over its queue; the shadow rays a shade stage
// queues are traced in the next intersect launch.
#pragma once

#include <algorithm>
#include <array>
#include <string>
#include <utility>
#include <vector>

#include "integrators/device.hpp"
#include "kernel/wavefront.hpp"

namespace pt {

// Stage names, in the order the per-stage times are reported.
inline constexpr std::array<const char*, 5> kWavefrontStageNames{"generate", "intersect", "escaped", "shade", "accumulate"};

// Paths in flight: a GPU needs about a million to fill its threads; a CPU a pool that stays near its caches.
inline constexpr u32 kGpuWavefrontPool = 1u << 20;
inline constexpr u32 kHostWavefrontPool = 1u << 16;

// Samples per batch so that a batch holds several pools' worth of paths (the pool drains at the end of every
// batch; with batches of many pools' worth that tail is paid rarely), at most `most`: for the whole image, 64, so
// that the result buffer stays bounded; for the pixels adaptive sampling leaves taking samples, as many as that
// buffer holds (at 64 a pass over a few thousand pixels was cut into batches, each paying the pool's drain).
inline u32 wavefront_samples_per_batch(u32 pixels, u32 pool_capacity, u64 most = 64) {
  const u64 wanted_items = 32ull * pool_capacity;
  return static_cast<u32>(std::clamp<u64>((wanted_items + pixels - 1) / pixels, 1, std::max<u64>(most, 1)));
}

template <Device D, class T>
class WavefrontIntegrator {
 public:
  WavefrontIntegrator(D& device, const SceneView<T>& scene, FilmPixel* film)
      : device_(device),
        memory_(device),
        scene_(scene),
        film_(film),
        pool_capacity_(device.host() ? kHostWavefrontPool : kGpuWavefrontPool),
        samples_per_batch_(wavefront_samples_per_batch(pixels(), pool_capacity_)) {
    work_items_ = static_cast<std::size_t>(pixels()) * samples_per_batch_;
    view_.for_each_array(pool_capacity_, work_items_, [&](auto*& array, std::size_t entries) {
      using Entry = std::remove_reference_t<decltype(*array)>;
      array = static_cast<Entry*>(memory_.allocate(entries * sizeof(Entry), "allocating the wavefront path pool"));
    });
    view_.pixels = pixels();
    active_list_ = static_cast<u32*>(memory_.allocate(static_cast<std::size_t>(pixels()) * sizeof(u32), "allocating the list of pixels taking samples"));
    device_.clear(view_.counters, kWavefrontCounters * sizeof(u32), "clearing the wavefront queues");
  }

  // Adds samples [first_sample, first_sample + sample_count) of every pixel to the film.
  void render(u32 first_sample, u32 sample_count) { render_rows(0, scene_.params.height, film_, first_sample, sample_count); }

  // The same for rows [first_row, first_row + row_count) of the image only, into `film`, which holds those rows. A
  // band takes more samples a batch than the whole image, as many as the results allocated for the image hold.
  void render_rows(u32 first_row, u32 row_count, FilmPixel* film, u32 first_sample, u32 sample_count) {
    const u32 band_pixels = scene_.params.width * row_count;
    view_.first_pixel = scene_.params.width * first_row;
    // Only the pixels adaptive sampling has not stopped become work items; where none is stopped, the list is left
    // out (one load less in every stage).
    stage(kGenerate, band_pixels, WavefrontActivePixels{film, active_list_, view_.counters + kCounterNextPaths});
    const u32 active = take_counters()[kCounterNextPaths];
    if (active == 0) return;
    view_.pixels = active;
    view_.active_pixels = active < band_pixels ? active_list_ : nullptr;
    const u32 samples_per_batch = wavefront_samples_per_batch(active, pool_capacity_, work_items_ / active);
    for (u32 batch_first = first_sample; batch_first < first_sample + sample_count; batch_first += samples_per_batch) {
      const u32 batch_samples = std::min(samples_per_batch, first_sample + sample_count - batch_first);
      const u32 items = active * batch_samples;
      view_.first_sample = batch_first;
      u32 next_item = 0, live = 0, shadows = 0;
      while (next_item < items || live > 0 || shadows > 0) {
        const u32 fresh = std::min(pool_capacity_ - live, items - next_item);
        if (fresh > 0) {
          stage(kGenerate, fresh, WavefrontGenerate<T>{scene_, view_, live, next_item});
          next_item += fresh;
          live += fresh;
        }
        if (shadows > 0)
          stage(kIntersect, live + shadows, WavefrontIntersectAndShadow<T>{scene_, view_, live});
        else
          stage(kIntersect, live, WavefrontIntersect<T>{scene_, view_});
        const std::array<u32, kWavefrontCounters> queued = take_counters();
        stage(kEscaped, queued[kCounterEscaped], WavefrontEscaped<T>{scene_, view_});
        for (u32 m = 0; m < kMaterialClasses; ++m) stage(kShade, queued[kCounterFirstMaterial + m], WavefrontShade<T>{scene_, view_, m});
        const std::array<u32, kWavefrontCounters> shaded = take_counters();
        shadows = shaded[kCounterShadow];
        live = shaded[kCounterNextPaths];
        view_.swap_pools();
      }
      stage(kAccumulate, active, WavefrontAccumulate<T>{view_, film, batch_samples});
    }
    device_.synchronise("running the wavefront stages");
  }

  // Seconds spent in each stage so far, named in kWavefrontStageNames order.
  std::vector<std::pair<std::string, double>> stage_seconds() const {
    std::vector<std::pair<std::string, double>> out;
    for (std::size_t i = 0; i < kWavefrontStageNames.size(); ++i) out.emplace_back(kWavefrontStageNames[i], seconds_[i]);
    return out;
  }
  double seconds() const {
    double total = 0;
    for (double s : seconds_) total += s;
    return total;
  }

 private:
  enum Stage { kGenerate, kIntersect, kEscaped, kShade, kAccumulate };
  static constexpr std::array<const char*, 5> kLaunching{"launching the generate stage", "launching the intersect stage",
                                                         "launching the escaped stage", "launching the shade stage",
                                                         "launching the accumulate stage"};

  u32 pixels() const { return scene_.params.width * scene_.params.height; }

  template <class Kernel>
  void stage(Stage which, u32 count, const Kernel& kernel) {
    if (count == 0) return;
    const typename D::Timer timer = device_.start_timer();
    device_.launch(kLaunching[which], count, kernel);
    device_.stop_timer(timer, &seconds_[which]);
  }

  // Reads the queue counters and sets them to zero (the host waits here: it needs the queue lengths).
  std::array<u32, kWavefrontCounters> take_counters() {
    std::array<u32, kWavefrontCounters> values{};
    device_.copy_to_host(values.data(), view_.counters, sizeof(values), "reading the wavefront queues");
    device_.clear(view_.counters, sizeof(values), "clearing the wavefront queues");
    return values;
  }

  D& device_;
  DeviceAllocations<D> memory_;
  SceneView<T> scene_;
  FilmPixel* film_;
  u32 pool_capacity_, samples_per_batch_;  // the batch's samples for the whole image
  u32* active_list_ = nullptr;             // the pixels taking samples (WavefrontActivePixels)
  std::size_t work_items_ = 0;             // results allocated: the whole image's batch
  WavefrontView<T> view_{};
  std::array<double, kWavefrontStageNames.size()> seconds_{};
};

}  // namespace pt
