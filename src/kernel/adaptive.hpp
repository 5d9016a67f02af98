// Adaptive sampling's judgement of a pixel (film/adaptive.hpp says when and why): one definition for the host and
// every device, so that a device judges its film where it lies, without sending it to the host.
#pragma once

#include "kernel/integrator.hpp"
#include "kernel/platform.hpp"

namespace pt {

// Pixels are judged by their error averaged over the (2 * kAdaptiveWindowRadius + 1)^2 pixels around them: one
// pixel's two half means say little, and a region stops only where all of it looks clean.
inline constexpr u32 kAdaptiveWindowRadius = 2;

// A mean brightness as a display shows it, on a 0..1 scale: clamped to white and raised to the power 1/2, close to
// the sRGB curve (whose exponent is 1/2.4 above its linear toe). A square root is exactly rounded everywhere, so
// the host and every device agree on it.
PT_HD inline double displayed_brightness(double linear) { return ::sqrt(linear < 0 ? 0.0 : linear > 1 ? 1.0 : linear); }

// The squared error of a pixel's displayed mean, estimated from its two halves: for independent halves A and B of
// its samples, |A - B| / 2 = |mean - A| estimates the standard error of the mean. Brightness is the mean of the
// three channels. A stopped pixel's sums are as they were when it stopped: its error is the one it stopped with.
PT_HD inline double displayed_squared_error(const FilmPixel& p, u32 samples_done) {
  const u32 given = p.stopped_at != 0 ? p.stopped_at : samples_done;
  const double odd_samples = static_cast<double>(given / 2);
  if (p.samples == 0 || odd_samples == 0) return 0.0;
  // Non-finite samples left out are too rare to move the estimate: the halves are taken as equal in size.
  const double mean = (p.r + p.g + p.b) / (3.0 * p.samples);
  const double odd_mean = static_cast<double>(p.odd_brightness) / (3.0 * odd_samples);
  const double error = displayed_brightness(mean) - displayed_brightness(odd_mean);
  return error * error;
}

// The error of pixel (x, y) as adaptive sampling judges it: the root mean square of the displayed errors of the
// window's pixels (those inside the image), always summed in the same order.
PT_HD inline double adaptive_error(const FilmPixel* film, u32 width, u32 height, u32 x, u32 y, u32 samples_done) {
  const u32 x0 = x >= kAdaptiveWindowRadius ? x - kAdaptiveWindowRadius : 0, y0 = y >= kAdaptiveWindowRadius ? y - kAdaptiveWindowRadius : 0;
  const u32 x1 = x + kAdaptiveWindowRadius < width ? x + kAdaptiveWindowRadius : width - 1;
  const u32 y1 = y + kAdaptiveWindowRadius < height ? y + kAdaptiveWindowRadius : height - 1;
  double sum = 0;
  for (u32 j = y0; j <= y1; ++j)
    for (u32 i = x0; i <= x1; ++i) sum += displayed_squared_error(film[static_cast<std::size_t>(j) * width + i], samples_done);
  return ::sqrt(sum / static_cast<double>((x1 - x0 + 1) * (y1 - y0 + 1)));
}

// Judges every pixel still taking samples after `samples_done` samples: `stops[i]` becomes samples_done where the
// pixel's error is below `threshold`, else 0 (and the pixel is counted in *taking). The film is only read here
// (every pixel's window reads its neighbours); AdaptiveApply then marks the stops in it.
struct AdaptiveJudge {
  const FilmPixel* film;
  u32* stops;
  u32* taking;
  u32 width, height, samples_done;
  double threshold;
  PT_HD void operator()(u32 i) const {
    u32 stop = 0;
    if (film[i].stopped_at == 0) {
      if (adaptive_error(film, width, height, i % width, i / width, samples_done) < threshold)
        stop = samples_done;
      else
        queue_push(taking);
    }
    stops[i] = stop;
  }
};

struct AdaptiveApply {
  FilmPixel* film;
  const u32* stops;
  PT_HD void operator()(u32 i) const {
    if (stops[i] != 0) film[i].stopped_at = stops[i];
  }
};

}  // namespace pt
