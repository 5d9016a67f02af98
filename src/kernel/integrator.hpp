// The path-tracing integrator (the seed's Algorithm 1, corrected): one camera sample of one pixel, and the
// accumulation of a range of samples into a film pixel. Every backend calls these.
#pragma once

#include "kernel/lights.hpp"

namespace pt {

template <class T>
struct SampleResult {
  Color<T> radiance;
  u32 rays;  // closest-hit queries made by this sample
};

// Everything a path carries from one bounce to the next. `bounce` counts the closest-hit queries made so far (its
// shadow rays apart); `scatter_pdf` is the density of the ray's direction, 0 for a camera ray or a specular choice.
template <class T>
struct PathState {
  Ray<T> ray;
  Color<T> radiance;
  Color<T> throughput;
  u32 bounce;
  u32 shadow_rays;
  T scatter_pdf;
};

// A shadow ray of next-event estimation, waiting to be traced: what it adds when it reaches the light of `entry`
// (for a mesh, its `triangle`) unblocked is weight x emitted radiance x the MIS weight over the light's density.
// The media it crosses weigh it by their transmittance and draw no random numbers.
template <class T>
struct ShadowRay {
  Ray<T> ray;
  Color<T> weight;  // the path's throughput times the material's scattering towards the light
  T scatter_pdf;    // the density with which the material would have scattered that way
  T distance;       // how far the ray may look for the light: just beyond the point chosen on it
  T light_pdf;      // the light's density for this direction where sampling gave it, else 0 (light_pdf finds it);
                    // as the format carries it (light_density, kernel/lights.hpp)
  u32 entry;        // kNoLight: none to trace
  u32 triangle;
};

template <class T>
PT_HD inline SampleRandom path_random(const RenderParams<T>& params, u32 pixel, u32 sample) {
  return SampleRandom::make(params.seed, pixel, sample, params.sampler);
}

// A new path: the camera ray of one sample of pixel (x, y).
template <class T>
PT_HD inline PathState<T> start_path(const SceneView<T>& scene, u32 x, u32 y, const SampleRandom& random) {
  return PathState<T>{camera_ray(scene.camera, scene.params.width, scene.params.height, x, y, random), Color<T>{}, Color<T>::splat(T(1)), 0, 0, T(0)};
}

// The weight of light that a scattered ray found: the power heuristic against the density `light_density` (as the
// format carries it) with which light sampling could have found it too, or 1 where the path could not have (a camera
// ray, a specular choice).
template <class T>
PT_HD inline T found_light_weight(const PathState<T>& path, T light_density) {
  return path.scatter_pdf > T(0) ? scattered_light_weight(path.scatter_pdf, light_density) : T(1);
}

// The path left the scene: it gathers the background, and ends.
template <class T>
PT_HD inline void path_escaped(const SceneView<T>& scene, PathState<T>& path) {
  T weight = T(1);
  if (scene.params.next_event && scene.lights.background != kNoLight)
    weight = found_light_weight(path, background_light_density(scene.lights.entries[scene.lights.background].pmf,
                                                               background_pdf(scene.background, path.ray.direction)));
  path.radiance += path.throughput * background_radiance(scene.background, path.ray.direction) * weight;
  ++path.bounce;
}

// The shadow ray that tells whether light sample `light` is seen along `ray` (from the scattering point towards it),
// carrying `weight` (throughput times scattering) and the material's density `scatter_pdf` for that direction.
template <class T>
PT_HD inline ShadowRay<T> shadow_ray_to(const LightSample<T>& light, const Ray<T>& ray, const Color<T>& weight, T scatter_pdf) {
  // A margin of 1/1024 keeps the light itself within reach of the rounded hit distance; only media there (a fog that
  // also fills the light) count for a length they should not, at most that fraction of the way.
  return ShadowRay<T>{ray, weight, scatter_pdf, light.distance + light.distance * constant<T>(1.0 / 1024), light.pdf, light.entry, light.triangle};
}

// Next-event estimation at a scattering point: a light picked, a direction towards it, and the shadow ray that will
// tell whether it is seen (traced by the caller: shadow_contribution). Leaves shadow.entry at kNoLight where there is
// nothing to trace.
template <class T>
PT_HOST_NOINLINE PT_HD void sample_next_event(const SceneView<T>& scene, PathState<T>& path, const Material<T>& material, const SurfacePoint<T>& at,
                                              const BounceRandom& random, ShadowRay<T>& shadow) {
  // Roulette of faint light samples (Cycles' light threshold): a light sample that could add less than the threshold
  // to the sample is kept with probability (that most) / threshold, at least 1/32, and counts 1 / that probability
  // when it is. The expected value is the same; work towards lights too faint or too far away to matter here is mostly
  // saved. Twice: first from a bound known before anything is drawn (a sphere's cone, at a diffuse surface or in a
  // medium), which saves the sample itself (the direction, the material evaluated again, their random numbers: most
  // of what a light sample costs where its shadow ray is short); then, for the samples kept, from what the shadow
  // ray would bring unblocked, wherever sampling knows the light's density and brightness beforehand.
  const T threshold = scene.params.light_threshold;
  const u32 entry = choose_light(scene.lights, random);
  T kept = T(1);
  if constexpr (std::is_floating_point_v<T>) {
    const bool surface = std::holds_alternative<Lambertian<T>>(material);
    if (threshold > T(0) && (surface || std::holds_alternative<Isotropic<T>>(material))) {
      const T reach = light_reach(scene, entry, at.p, path.ray.time, surface ? &at.normal : nullptr);
      if (reach < T(0)) return;  // the light lies wholly below the surface: the material would give it nothing
      const T most = max_component(path.throughput) * reach;
      if (most > T(0) && most < threshold) {
        kept = max(most / threshold, constant<T>(1.0 / 32));
        if (!(random.template uniform<T>(kDimLightRoulette) < kept)) return;
      }
    }
  }
  LightSample<T> light;
  if (!sample_light(scene, entry, at.p, path.ray.time, random, light)) return;
  const ScatterValue<T> value = material_evaluate(material, at, -path.ray.direction, light.direction, scene.textures, scene.texture_data);
  if (!(value.pdf > T(0))) return;
  Color<T> weight = path.throughput * value.value;
  if (kept < T(1)) weight = weight / kept;
  if (threshold > T(0) && light.pdf > T(0) && light.brightest > T(0)) {
    const T most = max_component(weight) * light.brightest * light_sample_weight(light.pdf, value.pdf);
    if (most < threshold) {
      const T keep = max(most / threshold, constant<T>(1.0 / 32));
      if (!(random.template uniform<T>(kDimShadowRoulette) < keep)) return;
      weight = weight / keep;
    }
  }
  shadow = shadow_ray_to(light, spawn_ray(at, light.direction, path.ray.time), weight, value.pdf);
  ++path.shadow_rays;
}

// exp(-optical_depth), the share of light a constant medium lets through; most shadow rays cross no medium and skip
// the exponential (exp(-0) is exactly 1 in every scalar type, so the result is the same).
template <class T>
PT_HD inline T transmittance(T optical_depth) {
  return optical_depth > T(0) ? exp(-optical_depth) : T(1);
}

// A shadow ray towards a point sampled on a quad light that met nothing up to that point has reached the light, even
// where rounding took it just past an edge: at grazing angles a direction off by one step moves the ray's crossing of
// the light's plane far along it, so in fixed point rays aimed near the edges missed the light and the walls next to
// it drew a dark seam (docs/numerics.md). `hit` becomes the light's point nearest that crossing. False for other
// lights (and a ray along the plane): they have no such miss to mend, or none measured.
template <class T>
PT_HD inline bool quad_light_reached(const SceneView<T>& scene, u32 primitive, const Ray<T>& ray, Hit<T>& hit) {
  const auto* q = std::get_if<Quad<T>>(&scene.primitives[primitive].shape);
  if (!q || !intersect_quad<T, true>(*q, ray, T(0), largest<T>(), hit)) return false;
  hit.primitive = primitive;
  hit.triangle = 0;
  return true;
}

// What a shadow ray adds to its path's radiance, given what its closest-hit query found (`blocked`, `hit`, and the
// optical depth of the media it crossed): the light's emission where the ray meets the light it aimed at before
// anything else, times the transmittance of those media (exact for constant media: exp(-density x length inside)),
// weighted by MIS against scattering. A backend that traces the query elsewhere (the rtl backend's engine) calls this.
template <class T>
PT_HD Color<T> shadow_contribution_found(const SceneView<T>& scene, const ShadowRay<T>& shadow, bool blocked, Hit<T> hit, T optical_depth) {
  const LightEntry<T>& light = scene.lights.entries[shadow.entry];
  if (light.primitive == kNoLight) {
    // The density sample_light drew the direction with (the background's is known then): not looked up again.
    const T light_density = shadow.light_pdf;
    // A direction that rounds into a black texel of an environment image has no density there: it carries nothing.
    if (blocked || !(light_density > T(0))) return Color<T>{};
    return shadow.weight * background_radiance(scene.background, shadow.ray.direction) *
           (light_sample_weight(light_density, shadow.scatter_pdf) * transmittance(optical_depth));
  }
  if (!blocked) {
    if (!quad_light_reached(scene, light.primitive, shadow.ray, hit)) return Color<T>{};
  } else if (hit.primitive != light.primitive || hit.triangle != shadow.triangle) {
    return Color<T>{};
  }
  const Primitive<T>& primitive = scene.primitives[hit.primitive];
  const Material<T>& material = scene.materials[material_of_hit(primitive, scene.meshes, hit)];
  const SurfacePoint<T> at =
      describe_hit(primitive, scene.triangle_attributes, scene.meshes, shadow.ray, hit, material_needs_uv(material, scene.textures));
  const T light_density = shadow.light_pdf > T(0) ? shadow.light_pdf : light_pdf(scene, shadow.entry, shadow.ray, hit, at);
  if (!(light_density > T(0))) return Color<T>{};
  return shadow.weight * material_emitted(material, at, scene.textures, scene.texture_data) *
         (light_sample_weight(light_density, shadow.scatter_pdf) * transmittance(optical_depth));
}

// What a shadow ray adds to its path's radiance: its closest-hit query traced here, then shadow_contribution_found.
template <class T>
PT_HOST_NOINLINE PT_HD Color<T> shadow_contribution(const SceneView<T>& scene, const ShadowRay<T>& shadow, const SampleRandom& random) {
  const LightEntry<T>& light = scene.lights.entries[shadow.entry];
  Hit<T> hit{};
  T optical_depth = T(0);
  IntersectContext<T> context{scene.boundaries, &random, 0, &optical_depth};
  if constexpr (std::is_floating_point_v<T>) {
    // The walk stops at the first hit that blocks the ray: any hit for the background; for a shape, a hit on another
    // primitive before the light's point (the light is met at its point, so such a hit is in front of it whatever
    // lies nearer), with a margin of a 1024th of the way, far above either distance's rounding. The answer is the
    // closest hit's; fixed point, whose steps can exceed that margin on short rays, searches for the closest.
    context.light_primitive = light.primitive;
    context.blocked_before = light.primitive == kNoLight ? shadow.distance : shadow.distance - shadow.distance * constant<T>(1.0 / 512);
  }
  const bool blocked = closest_hit(scene, shadow.ray, context, hit, shadow.distance);
  return shadow_contribution_found(scene, shadow, blocked, hit, optical_depth);
}

// The path hit something: it gathers the emission there, picks a light to sample (next-event estimation: the shadow
// ray is left for the caller to trace), and scatters. Returns whether it goes on (with its new ray); either way the
// bounce is counted.
template <class T>
PT_HD inline bool path_shade(const SceneView<T>& scene, PathState<T>& path, const Hit<T>& hit, const SampleRandom& random, ShadowRay<T>& shadow) {
  shadow.entry = kNoLight;
  const u32 bounce = path.bounce++;
  const Primitive<T>& primitive = scene.primitives[hit.primitive];
  const Material<T>& material = scene.materials[material_of_hit(primitive, scene.meshes, hit)];
  const bool needs_uv = material_needs_uv(material, scene.textures);
  const SurfacePoint<T> at =
      describe_hit(primitive, scene.triangle_attributes, scene.meshes, path.ray, hit, needs_uv, material_needs_tangent(material));
  // Emission counts with the throughput of the path that reached it (the seed dropped this factor), weighted against
  // light sampling where that could have found it.
  T weight = T(1);
  if (scene.params.next_event && path.scatter_pdf > T(0)) {
    const u32 entry = scene.lights.primitive_light[hit.primitive];
    if (entry != kNoLight) weight = found_light_weight(path, light_pdf(scene, entry, path.ray, hit, at));
  }
  path.radiance += path.throughput * material_emitted(material, at, scene.textures, scene.texture_data) * weight;
  const BounceRandom bounce_random{&random, bounce};
  if (scene.params.next_event && scene.lights.count > 0 && path.bounce < scene.params.max_depth && material_samples_lights(material))
    sample_next_event(scene, path, material, at, bounce_random, shadow);
  Scatter<T> scatter;
  if (!material_scatter(material, path.ray, at, scene.textures, scene.texture_data, bounce_random, scatter)) return false;
  path.throughput *= scatter.attenuation;
  path.ray = scatter.ray;
  path.scatter_pdf = scatter.pdf;
  const RenderParams<T>& params = scene.params;
  if (params.roulette_depth > 0 && bounce + 1 >= params.roulette_depth) {
    // Continue with probability q and divide by q: unbiased, and dark paths stop early.
    const T q = min(max_component(path.throughput), constant<T>(0.95));
    if (!(bounce_random.template uniform<T>(kDimRoulette) < q)) return false;
    path.throughput = path.throughput / q;
  }
  return true;
}

// The material class (variant index) a hit is shaded with: the wavefront integrator queues hits by it.
template <class T>
PT_HD inline u32 hit_material_class(const SceneView<T>& scene, const Hit<T>& hit) {
  return static_cast<u32>(scene.materials[material_of_hit(scene.primitives[hit.primitive], scene.meshes, hit)].index());
}

// One camera sample of pixel (x, y), traced to the end in one go (the megakernel integrator).
template <class T>
PT_HD inline SampleResult<T> trace_sample(const SceneView<T>& scene, u32 x, u32 y, u32 sample) {
  const SampleRandom random = path_random(scene.params, y * scene.params.width + x, sample);
  PathState<T> path = start_path(scene, x, y, random);
  while (path.bounce < scene.params.max_depth) {
    Hit<T> hit{};
    if (!closest_hit(scene, path.ray, IntersectContext<T>{scene.boundaries, &random, path.bounce}, hit)) {
      path_escaped(scene, path);
      break;
    }
    ShadowRay<T> shadow;
    const bool goes_on = path_shade(scene, path, hit, random, shadow);
    if (shadow.entry != kNoLight) path.radiance += shadow_contribution(scene, shadow, random);
    if (!goes_on) break;
  }
  return SampleResult<T>{path.radiance, path.bounce + path.shadow_rays};
}

// One pixel of the film: the sum of its finite samples (in double, so long renders lose no precision),
// how many there were, and how many rays they cost. Non-finite samples are left out and counted by the host
// as requested minus accumulated. Adaptive sampling (kernel/adaptive.hpp) keeps two more numbers: the brightness
// (r + g + b) summed over the pixel's first Q samples, Q the largest power of two below the number of samples given
// (first_brightness: its mean against that of the samples after them estimates the pixel's error), and the sample
// count at which the pixel was judged clean and stopped (0 while it takes samples). Everything a pixel needs is
// here, so bands sent to other devices or processes and saved films carry it.
struct FilmPixel {
  double r, g, b;
  float first_brightness;
  u32 samples;
  u32 rays;
  u32 stopped_at;
};

// The largest power of two below `count` (count >= 2): the samples whose sum first_brightness keeps.
PT_HD inline u32 first_samples_below(u32 count) {
  u32 v = count - 1;
  v |= v >> 1;
  v |= v >> 2;
  v |= v >> 4;
  v |= v >> 8;
  v |= v >> 16;
  return (v >> 1) + 1;
}

// Adds sample number `sample` to a film pixel; a non-finite sample is left out (and so counted as dropped).
// Brightness is a plain sum of the channels: no product a compiler could fuse differently in two kernels.
// Before a sample whose number is a power of two, the brightness so far becomes first_brightness: the first 2^k
// samples of a pixel are one stratified set (kernel/random.hpp, SamplerKind::kSobol), and the samples after them up
// to any judgement's count (film/adaptive.cpp) are one or two such sets, so the error is judged from means of
// stratified sets, as the image is made of. (Halves taken sample by sample, odd against even, are no such sets:
// their difference measures the variance of independent samples, ten times the stratified mean's in cornell-smoke's
// dark fog.)
template <class T>
PT_HD inline void add_sample(FilmPixel& pixel, const SampleResult<T>& result, u32 sample) {
  if (sample != 0 && (sample & (sample - 1u)) == 0) pixel.first_brightness = static_cast<float>(pixel.r + pixel.g + pixel.b);
  pixel.rays += result.rays;
  if (!is_finite(result.radiance)) return;
  const double r = static_cast<double>(result.radiance.x), g = static_cast<double>(result.radiance.y), b = static_cast<double>(result.radiance.z);
  pixel.r += r;
  pixel.g += g;
  pixel.b += b;
  ++pixel.samples;
}

// Adds samples [first_sample, first_sample + sample_count) of pixel (x, y). Samples are always added in
// increasing order, so the sum does not depend on how a render is split into passes, launches or threads.
template <class T>
PT_HD inline void accumulate_pixel(const SceneView<T>& scene, u32 x, u32 y, u32 first_sample, u32 sample_count, FilmPixel& pixel) {
  if (pixel.stopped_at != 0) return;  // judged clean by adaptive sampling
  FilmPixel sum = pixel;
  for (u32 s = first_sample; s < first_sample + sample_count; ++s) add_sample(sum, trace_sample(scene, x, y, s), s);
  pixel = sum;
}

// The megakernel on host devices, a kernel over a band of the image's rows: samples [first_sample, first_sample +
// sample_count) of pixel (x, first_row + y) added to the band's film, whose first row is the band's (a whole image
// is the band from row 0; several devices each render bands of one image: docs/distributed.md).
template <class T>
struct MegakernelPass {
  SceneView<T> scene;
  FilmPixel* film;
  u32 first_sample, sample_count;
  u32 first_row = 0;
  PT_HD void operator()(u32 x, u32 y) const {
    accumulate_pixel(scene, x, first_row + y, first_sample, sample_count, film[static_cast<std::size_t>(y) * scene.params.width + x]);
  }
};

// The megakernel on GPUs: one sample of pixel (x, y) added to the film, with no loop over samples in the kernel.
// The same sums as MegakernelPass with a count of one. With that loop around the bounce loop and the BVH walk
// (a trip count of one, known only at run time), the code made for NVIDIA GPUs went wrong in rare warps: through
// AdaptiveCpp and LLVM, one warp of book-1's sample 55 at 1200x800 never ended (17 of its 32 lanes, whose paths
// end after 2 to 17 bounces when traced alone); through nvcc, samples after a thread's first came out non-finite
// at a rate near 1e-5 (docs/backends.md, docs/cuda-notes.md).
template <class T>
struct MegakernelSample {
  SceneView<T> scene;
  FilmPixel* film;
  u32 sample;
  u32 first_row = 0;  // of the band, as in MegakernelPass
  PT_HD void operator()(u32 x, u32 y) const {
    FilmPixel& pixel = film[static_cast<std::size_t>(y) * scene.params.width + x];
    if (pixel.stopped_at != 0) return;  // judged clean by adaptive sampling
    FilmPixel sum = pixel;
    add_sample(sum, trace_sample(scene, x, first_row + y, sample), sample);
    pixel = sum;
  }
};

}  // namespace pt
