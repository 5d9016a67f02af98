// What a render is asked for besides the scene: image size, samples, path depth, seed. A scene file gives them,
// the command line overrides them, and flattening hands them to the kernels.
#pragma once

#include <optional>
#include <string_view>

#include "kernel/random.hpp"

namespace pt {

// How paths find lights: next-event estimation (a shadow ray towards a light chosen at every diffuse bounce,
// combined with the scattered direction by multiple importance sampling), only by scattering into them, or the
// default, next-event estimation of the lights where it pays: every emitting shape, and the background only where
// its radiance varies so much that scattering alone would find it noisily (flat/flat_scene.hpp,
// background_scattering_variance and kBackgroundSamplingVariance); a smooth sky is left to scattering, which
// samples it as well at no shadow ray's cost.
enum class LightSampling : u32 { kNone = 0, kNextEvent = 1, kAuto = 2 };

// How bidirectional path tracing is scheduled on a device: each sample in one kernel, or in stages over bands of rows
// with the connections a launch of their own (integrators/bidirectional.hpp); auto takes the stages on GPUs, where they
// are the faster, and one kernel on the host. Both make the same image bit for bit.
enum class BidirectionalSchedule : u32 { kAuto = 0, kOneKernel = 1, kStaged = 2 };

struct RenderSettings {
  u32 width = 800;
  u32 height = 480;
  u32 samples_per_pixel = 100;
  u32 max_depth = 50;
  u32 seed = 1;
  u32 roulette_depth = 3;  // as pbrt, Mitsuba and Cycles do: long paths of little weight cost most of the time
  LightSampling light_sampling = LightSampling::kAuto;
  SamplerKind sampler = SamplerKind::kSobol;
  // Adaptive sampling (film/adaptive.hpp): a pixel whose estimated error, as displayed on a 0..1 scale, falls
  // below this stops taking samples; 0 gives every pixel all its samples.
  double noise_threshold = 0;
  // Light samples that could add less than this to a sample are taken by chance, counted by the inverse of that chance
  // (kernel/integrator.hpp, sample_next_event); 0 takes every one. Radiance of 1 is white on the display.
  double light_threshold = 0.01;
  BidirectionalSchedule bidirectional_schedule = BidirectionalSchedule::kAuto;
  // Vertex merging's first radius in the scene's units (integrator vcm); 0: chosen from the camera and the image's
  // height (flat/flatten.cpp, default_merge_radius).
  double merge_radius = 0;
};

// The largest light threshold taken: more would trace nearly no shadow ray of a white light.
inline constexpr double kMaxLightThreshold = 1.0;

// The largest noise threshold taken: an error of the whole display range.
inline constexpr double kMaxNoiseThreshold = 1.0;

inline const char* sampler_name(SamplerKind kind) { return kind == SamplerKind::kSobol ? "sobol" : "independent"; }

inline const char* light_sampling_name(LightSampling sampling) {
  return sampling == LightSampling::kNone ? "none" : sampling == LightSampling::kNextEvent ? "nee" : "auto";
}

// The schedule's name as the command line spells it.
inline const char* bidirectional_schedule_name(BidirectionalSchedule schedule) {
  return schedule == BidirectionalSchedule::kOneKernel ? "one-kernel" : schedule == BidirectionalSchedule::kStaged ? "staged" : "auto";
}

// The schedule of a name (auto, one-kernel, staged), or nothing for another text.
inline std::optional<BidirectionalSchedule> parse_bidirectional_schedule(std::string_view name) {
  for (const BidirectionalSchedule s : {BidirectionalSchedule::kAuto, BidirectionalSchedule::kOneKernel, BidirectionalSchedule::kStaged})
    if (name == bidirectional_schedule_name(s)) return s;
  return std::nullopt;
}

// The light sampling of a name (auto, nee, none), or nothing for another text.
inline std::optional<LightSampling> parse_light_sampling(std::string_view name) {
  for (const LightSampling s : {LightSampling::kAuto, LightSampling::kNextEvent, LightSampling::kNone})
    if (name == light_sampling_name(s)) return s;
  return std::nullopt;
}

}  // namespace pt
