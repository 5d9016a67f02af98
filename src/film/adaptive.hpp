// Adaptive sampling: pixels whose estimated relative error has fallen below a threshold stop taking samples. The
// pixels are judged at fixed sample counts, from the film alone, so the image does not depend on passes, threads,
// devices or processes, and a render resumed from a saved film goes on exactly as it would have.
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "kernel/integrator.hpp"

namespace pt {

// The first sample count at which pixels are judged: fewer samples say too little about a pixel's error.
inline constexpr u32 kAdaptiveFirstJudgement = 16;

// Pixels are judged by their error averaged over the square of (2 * kAdaptiveWindowRadius + 1)^2 pixels around
// them: one pixel's two half means say little, and a region stops only where all of it looks clean.
inline constexpr u32 kAdaptiveWindowRadius = 2;

// Below this brightness (r + g + b of the mean, about 0.001 a channel) the error is measured against it instead:
// near-black pixels would otherwise never count as clean.
inline constexpr double kAdaptiveBrightnessFloor = 3e-3;

// The sample counts at which pixels are judged: 16, 20, 24, 28, 32, 40, 48, 56, 64, 80, ... (four a doubling,
// so that a pixel takes at most a quarter more samples than it needed). The first one after `done`.
u32 next_judgement(u32 done);
bool is_judgement(u32 samples);

// Each pixel's estimated relative error after `samples_done` samples: the mean of its odd-numbered samples
// against the mean of all estimates the standard error of the mean (for independent halves A and B of the
// samples, |A - B| / 2 = |mean - A|), squared and averaged over the window, against the window's brightness.
// A pixel already stopped has the error it was stopped with (its sums have not changed since).
std::vector<float> relative_errors(std::span<const FilmPixel> film, u32 width, u32 height, u32 samples_done);

// Stops every pixel still taking samples whose relative error after `samples_done` samples is below `threshold`
// (its stopped_at becomes samples_done); returns how many pixels take samples still.
std::size_t stop_clean_pixels(std::span<FilmPixel> film, u32 width, u32 height, u32 samples_done, double threshold);

// The number of pixels of `film` still taking samples.
std::size_t pixels_taking_samples(std::span<const FilmPixel> film);

}  // namespace pt
