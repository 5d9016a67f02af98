// The CPU backend: the megakernel over tiles of 8x8 pixels scheduled by oneTBB's work-stealing scheduler (each
// pixel rendered by exactly one task, so the image is bitwise the same for any number of threads), or the
// wavefront stages as parallel loops over their queues. Each scalar type is instantiated in a source file of its
// own (cpu_backend_*.cpp): GCC spends its inlining budget per translation unit, and with the fixed-point formats in
// the same unit it stopped inlining the float kernels' shading functions (5 % slower renders).
#pragma once

#include "backends/cpu/cpu_backend.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <memory>
#include <vector>

#include <fmt/format.h>
#include <tbb/task_arena.h>

#include "backends/cpu/parallel_loop.hpp"
#include "backends/wavefront_schedule.hpp"
#include "flat/number_formats.hpp"

namespace pt {

namespace cpu_detail {

template <class T>
class CpuWavefrontStages final : public WavefrontStages {
 public:
  CpuWavefrontStages(ParallelLoop& loop, const SceneView<T>& scene, FilmPixel* film)
      : WavefrontStages(scene.params.width * scene.params.height, kHostWavefrontPool), loop_(loop), scene_(scene), film_(film) {
    // The same layout as on a GPU, in host memory; make_unique zeroes it, counters included.
    allocate_wavefront(*this, view_, [&](std::size_t bytes) -> void* { return memory_.emplace_back(std::make_unique<std::byte[]>(bytes)).get(); });
  }

  void begin_batch(u32 first_sample, u32) override { view_.first_sample = first_sample; }
  void generate(u32 first_slot, u32 count, u32 first_item) override {
    timed(0, count, [&](u32 i) { wavefront_generate(scene_, view_, first_slot + i, first_item + i); });
  }
  void intersect(u32 count) override { timed(1, count, [&](u32 i) { wavefront_intersect(scene_, view_, i); }); }
  void escaped(u32 count) override { timed(2, count, [&](u32 i) { wavefront_escaped(scene_, view_, i); }); }
  void shade(u32 material_class, u32 count) override {
    timed(3, count, [&](u32 i) { wavefront_shade(scene_, view_, material_class, i); });
  }
  void accumulate(u32 sample_count) override {
    timed(4, view_.pixels, [&](u32 pixel) { wavefront_accumulate(view_, film_, pixel, sample_count); });
  }
  std::array<u32, kWavefrontCounters> take_counters() override {
    std::array<u32, kWavefrontCounters> values;
    std::copy_n(view_.counters, kWavefrontCounters, values.begin());
    std::fill_n(view_.counters, kWavefrontCounters, 0u);
    return values;
  }
  void swap_pools() override { view_.swap_pools(); }

 private:
  template <class F>
  void timed(int stage, u32 count, const F& body) {
    const auto start = std::chrono::steady_clock::now();
    loop_.run(count, 256, body);
    seconds_[stage] += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }

  ParallelLoop& loop_;
  const SceneView<T>& scene_;
  FilmPixel* film_;
  std::vector<std::unique_ptr<std::byte[]>> memory_;  // every array of view_
  WavefrontView<T> view_{};
};

template <class T>
class CpuBackend final : public RenderBackend<T> {
 public:
  CpuBackend(unsigned threads, Integrator integrator)
      : threads_(threads == 0 ? static_cast<unsigned>(tbb::this_task_arena::max_concurrency()) : threads),
        integrator_(integrator),
        loop_(threads_) {}

  std::string name() const override {
    return fmt::format("cpu ({} thread{}, {})", threads_, threads_ == 1 ? "" : "s",
                       integrator_ == Integrator::kWavefront ? "wavefront" : "megakernel");
  }

  void upload(const FlatScene<T>& scene) override {
    scene_ = scene;
    view_ = scene_.view();
    film_.assign(static_cast<std::size_t>(scene.params.width) * scene.params.height, FilmPixel{});
    saturations_ = 0;
    wavefront_.reset();
    if (integrator_ == Integrator::kWavefront) {
      wavefront_ = std::make_unique<CpuWavefrontStages<T>>(loop_, view_, film_.data());
    }
  }

  std::vector<std::pair<std::string, double>> stage_seconds() const override {
    return wavefront_ ? wavefront_->stage_seconds() : std::vector<std::pair<std::string, double>>{};
  }

  void render(u32 first_sample, u32 sample_count) override {
    if (wavefront_) {
      run_wavefront(*wavefront_, first_sample, sample_count);
      return;
    }
    const SceneView<T> view = view_;
    const u32 width = scene_.params.width, height = scene_.params.height;
    FilmPixel* film = film_.data();
    // 8x8 tiles: each pixel belongs to one tile, rendered by one thread, in sample order.
    const u32 tiles_x = (width + kTile - 1) / kTile, tiles_y = (height + kTile - 1) / kTile;
    loop_.run(tiles_x * tiles_y, 1, [&](u32 tile) {
      const u32 x0 = (tile % tiles_x) * kTile, y0 = (tile / tiles_x) * kTile;
      // Kernels count saturations per thread; a tile adds what its thread counted while rendering it.
      [[maybe_unused]] u64 before = 0;
      if constexpr (is_fixed_v<T>) before = fixed_saturations_this_thread();
      for (u32 y = y0; y < std::min(height, y0 + kTile); ++y)
        for (u32 x = x0; x < std::min(width, x0 + kTile); ++x)
          accumulate_pixel(view, x, y, first_sample, sample_count, film[static_cast<std::size_t>(y) * width + x]);
      if constexpr (is_fixed_v<T>) saturations_.fetch_add(fixed_saturations_this_thread() - before, std::memory_order_relaxed);
    });
  }

  void read_film(std::vector<FilmPixel>& pixels) override { pixels = film_; }

  u64 saturations() const override { return saturations_.load(std::memory_order_relaxed); }

 private:
  unsigned threads_;
  Integrator integrator_;
  static constexpr u32 kTile = 8;
  ParallelLoop loop_;
  FlatScene<T> scene_;
  SceneView<T> view_{};
  std::vector<FilmPixel> film_;
  std::unique_ptr<CpuWavefrontStages<T>> wavefront_;
  std::atomic<u64> saturations_{0};
};

}  // namespace cpu_detail

template <class T>
std::unique_ptr<RenderBackend<T>> make_cpu_backend(unsigned threads, Integrator integrator) {
  return std::make_unique<cpu_detail::CpuBackend<T>>(threads, integrator);
}

}  // namespace pt
