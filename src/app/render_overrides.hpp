// Render settings given on top of a scene file's own: the command line's options and the Python module's
// arguments, applied and checked in one place.
#pragma once

#include <optional>
#include <string>

#include "base/render_settings.hpp"
#include "scene/scene.hpp"

namespace pt {

struct RenderOverrides {
  std::optional<u32> width, height, samples_per_pixel, max_depth, seed;
  std::optional<LightSampling> light_sampling;
  std::optional<SamplerKind> sampler;
  std::optional<double> noise_threshold;
  std::optional<double> light_threshold;
};

// How a front end spells the overrides in its messages: "--width 20" on the command line, "width=20" in Python.
struct OverrideSpelling {
  std::string width, height, samples_per_pixel, max_depth, noise_threshold, light_threshold;
  std::string before_value;
};
inline const OverrideSpelling kCommandLineSpelling{"--width", "--height", "--spp", "--depth", "--noise-threshold", "--light-threshold", " "};

// The scene's render settings with `overrides` applied. Throws InputError, naming the override as `spelling` writes
// it, for a width or height outside 1..kMaxImageSide, samples per pixel outside 1..kMaxSamplesPerPixel, a depth
// outside 1..kMaxDepth, a noise threshold that is not a number in 0..kMaxNoiseThreshold, a light threshold not in
// 0..kMaxLightThreshold, or an image of more than kMaxImagePixels (the scene's own values were checked when it was
// read, so a size too large here comes from the overrides).
RenderSettings apply_overrides(const SceneDescription& scene, const RenderOverrides& overrides, const OverrideSpelling& spelling);

}  // namespace pt
