// The host-side interface every backend (CPU threads, CUDA, SYCL) implements: upload the flat scene, render a
// range of samples into the film it keeps, read the film back.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "base/errors.hpp"
#include "flat/flat_scene.hpp"
#include "integrators/integrator_choice.hpp"
#include "kernel/adaptive.hpp"
#include "kernel/layers.hpp"

namespace pt {

// A device a backend renders on (`index` >= 0: the number --device or --sycl-device takes), or a word about a backend
// that has none here (`index` -1: not built, no driver, no GPU). `pathtracer devices` prints them, one a line.
struct DeviceDescription {
  std::string backend;
  int index = -1;
  std::string name;
};

// Adaptive sampling's judgement of a film held on the host (kernel/adaptive.hpp), pixel by pixel in order: marks the
// clean pixels stopped and returns how many take samples still.
inline std::size_t judge_film_on_host(std::span<FilmPixel> film, u32 width, u32 height, u32 samples_done, double threshold) {
  std::vector<u32> stops(film.size());
  u32 taking = 0;
  const AdaptiveJudge judge{film.data(), stops.data(), &taking, width, height, samples_done, threshold};
  for (u32 i = 0; i < film.size(); ++i) judge(i);
  const AdaptiveApply apply{film.data(), stops.data()};
  for (u32 i = 0; i < film.size(); ++i) apply(i);
  return taking;
}

template <class T>
class RenderBackend {
 public:
  virtual ~RenderBackend() = default;

  // Human-readable description, e.g. "cpu (2 threads)".
  virtual std::string name() const = 0;

  // Copies the scene to wherever the backend renders and clears the film to params.width x params.height. A
  // backend whose memory is the host's (the CPU) reads the scene's own arrays instead: the scene must then stay
  // alive and unchanged until the next upload or the backend's end.
  virtual void upload(const FlatScene<T>& scene) = 0;

  // Adds samples [first_sample, first_sample + sample_count) of every pixel to the film. Samples must be
  // rendered in increasing order across calls; the result does not depend on how they are split into calls.
  virtual void render(u32 first_sample, u32 sample_count) = 0;

  // render(), unless `stop` turns true while it runs: a backend that can give up a pass part-way (one whose bands
  // are rendered by other processes) then returns false with its film as it was before the call. Others render
  // the whole pass and return true.
  virtual bool render_unless(u32 first_sample, u32 sample_count, const std::function<bool()>& stop) {
    (void)stop;
    render(first_sample, sample_count);
    return true;
  }

  // Seconds a render pass should take (film/film.cpp): between passes the render reports progress, saves its film
  // and notices a stop, but where every pass costs a transfer of the film, fewer, longer passes are faster.
  virtual double pass_seconds() const { return 0.5; }

  // Adds samples [first_sample, first_sample + sample_count) of every pixel of rows [first_row, first_row +
  // row_count) to `band`, those rows of a film held by the caller (row-major, the band's first row first): the
  // bands that several devices or processes render of one image (docs/distributed.md). Each pixel gets the same
  // sums as render() gives it. The backend's own film is scratch here: render() and this are not mixed after one
  // upload.
  virtual void render_rows(u32 first_row, u32 row_count, u32 first_sample, u32 sample_count, std::span<FilmPixel> band) = 0;

  // Adds the render layers (kernel/layers.hpp: albedo, normal and distance of what each camera sample meets first)
  // of samples [first_sample, first_sample + sample_count) of every pixel to `layers`, held by the caller
  // (row-major, the whole image), after upload; the film is left as it was. The sums do not depend on how the
  // samples are split into calls, nor on the device.
  virtual void render_layers(u32 first_sample, u32 sample_count, std::span<LayerPixel> layers) = 0;

  // Adaptive sampling (film/adaptive.hpp): judges every pixel of the film (width x height) still taking samples
  // after `samples_done` samples, marks those whose error is below `threshold` stopped, and returns how many take
  // samples still. Where the film is (on a device, or on the host), as judge_film_on_host does.
  virtual std::size_t stop_clean_pixels(u32 width, u32 height, u32 samples_done, double threshold) {
    std::vector<FilmPixel> film;
    read_film(film);
    const std::size_t taking = judge_film_on_host(film, width, height, samples_done, threshold);
    write_film(film);
    return taking;
  }

  // Copies the film to the host (row-major, rows from the top).
  virtual void read_film(std::vector<FilmPixel>& pixels) = 0;

  // Replaces the film (after upload, before render) with one read back earlier: a resumed render goes on from it.
  virtual void write_film(std::span<const FilmPixel> pixels) = 0;

  // The film where the host can read it, valid until the next upload: the backend's own memory where that is host
  // memory (no copy: a large film would otherwise be held twice), else a copy read back into `copy`.
  virtual std::span<const FilmPixel> film_on_host(std::vector<FilmPixel>& copy) {
    read_film(copy);
    return copy;
  }

  // Time the device spent rendering since the last upload, measured on the device (CUDA events) where the
  // backend can; otherwise empty and callers use the wall clock.
  virtual std::optional<double> device_seconds() const { return std::nullopt; }

  // Seconds spent in each stage of the wavefront integrator since the last upload (empty for the megakernel).
  virtual std::vector<std::pair<std::string, double>> stage_seconds() const { return {}; }

  // Fixed-point saturation events since the last upload; 0 where the backend does not count them (GPUs).
  virtual u64 saturations() const { return 0; }

  // Where the work went when several devices or processes render one image: each one's name and the
  // pixel-samples it rendered since the last upload; empty for a single device.
  virtual std::vector<std::pair<std::string, u64>> work_shares() const { return {}; }

  // Lines the backend adds to a render's summary (the rtl backend: what its engine did).
  virtual std::vector<std::string> report() const { return {}; }
};

}  // namespace pt
