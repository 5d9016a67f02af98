// The CPU backend: tiles of 8x8 pixels scheduled by oneTBB's work-stealing scheduler. Each pixel is rendered by
// exactly one task, so the image is bitwise the same for any number of threads.
#include "backends/cpu/cpu_backend.hpp"

#include <atomic>

#include <fmt/format.h>
#include <tbb/blocked_range2d.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "flat/number_formats.hpp"

namespace pt {

namespace {

template <class T>
class CpuBackend final : public RenderBackend<T> {
 public:
  explicit CpuBackend(unsigned threads)
      : threads_(threads == 0 ? static_cast<unsigned>(tbb::this_task_arena::max_concurrency()) : threads),
        arena_(static_cast<int>(threads_)) {}

  std::string name() const override { return fmt::format("cpu ({} thread{})", threads_, threads_ == 1 ? "" : "s"); }

  void upload(const FlatScene<T>& scene) override {
    scene_ = scene;
    film_.assign(static_cast<std::size_t>(scene.params.width) * scene.params.height, FilmPixel{});
    saturations_ = 0;
  }

  void render(u32 first_sample, u32 sample_count) override {
    const SceneView<T> view = scene_.view();
    const u32 width = scene_.params.width, height = scene_.params.height;
    FilmPixel* film = film_.data();
    arena_.execute([&] {
      tbb::parallel_for(tbb::blocked_range2d<u32>(0, height, 8, 0, width, 8), [&](const tbb::blocked_range2d<u32>& tile) {
        // Kernels count saturations per thread; a tile adds what its thread counted while rendering it.
        [[maybe_unused]] u64 before = 0;
        if constexpr (is_fixed_v<T>) before = fixed_saturations_this_thread();
        for (u32 y = tile.rows().begin(); y < tile.rows().end(); ++y)
          for (u32 x = tile.cols().begin(); x < tile.cols().end(); ++x)
            accumulate_pixel(view, x, y, first_sample, sample_count, film[static_cast<std::size_t>(y) * width + x]);
        if constexpr (is_fixed_v<T>) saturations_.fetch_add(fixed_saturations_this_thread() - before, std::memory_order_relaxed);
      });
    });
  }

  void read_film(std::vector<FilmPixel>& pixels) override { pixels = film_; }

  u64 saturations() const override { return saturations_.load(std::memory_order_relaxed); }

 private:
  unsigned threads_;
  tbb::task_arena arena_;
  FlatScene<T> scene_;
  std::vector<FilmPixel> film_;
  std::atomic<u64> saturations_{0};
};

}  // namespace

template <class T>
std::unique_ptr<RenderBackend<T>> make_cpu_backend(unsigned threads) {
  return std::make_unique<CpuBackend<T>>(threads);
}

template std::unique_ptr<RenderBackend<float>> make_cpu_backend<float>(unsigned);
template std::unique_ptr<RenderBackend<double>> make_cpu_backend<double>(unsigned);
#define PT_INSTANTIATE_FIXED_CPU_BACKEND(I, F) template std::unique_ptr<RenderBackend<Fixed<I, F>>> make_cpu_backend<Fixed<I, F>>(unsigned);
PT_FOR_EACH_FIXED_FORMAT(PT_INSTANTIATE_FIXED_CPU_BACKEND)

}  // namespace pt
