// The film and the render loop around a backend: passes of samples, progress, statistics, and the final image.
#pragma once

#include <functional>
#include <span>
#include <vector>

#include "backends/backend.hpp"
#include "image/image_io.hpp"

namespace pt {

struct RenderStats {
  double seconds = 0;            // wall time of the rendering passes
  double upload_seconds = 0;     // copying the scene to the backend and clearing its film
  double read_back_seconds = 0;  // copying the film back
  double resolve_seconds = 0;    // turning the film into an image
  u64 samples = 0;               // camera samples traced
  u64 rays = 0;                  // closest-hit queries
  u64 dropped_samples = 0;       // non-finite samples left out of their pixel
  u64 saturations = 0;           // fixed-point results clamped to the format's range (0 for float and double)
};

struct Progress {
  u32 samples_done, samples_total;  // per pixel
  double elapsed_seconds;
  double samples_per_second;
};

using ProgressCallback = std::function<void(const Progress&)>;

// Samples per pixel of the next render pass, so that it takes about `pass_seconds` at the pace so far: `samples`
// took `elapsed` seconds and the last pass had `last`.
// At least 1; at most 4 times the last, so that one fast pass misjudged does not make the next run long; and, under
// a time limit (`time_left` seconds, 0 for none), no more than fit before it.
u32 next_pass_samples(double elapsed, u32 samples, u32 last, double pass_seconds, double time_left = 0);

// How a render may end before all its samples, save its film on the way, and start from a saved one. Everything
// is checked between passes (half a second apart, or a few seconds where a pass sends the film to other processes),
// and a stop also during a pass where the backend can give that pass up: a stop takes effect within about a second.
struct RenderControl {
  std::function<bool()> stop_requested;    // an interrupt: stop after the pass under way, or give it up
  double time_limit_seconds = 0;           // > 0: stop once the passes have taken this long
  double checkpoint_interval_seconds = 0;  // > 0 (with `checkpoint`): save the film about this often
  // Called with the film and its samples per pixel every interval and when the render ends, early or not.
  std::function<void(std::span<const FilmPixel>, u32 samples_done)> checkpoint;
  std::span<const FilmPixel> start_film;  // a resumed render: the film to go on from, holding
  u32 start_samples = 0;                  // this many samples per pixel
  // Someone watching the film converge (the preview page): after every pass where `watching()` says a frame is
  // wanted, `show` is given the film (valid during the call) and the progress. Unwatched, the film stays put.
  std::function<bool()> watching;
  std::function<void(std::span<const FilmPixel>, const Progress&)> show;
  // "Save now": where `save_requested()` says so after a pass, `save_image` is given the film of the samples done
  // (and the checkpoint, where there is one, is saved too); the render goes on.
  std::function<bool()> save_requested;
  std::function<void(std::span<const FilmPixel>, u32 samples_done)> save_image;
};

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
  u32 samples_done = 0;        // per pixel: all of the scene's, or fewer where the render was stopped
  bool stopped_early = false;  // by an interrupt or the time limit
  RenderStats stats;
  std::span<const FilmPixel> pixels() const { return copy.empty() ? on_backend : std::span<const FilmPixel>(copy); }
};

// The film resolved a band of rows at a time, as the image writers ask for it: the film (40 bytes a pixel) is the
// only full-size buffer while an image is written. Refers to `film`, which must outlive it.
ImageRows film_rows(const RenderedFilm& film);
// The same of a film held elsewhere (valid while the rows are read).
ImageRows film_rows(std::span<const FilmPixel> film, u32 width, u32 height);

struct RenderResult {
  LinearImage image;
  RenderStats stats;
};

// Uploads the scene and renders all its samples per pixel, in passes sized to report progress about twice a
// second. The image does not depend on the pass sizes, nor on where a render was stopped and resumed: samples are
// added to each pixel in order.
template <class T>
RenderedFilm render_film(RenderBackend<T>& backend, const FlatScene<T>& scene, const ProgressCallback& progress = {},
                         const RenderControl& control = {});

// render_film, resolved into an image.
template <class T>
RenderResult render_scene(RenderBackend<T>& backend, const FlatScene<T>& scene, const ProgressCallback& progress = {});

}  // namespace pt
