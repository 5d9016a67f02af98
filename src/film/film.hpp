// The film and the render loop around a backend: passes of samples, progress, statistics, and the final image.
#pragma once

#include <functional>
#include <span>
#include <vector>

#include "backends/backend.hpp"
#include "image/image_io.hpp"

namespace pt {

struct RenderStats {
  double seconds = 0;           // wall time of the rendering passes
  double upload_seconds = 0;    // copying the scene to the backend and clearing its film
  double read_back_seconds = 0; // copying the film back
  double resolve_seconds = 0;   // turning the film into an image
  u64 samples = 0;              // camera samples traced
  u64 rays = 0;                 // closest-hit queries
  u64 dropped_samples = 0;      // non-finite samples left out of their pixel
  u64 saturations = 0;          // fixed-point results clamped to the format's range (0 for float and double)
};

struct Progress {
  u32 samples_done, samples_total;  // per pixel
  double elapsed_seconds;
  double samples_per_second;
};

using ProgressCallback = std::function<void(const Progress&)>;

// The mean of each pixel's finite samples (black where a pixel has none).
LinearImage resolve_film(std::span<const FilmPixel> film, u32 width, u32 height);

// Statistics of a film rendered with `samples_per_pixel` samples per pixel.
RenderStats film_stats(std::span<const FilmPixel> film, u32 samples_per_pixel);

// A finished film on the host. Its pixels are the backend's own memory where that is host memory (valid until
// the backend's next upload or its end), else a copy held here.
struct RenderedFilm {
  std::span<const FilmPixel> on_backend;
  std::vector<FilmPixel> copy;
  u32 width = 0, height = 0;
  RenderStats stats;
  std::span<const FilmPixel> pixels() const { return copy.empty() ? on_backend : std::span<const FilmPixel>(copy); }
};

// The film resolved a band of rows at a time, as the image writers ask for it: the film (32 bytes a pixel) is the
// only full-size buffer while an image is written. Refers to `film`, which must outlive it.
ImageRows film_rows(const RenderedFilm& film);

struct RenderResult {
  LinearImage image;
  RenderStats stats;
};

// Uploads the scene and renders all its samples per pixel, in passes sized to report progress about twice a
// second. The image does not depend on the pass sizes.
template <class T>
RenderedFilm render_film(RenderBackend<T>& backend, const FlatScene<T>& scene, const ProgressCallback& progress = {});

// render_film, resolved into an image.
template <class T>
RenderResult render_scene(RenderBackend<T>& backend, const FlatScene<T>& scene, const ProgressCallback& progress = {});

}  // namespace pt
