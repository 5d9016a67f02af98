// The render loop and film resolution.
#include "film/film.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <thread>

#include "base/number_formats.hpp"
#include "film/adaptive.hpp"
#include "base/parallel_loop.hpp"

namespace pt {

namespace {

// Rows [first_row, first_row + row_count) of the film as linear RGB, three floats per pixel, into `rgb`.
void resolve_rows(std::span<const FilmPixel> film, u32 width, u32 first_row, u32 row_count, float* rgb) {
  const std::size_t first = static_cast<std::size_t>(first_row) * width, end = first + static_cast<std::size_t>(row_count) * width;
  for (std::size_t i = first; i < end; ++i, rgb += 3) {
    const FilmPixel& p = film[i];
    const double scale = p.samples ? 1.0 / p.samples : 0.0;
    rgb[0] = static_cast<float>(p.r * scale);
    rgb[1] = static_cast<float>(p.g * scale);
    rgb[2] = static_cast<float>(p.b * scale);
  }
}

}  // namespace

LinearImage resolve_film(std::span<const FilmPixel> film, u32 width, u32 height) {
  LinearImage image;
  image.width = width;
  image.height = height;
  image.rgb.resize(static_cast<std::size_t>(width) * height * 3);
  // By rows on every core: large films take tens of milliseconds on one, most of it first touches of new memory.
  ParallelLoop loop(std::max(1u, std::thread::hardware_concurrency()));
  loop.run(height, 8, [&](u32 y) { resolve_rows(film, width, y, 1, image.rgb.data() + static_cast<std::size_t>(y) * width * 3); });
  return image;
}

ImageRows film_rows(std::span<const FilmPixel> film, u32 width, u32 height) {
  return ImageRows{width, height, [film, width](u32 first_row, u32 row_count, float* rgb) { resolve_rows(film, width, first_row, row_count, rgb); }, {}};
}

ImageRows film_rows(const RenderedFilm& film) {
  return ImageRows{film.width,
                   film.height,
                   [&film](u32 first_row, u32 row_count, float* rgb) { resolve_rows(film.pixels(), film.width, first_row, row_count, rgb); },
                   {}};
}

RenderStats film_stats(std::span<const FilmPixel> film, u32 samples_per_pixel) {
  RenderStats stats;
  for (const FilmPixel& p : film) {
    const u32 given = p.stopped_at != 0 ? std::min(p.stopped_at, samples_per_pixel) : samples_per_pixel;  // fewer where adaptive sampling stopped it
    stats.rays += p.rays;
    stats.dropped_samples += given - p.samples;
    stats.samples += given;
  }
  return stats;
}

u32 next_pass_samples(double elapsed, u32 samples, u32 last, double pass_seconds, double time_left) {
  const double per_sample = samples > 0 ? elapsed / samples : 0;
  double wanted = per_sample > 0 ? pass_seconds / per_sample : 2.0 * last;
  if (time_left > 0 && per_sample > 0) wanted = std::min(wanted, time_left / per_sample);
  return static_cast<u32>(std::clamp(wanted, 1.0, std::max(1.0, 4.0 * last)));
}

template <class T>
RenderedFilm render_film(RenderBackend<T>& backend, const FlatScene<T>& scene, const ProgressCallback& progress, const RenderControl& control) {
  using Clock = std::chrono::steady_clock;
  const auto seconds_since = [](Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); };
  const auto upload_start = Clock::now();
  backend.upload(scene);
  const u32 total = scene.samples_per_pixel;
  u32 done = 0;
  if (!control.start_film.empty()) {
    backend.write_film(control.start_film);
    done = std::min(control.start_samples, total);
  }
  const double upload_seconds = seconds_since(upload_start);
  const double pixels = static_cast<double>(scene.params.width) * scene.params.height;
  const auto start = Clock::now();
  auto last_checkpoint = start;
  const u32 first = done;
  u32 pass = 1;
  bool stopped = false;
  const std::function<bool()> stop = control.stop_requested ? control.stop_requested : [] { return false; };
  std::vector<FilmPixel> saved;
  // The film on the host, read from the backend at most once between two passes (a GPU's is copied back), for
  // whichever of the preview, "save now" and the checkpoint want it.
  std::span<const FilmPixel> film_read;
  const auto film_now = [&] {
    if (film_read.empty()) film_read = backend.film_on_host(saved);
    return film_read;
  };
  const auto save = [&] {
    if (!control.checkpoint) return;
    control.checkpoint(film_now(), done);
    last_checkpoint = Clock::now();
  };
  // Adaptive sampling: passes end at the sample counts where pixels are judged, and there the backend marks the
  // clean pixels of its film stopped; the kernels skip stopped pixels.
  const bool adaptive = scene.noise_threshold > 0;
  std::vector<FilmPixel> copy;
  std::size_t taking = adaptive ? pixels_taking_samples(backend.film_on_host(copy)) : static_cast<std::size_t>(pixels);
  u64 traced = 0;  // pixel-samples this run
  while (done < total && taking > 0) {
    // A time limit stops a render only after it has made a pass, so that even a tiny limit leaves an image.
    if (stop() || (control.time_limit_seconds > 0 && done > first && seconds_since(start) >= control.time_limit_seconds)) {
      stopped = true;
      break;
    }
    pass = std::min(pass, total - done);
    if (adaptive) pass = std::min(pass, next_judgement(done) - done);
    // A pass given up on a stop leaves the film as it was before it: the render ends with the samples done.
    film_read = {};
    if (!backend.render_unless(done, pass, stop)) {
      stopped = true;
      break;
    }
    done += pass;
    traced += static_cast<u64>(pass) * taking;
    if (adaptive && is_judgement(done) && done < total)
      taking = backend.stop_clean_pixels(scene.params.width, scene.params.height, done, scene.noise_threshold);
    const double elapsed = std::chrono::duration<double>(Clock::now() - start).count();
    const double rate = elapsed > 0 ? static_cast<double>(traced) / elapsed : 0;
    // Every pixel clean: the render is complete.
    if (taking == 0) done = total;
    const Progress report{done, total, elapsed, rate};
    if (progress) progress(report);
    if (control.watching && control.watching()) control.show(film_now(), report);
    const bool save_now = control.save_requested && control.save_requested();
    if (save_now && done < total) control.save_image(film_now(), done);
    if ((save_now && done < total) ||
        (control.checkpoint_interval_seconds > 0 && done < total && seconds_since(last_checkpoint) >= control.checkpoint_interval_seconds))
      save();
    // Passes of about half a second by default: often enough to report and to stop (mpirun kills ranks 1 s after
    // passing on a SIGTERM, so rank 0 must end its pass, save and write within it), rarely enough to cost nothing.
    // A backend that gives up a pass on a stop may ask for longer ones. (Under adaptive sampling the pace is that of
    // the pixels still taking samples, so passes lengthen as pixels stop.)
    const double pace = traced > 0 ? elapsed * static_cast<double>(taking) * (done - first) / static_cast<double>(traced) : elapsed;
    pass = next_pass_samples(pace, done - first, pass, backend.pass_seconds(),
                             control.time_limit_seconds > 0 ? std::max(control.time_limit_seconds - elapsed, 1e-9) : 0.0);
  }
  if (done > first) save();  // stopped or finished, either can be resumed (a finished render to more samples)
  const double render_seconds = seconds_since(start);
  RenderedFilm film;
  film.samples_done = done;
  film.stopped_early = stopped;
  film.width = scene.params.width;
  film.height = scene.params.height;
  const auto read_start = Clock::now();
  film.on_backend = backend.film_on_host(film.copy);
  if (film.on_backend.data() == film.copy.data()) film.on_backend = {};  // the copy it is
  film.stats = film_stats(film.pixels(), done);
  film.stats.samples = traced;
  film.stats.saturations = backend.saturations();
  film.stats.seconds = render_seconds;
  film.stats.upload_seconds = upload_seconds;
  film.stats.read_back_seconds = seconds_since(read_start);
  return film;
}

template <class T>
RenderResult render_scene(RenderBackend<T>& backend, const FlatScene<T>& scene, const ProgressCallback& progress) {
  const RenderedFilm film = render_film(backend, scene, progress);
  using Clock = std::chrono::steady_clock;
  const auto resolve_start = Clock::now();
  RenderResult result;
  result.image = resolve_film(film.pixels(), film.width, film.height);
  result.stats = film.stats;
  result.stats.resolve_seconds = std::chrono::duration<double>(Clock::now() - resolve_start).count();
  return result;
}

#define PT_INSTANTIATE_RENDER(...)                                                                                                    \
  template RenderedFilm render_film<__VA_ARGS__>(RenderBackend<__VA_ARGS__>&, const FlatScene<__VA_ARGS__>&, const ProgressCallback&, \
                                                 const RenderControl&);                                                               \
  template RenderResult render_scene<__VA_ARGS__>(RenderBackend<__VA_ARGS__>&, const FlatScene<__VA_ARGS__>&, const ProgressCallback&);
PT_FOR_EACH_SCALAR_TYPE(PT_INSTANTIATE_RENDER)

}  // namespace pt
