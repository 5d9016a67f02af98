// The megakernel integrator on any device: each sample of a pixel traced to the end in one kernel; on a GPU in
// batches sized so that a batch takes about a tenth of a second between synchronisations.
#pragma once

#include <algorithm>

#include "integrators/device.hpp"
#include "kernel/integrator.hpp"

namespace pt {

// Samples for the next synchronised batch of a device backend, so that a batch takes about target_seconds: often
// enough for progress and error reports, rarely enough that a fast device is not left idle between batches.
// `seconds` is what the last batch of `count` samples took; the size at most doubles from one batch to the next.
inline u32 next_batch_samples(double seconds, u32 count, double target_seconds) {
  const double per_sample = seconds / count;
  const double wanted = per_sample > 0 ? target_seconds / per_sample : 2.0 * count;
  return static_cast<u32>(std::clamp(wanted, 1.0, 2.0 * count + 1));
}

template <Device D, class T>
class MegakernelIntegrator {
 public:
  MegakernelIntegrator(D& device, const SceneView<T>& scene, FilmPixel* film) : device_(device), scene_(scene), film_(film) {}

  // Adds samples [first_sample, first_sample + sample_count) of every pixel to the film.
  void render(u32 first_sample, u32 sample_count) { render_rows(0, scene_.params.height, film_, first_sample, sample_count); }

  // The same for rows [first_row, first_row + row_count) of the image only, into `film`, which holds those rows.
  void render_rows(u32 first_row, u32 row_count, FilmPixel* film, u32 first_sample, u32 sample_count) {
    const u32 width = scene_.params.width, height = row_count;
    u32 done = 0;
    while (done < sample_count) {
      // On a GPU, batches of about a tenth of a second between synchronisations, of one sample per launch with a
      // kernel that has no loop over samples (MegakernelSample says what went wrong with one), so each launch
      // starts its warps converged on a fresh sample and stays far below any display watchdog's limit. On the
      // host a launch costs a fork and join of the threads, and a pixel's samples traced back to back share the
      // caches (passes of a sample or two over the whole image were 4 % slower), so one launch takes every
      // sample of the call, each pixel's in order: the same sums either way.
      const bool host = device_.host();
      const u32 count = host ? sample_count - done : std::min(samples_per_batch_, sample_count - done);
      const double before = seconds_;
      const typename D::Timer timer = device_.start_timer();
      if (host) {
        device_.launch_image("launching the render kernel", width, height, MegakernelPass<T>{scene_, film, first_sample + done, count, first_row});
      } else {
        for (u32 s = first_sample + done; s < first_sample + done + count; ++s)
          device_.launch_image("launching the render kernel", width, height, MegakernelSample<T>{scene_, film, s, first_row});
      }
      device_.stop_timer(timer, &seconds_);
      device_.synchronise("running the render kernel");
      done += count;
      samples_per_batch_ = next_batch_samples(seconds_ - before, count, kBatchTargetSeconds);
    }
  }

  // Time spent in render kernels so far.
  double seconds() const { return seconds_; }

 private:
  static constexpr double kBatchTargetSeconds = 0.1;

  D& device_;
  SceneView<T> scene_;
  FilmPixel* film_;
  u32 samples_per_batch_ = 1;
  double seconds_ = 0;
};

}  // namespace pt
