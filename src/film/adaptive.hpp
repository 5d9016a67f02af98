// Adaptive sampling: pixels whose estimated error, as a display shows them, has fallen below a threshold stop taking
// samples. The pixels are judged at fixed sample counts, from the film alone (kernel/adaptive.hpp), so the image
// does not depend on passes, threads, devices or processes, and a render resumed from a saved film goes on exactly
// as it would have.
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "kernel/adaptive.hpp"

namespace pt {

// The first sample count at which pixels are judged: fewer samples say too little about a pixel's error.
inline constexpr u32 kAdaptiveFirstJudgement = 16;

// The sample counts at which pixels are judged: 16, 20, 24, 28, 32, 40, 48, 56, 64, 80, ... (four a doubling,
// so that a pixel takes at most a quarter more samples than it needed). The first one after `done`.
u32 next_judgement(u32 done);
bool is_judgement(u32 samples);

// Each pixel's error as adaptive sampling judges it after `samples_done` samples (kernel/adaptive.hpp).
std::vector<float> adaptive_errors(std::span<const FilmPixel> film, u32 width, u32 height, u32 samples_done);

// The number of pixels of `film` still taking samples.
std::size_t pixels_taking_samples(std::span<const FilmPixel> film);

}  // namespace pt
