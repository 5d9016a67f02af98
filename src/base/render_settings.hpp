// What a render is asked for besides the scene: image size, samples, path depth, seed. A scene file gives them,
// the command line overrides them, and flattening hands them to the kernels.
#pragma once

#include "kernel/random.hpp"

namespace pt {

// How paths find lights: next-event estimation (a shadow ray towards a light chosen at every diffuse bounce,
// combined with the scattered direction by multiple importance sampling), or only by scattering into them.
enum class LightSampling : u32 { kNone = 0, kNextEvent = 1 };

struct RenderSettings {
  u32 width = 800;
  u32 height = 480;
  u32 samples_per_pixel = 100;
  u32 max_depth = 50;
  u32 seed = 1;
  u32 roulette_depth = 3;  // as pbrt, Mitsuba and Cycles do: long paths of little weight cost most of the time
  LightSampling light_sampling = LightSampling::kNextEvent;
  SamplerKind sampler = SamplerKind::kSobol;
  // Adaptive sampling (film/adaptive.hpp): a pixel whose estimated error, as displayed on a 0..1 scale, falls
  // below this stops taking samples; 0 gives every pixel all its samples.
  double noise_threshold = 0;
};

// The largest noise threshold taken: an error of the whole display range.
inline constexpr double kMaxNoiseThreshold = 1.0;

inline const char* sampler_name(SamplerKind kind) { return kind == SamplerKind::kSobol ? "sobol" : "independent"; }

}  // namespace pt
