// Adaptive sampling's schedule and its judgement of each pixel's error.
#include "film/adaptive.hpp"

#include <algorithm>
#include <bit>

namespace pt {

namespace {

// The spacing of judgements around `samples`: a quarter of the power of two at or below it.
u32 judgement_step(u32 samples) { return std::max(kAdaptiveFirstJudgement / 4, std::bit_floor(samples) / 4); }

}  // namespace

u32 next_judgement(u32 done) {
  if (done < kAdaptiveFirstJudgement) return kAdaptiveFirstJudgement;
  const u32 step = judgement_step(done);
  const u64 next = (static_cast<u64>(done) / step + 1) * step;
  return static_cast<u32>(std::min<u64>(next, 0xffffffffu));
}

bool is_judgement(u32 samples) { return samples >= kAdaptiveFirstJudgement && samples % judgement_step(samples) == 0; }

std::vector<float> adaptive_errors(std::span<const FilmPixel> film, u32 width, u32 height, u32 samples_done) {
  std::vector<float> errors(film.size());
  for (u32 y = 0; y < height; ++y)
    for (u32 x = 0; x < width; ++x)
      errors[static_cast<std::size_t>(y) * width + x] = static_cast<float>(adaptive_error(film.data(), width, height, x, y, samples_done));
  return errors;
}

std::size_t pixels_taking_samples(std::span<const FilmPixel> film) {
  return static_cast<std::size_t>(std::count_if(film.begin(), film.end(), [](const FilmPixel& p) { return p.stopped_at == 0; }));
}

}  // namespace pt
