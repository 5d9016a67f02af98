// Render settings given on top of a scene file's own (render_overrides.hpp).
#include "app/render_overrides.hpp"

#include <fmt/format.h>

#include "app/image_size.hpp"
#include "base/errors.hpp"
#include "loading/scene_loader.hpp"

namespace pt {
namespace {

std::string spelled(const OverrideSpelling& spelling, const std::string& name, u32 value) {
  return name + spelling.before_value + std::to_string(value);
}

void check_range(const OverrideSpelling& spelling, const std::optional<u32>& value, const std::string& name, u32 most) {
  if (value && (*value < 1 || *value > most)) throw InputError(fmt::format("{}: not in 1..{}", spelled(spelling, name, *value), most));
}

}  // namespace

RenderSettings apply_overrides(const SceneDescription& scene, const RenderOverrides& overrides, const OverrideSpelling& spelling) {
  check_range(spelling, overrides.width, spelling.width, kMaxImageSide);
  check_range(spelling, overrides.height, spelling.height, kMaxImageSide);
  check_range(spelling, overrides.samples_per_pixel, spelling.samples_per_pixel, kMaxSamplesPerPixel);
  check_range(spelling, overrides.max_depth, spelling.max_depth, kMaxDepth);
  if (overrides.noise_threshold && !(*overrides.noise_threshold >= 0 && *overrides.noise_threshold <= kMaxNoiseThreshold))
    throw InputError(fmt::format("{}{}{}: not an error in 0..{} (0: every pixel takes all its samples)", spelling.noise_threshold,
                                 spelling.before_value, *overrides.noise_threshold, kMaxNoiseThreshold));
  if (overrides.light_threshold && !(*overrides.light_threshold >= 0 && *overrides.light_threshold <= kMaxLightThreshold))
    throw InputError(fmt::format("{}{}{}: not a radiance in 0..{} (0: every shadow ray is traced)", spelling.light_threshold, spelling.before_value,
                                 *overrides.light_threshold, kMaxLightThreshold));
  RenderSettings settings = scene.render;
  if (overrides.light_threshold) settings.light_threshold = *overrides.light_threshold;
  if (overrides.noise_threshold) settings.noise_threshold = *overrides.noise_threshold;
  if (overrides.width) settings.width = *overrides.width;
  if (overrides.height) settings.height = *overrides.height;
  if (overrides.samples_per_pixel) settings.samples_per_pixel = *overrides.samples_per_pixel;
  if (overrides.max_depth) settings.max_depth = *overrides.max_depth;
  if (overrides.seed) settings.seed = *overrides.seed;
  if (overrides.light_sampling) settings.light_sampling = *overrides.light_sampling;
  if (overrides.sampler) settings.sampler = *overrides.sampler;
  if (overrides.width && overrides.height)
    check_image_size(settings.width, settings.height,
                     spelled(spelling, spelling.width, settings.width) + " " + spelled(spelling, spelling.height, settings.height));
  else if (overrides.width)
    check_image_size(
        settings.width, settings.height,
        fmt::format("{} with the scene's height {} ({})", spelled(spelling, spelling.width, settings.width), settings.height, scene.source));
  else if (overrides.height)
    check_image_size(
        settings.width, settings.height,
        fmt::format("{} with the scene's width {} ({})", spelled(spelling, spelling.height, settings.height), settings.width, scene.source));
  return settings;
}

}  // namespace pt
