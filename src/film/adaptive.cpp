// Adaptive sampling's schedule and its judgement of each pixel's error.
#include "film/adaptive.hpp"

#include <algorithm>
#include <bit>
#include <cmath>

namespace pt {

namespace {

// The spacing of judgements around `samples`: a quarter of the power of two at or below it.
u32 judgement_step(u32 samples) { return std::max(kAdaptiveFirstJudgement / 4, std::bit_floor(samples) / 4); }

// Box filter of radius kAdaptiveWindowRadius over a width x height array, clamped at the borders (each output the
// mean of the window's pixels inside the image), as two passes of running sums.
std::vector<double> window_means(const std::vector<double>& values, u32 width, u32 height) {
  const int r = static_cast<int>(kAdaptiveWindowRadius);
  std::vector<double> rows(values.size()), out(values.size());
  for (u32 y = 0; y < height; ++y)
    for (int x = 0; x < static_cast<int>(width); ++x) {
      double sum = 0;
      const int lo = std::max(0, x - r), hi = std::min(static_cast<int>(width) - 1, x + r);
      for (int i = lo; i <= hi; ++i) sum += values[static_cast<std::size_t>(y) * width + i];
      rows[static_cast<std::size_t>(y) * width + x] = sum / (hi - lo + 1);
    }
  for (int y = 0; y < static_cast<int>(height); ++y)
    for (u32 x = 0; x < width; ++x) {
      double sum = 0;
      const int lo = std::max(0, y - r), hi = std::min(static_cast<int>(height) - 1, y + r);
      for (int j = lo; j <= hi; ++j) sum += rows[static_cast<std::size_t>(j) * width + x];
      out[static_cast<std::size_t>(y) * width + x] = sum / (hi - lo + 1);
    }
  return out;
}

}  // namespace

u32 next_judgement(u32 done) {
  if (done < kAdaptiveFirstJudgement) return kAdaptiveFirstJudgement;
  const u32 step = judgement_step(done);
  const u64 next = (static_cast<u64>(done) / step + 1) * step;
  return static_cast<u32>(std::min<u64>(next, 0xffffffffu));
}

bool is_judgement(u32 samples) { return samples >= kAdaptiveFirstJudgement && samples % judgement_step(samples) == 0; }

std::vector<float> relative_errors(std::span<const FilmPixel> film, u32 width, u32 height, u32 samples_done) {
  const std::size_t pixels = static_cast<std::size_t>(width) * height;
  std::vector<double> squared_error(pixels), brightness(pixels);
  for (std::size_t i = 0; i < pixels; ++i) {
    // A stopped pixel's sums are as they were when it stopped: its error is the one it was stopped with.
    const FilmPixel& p = film[i];
    const double odd_samples = (p.stopped_at != 0 ? p.stopped_at : samples_done) / 2;
    if (p.samples == 0 || odd_samples == 0) continue;
    // Non-finite samples left out are too rare to move the estimate: the halves are taken as equal in size.
    const double mean = (p.r + p.g + p.b) / p.samples, odd_mean = p.odd_brightness / odd_samples;
    squared_error[i] = (mean - odd_mean) * (mean - odd_mean);
    brightness[i] = mean;
  }
  const std::vector<double> error = window_means(squared_error, width, height), level = window_means(brightness, width, height);
  std::vector<float> relative(pixels);
  for (std::size_t i = 0; i < pixels; ++i)
    relative[i] = static_cast<float>(std::sqrt(error[i]) / std::max(std::abs(level[i]), kAdaptiveBrightnessFloor));
  return relative;
}

std::size_t stop_clean_pixels(std::span<FilmPixel> film, u32 width, u32 height, u32 samples_done, double threshold) {
  const std::vector<float> relative = relative_errors(film, width, height, samples_done);
  std::size_t taking = 0;
  for (std::size_t i = 0; i < film.size(); ++i) {
    if (film[i].stopped_at != 0) continue;
    if (relative[i] < threshold)
      film[i].stopped_at = samples_done;
    else
      ++taking;
  }
  return taking;
}

std::size_t pixels_taking_samples(std::span<const FilmPixel> film) {
  return static_cast<std::size_t>(std::count_if(film.begin(), film.end(), [](const FilmPixel& p) { return p.stopped_at == 0; }));
}

}  // namespace pt
