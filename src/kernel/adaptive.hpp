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

// The variance of one sample of a pixel, as displayed, estimated from two parts of its n samples (stopped pixels: n
// as given when they stopped): the first Q, Q the largest power of two below n, and the n - Q after them. Their means
// A and B differ by noise of variance sigma^2 (1 / Q + 1 / (n - Q)), which gives sigma^2. Brightness is the mean of
// the three channels. A stopped pixel's sums are as they were when it stopped; its variance per sample is still what
// it was, whatever its count.
PT_HD inline double displayed_sample_variance(const FilmPixel& p, u32 samples_done) {
  const u32 given = p.stopped_at != 0 ? p.stopped_at : samples_done;
  if (p.samples == 0 || given < 2) return 0.0;
  // Non-finite samples left out are too rare to move the estimate: the parts' counts are taken from sample numbers.
  const u32 first = first_samples_below(given), rest = given - first;
  const double first_mean = static_cast<double>(p.first_brightness) / (3.0 * first);
  const double rest_mean = (p.r + p.g + p.b - static_cast<double>(p.first_brightness)) / (3.0 * rest);
  const double difference = displayed_brightness(first_mean) - displayed_brightness(rest_mean);
  return difference * difference / (1.0 / first + 1.0 / rest);
}

// The error of pixel (x, y)'s displayed mean as adaptive sampling judges it: the variance per sample averaged over
// the window's pixels (those inside the image; always summed in the same order), over the samples the pixel has been
// given (counted by sample numbers, as the parts of displayed_sample_variance are). The
// window's neighbours lend their variance, not their error: a neighbour that stopped early keeps its error, and
// counted as an error it would hold the pixels around it above the threshold however many samples they took.
PT_HD inline double adaptive_error(const FilmPixel* film, u32 width, u32 height, u32 x, u32 y, u32 samples_done) {
  const u32 x0 = x >= kAdaptiveWindowRadius ? x - kAdaptiveWindowRadius : 0, y0 = y >= kAdaptiveWindowRadius ? y - kAdaptiveWindowRadius : 0;
  const u32 x1 = x + kAdaptiveWindowRadius < width ? x + kAdaptiveWindowRadius : width - 1;
  const u32 y1 = y + kAdaptiveWindowRadius < height ? y + kAdaptiveWindowRadius : height - 1;
  double sum = 0;
  for (u32 j = y0; j <= y1; ++j)
    for (u32 i = x0; i <= x1; ++i) sum += displayed_sample_variance(film[static_cast<std::size_t>(j) * width + i], samples_done);
  if (samples_done == 0) return 0.0;
  return ::sqrt(sum / (static_cast<double>((x1 - x0 + 1) * (y1 - y0 + 1)) * static_cast<double>(samples_done)));
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
