// The bidirectional integrator on any device: for each sample, one launch over the image that traces a light subpath
// and a camera subpath per pixel (kernel/bidirectional.hpp) and one that folds that sample's splats into the film.
#pragma once

#include <cstddef>
#include <string>

#include "integrators/device.hpp"
#include "kernel/bidirectional.hpp"

namespace pt {

template <Device D, class T>
class BidirectionalIntegrator {
 public:
  BidirectionalIntegrator(D& device, const SceneView<T>& scene, FilmPixel* film) : device_(device), scene_(scene), film_(film) {
    if (scene.params.max_depth > kMaxBidirectionalDepth)
      throw BackendError("bdpt traces paths of at most " + std::to_string(kMaxBidirectionalDepth) + " bounces; this render asks for " +
                         std::to_string(scene.params.max_depth) + " (--depth)");
    const std::size_t bytes = 3 * sizeof(u64) * static_cast<std::size_t>(scene.params.width) * scene.params.height;
    splats_ = static_cast<u64*>(memory_.allocate(bytes, "allocating the splat sums"));
    device_.clear(splats_, bytes, "clearing the splat sums");
  }

  // Adds samples [first_sample, first_sample + sample_count) of every pixel to the film, light tracing's splats
  // included, each sample's after its own contributions.
  void render(u32 first_sample, u32 sample_count) {
    const u32 width = scene_.params.width, height = scene_.params.height;
    const typename D::Timer timer = device_.start_timer();
    for (u32 s = first_sample; s < first_sample + sample_count; ++s) {
      device_.launch_image("launching the bidirectional kernel", width, height, BidirectionalSample<T>{scene_, film_, SplatFilm{splats_, width}, s});
      device_.launch("folding the splats", width * height, FoldSplats{film_, splats_});
    }
    device_.stop_timer(timer, &seconds_);
    device_.synchronise("running the bidirectional kernel");
  }

  double seconds() const { return seconds_; }

 private:
  D& device_;
  SceneView<T> scene_;
  FilmPixel* film_;
  DeviceAllocations<D> memory_{device_};
  u64* splats_ = nullptr;
  double seconds_ = 0;
};

}  // namespace pt
