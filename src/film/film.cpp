// The render loop and film resolution.
#include "film/film.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <thread>

#include "base/number_formats.hpp"
#include "base/parallel_loop.hpp"

namespace pt {

LinearImage resolve_film(const std::vector<FilmPixel>& film, u32 width, u32 height) {
  LinearImage image;
  image.width = width;
  image.height = height;
  image.rgb.resize(static_cast<std::size_t>(width) * height * 3);
  // By rows on every core: large films take tens of milliseconds on one, most of it first touches of new memory.
  ParallelLoop loop(std::max(1u, std::thread::hardware_concurrency()));
  loop.run(height, 8, [&](u32 y) {
    for (std::size_t i = static_cast<std::size_t>(y) * width; i < static_cast<std::size_t>(y + 1) * width; ++i) {
      const FilmPixel& p = film[i];
      const double scale = p.samples ? 1.0 / p.samples : 0.0;
      image.rgb[3 * i + 0] = static_cast<float>(p.r * scale);
      image.rgb[3 * i + 1] = static_cast<float>(p.g * scale);
      image.rgb[3 * i + 2] = static_cast<float>(p.b * scale);
    }
  });
  return image;
}

RenderStats film_stats(const std::vector<FilmPixel>& film, u32 samples_per_pixel) {
  RenderStats stats;
  for (const FilmPixel& p : film) {
    stats.rays += p.rays;
    stats.dropped_samples += samples_per_pixel - p.samples;
  }
  stats.samples = static_cast<u64>(film.size()) * samples_per_pixel;
  return stats;
}

template <class T>
RenderResult render_scene(RenderBackend<T>& backend, const FlatScene<T>& scene, const ProgressCallback& progress) {
  using Clock = std::chrono::steady_clock;
  const auto seconds_since = [](Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); };
  const auto upload_start = Clock::now();
  backend.upload(scene);
  const double upload_seconds = seconds_since(upload_start);
  const u32 total = scene.samples_per_pixel;
  const double pixels = static_cast<double>(scene.params.width) * scene.params.height;
  const auto start = Clock::now();
  u32 done = 0, pass = 1;
  while (done < total) {
    pass = std::min(pass, total - done);
    backend.render(done, pass);
    done += pass;
    const double elapsed = std::chrono::duration<double>(Clock::now() - start).count();
    const double rate = elapsed > 0 ? done * pixels / elapsed : 0;
    if (progress) progress(Progress{done, total, elapsed, rate});
    // Aim for passes of about half a second: often enough to report, rarely enough to cost nothing.
    const double per_sample = elapsed / done;
    const double wanted = per_sample > 0 ? 0.5 / per_sample : 2.0 * pass;
    pass = static_cast<u32>(std::clamp(wanted, 1.0, std::max(1.0, 4.0 * pass)));
  }
  const double render_seconds = seconds_since(start);
  RenderResult result;
  std::vector<FilmPixel> film;
  const auto read_start = Clock::now();
  backend.read_film(film);
  const double read_back_seconds = seconds_since(read_start);
  const auto resolve_start = Clock::now();
  result.stats = film_stats(film, total);
  result.stats.saturations = backend.saturations();
  result.image = resolve_film(film, scene.params.width, scene.params.height);
  result.stats.seconds = render_seconds;
  result.stats.upload_seconds = upload_seconds;
  result.stats.read_back_seconds = read_back_seconds;
  result.stats.resolve_seconds = seconds_since(resolve_start);
  return result;
}

#define PT_INSTANTIATE_RENDER(...) \
  template RenderResult render_scene<__VA_ARGS__>(RenderBackend<__VA_ARGS__>&, const FlatScene<__VA_ARGS__>&, const ProgressCallback&);
PT_FOR_EACH_SCALAR_TYPE(PT_INSTANTIATE_RENDER)

}  // namespace pt
