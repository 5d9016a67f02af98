// The path-tracing integrator (the seed's Algorithm 1, corrected): one camera sample of one pixel, and the
// accumulation of a range of samples into a film pixel. Every backend calls these.
#pragma once

#include "kernel/scene_view.hpp"

namespace pt {

template <class T>
struct SampleResult {
  Color<T> radiance;
  u32 rays;  // closest-hit queries made by this sample
};

template <class T>
PT_HD inline SampleResult<T> trace_sample(const SceneView<T>& scene, u32 x, u32 y, u32 sample) {
  const RenderParams<T>& params = scene.params;
  const SampleRandom random = SampleRandom::make(params.seed, y * params.width + x, sample);
  Ray<T> ray = camera_ray(scene.camera, params, x, y, random);
  Color<T> radiance{};
  Color<T> throughput = Color<T>::splat(T(1));
  u32 bounce = 0;
  for (; bounce < params.max_depth; ++bounce) {
    const IntersectContext<T> context{scene.boundaries, &random, bounce};
    Hit<T> hit{};
    if (!closest_hit(scene, ray, context, hit)) {
      radiance += throughput * background_radiance(scene.background, ray.direction);
      ++bounce;
      break;
    }
    const Primitive<T>& primitive = scene.primitives[hit.primitive];
    const Material<T>& material = scene.materials[primitive.material];
    const bool needs_uv = material_needs_uv(material, scene.textures);
    const SurfacePoint<T> at = describe_hit(primitive, scene.triangle_attributes, ray, hit, needs_uv);
    // Emission counts with the throughput of the path that reached it (the seed dropped this factor).
    radiance += throughput * material_emitted(material, at, scene.textures, scene.texture_data);
    Scatter<T> scatter;
    const BounceRandom bounce_random{&random, bounce};
    if (!material_scatter(material, ray, at, scene.textures, scene.texture_data, bounce_random, scatter)) {
      ++bounce;
      break;
    }
    throughput *= scatter.attenuation;
    ray = scatter.ray;
    if (params.roulette_depth > 0 && bounce + 1 >= params.roulette_depth) {
      // Continue with probability q and divide by q: unbiased, and dark paths stop early.
      const T q = min(max_component(throughput), constant<T>(0.95));
      if (!(bounce_random.template uniform<T>(kDimRoulette) < q)) {
        ++bounce;
        break;
      }
      throughput = throughput / q;
    }
  }
  return SampleResult<T>{radiance, bounce};
}

// One pixel of the film: the sum of its finite samples (in double, so long renders lose no precision),
// how many there were, and how many rays they cost. Non-finite samples are left out and counted by the host
// as requested minus accumulated.
struct FilmPixel {
  double r, g, b;
  u32 samples;
  u32 rays;
};

// Adds samples [first_sample, first_sample + sample_count) of pixel (x, y). Samples are always added in
// increasing order, so the sum does not depend on how a render is split into passes, launches or threads.
template <class T>
PT_HD inline void accumulate_pixel(const SceneView<T>& scene, u32 x, u32 y, u32 first_sample, u32 sample_count, FilmPixel& pixel) {
  FilmPixel sum = pixel;
  for (u32 s = first_sample; s < first_sample + sample_count; ++s) {
    const SampleResult<T> result = trace_sample(scene, x, y, s);
    sum.rays += result.rays;
    if (!is_finite(result.radiance)) continue;
    sum.r += static_cast<double>(result.radiance.x);
    sum.g += static_cast<double>(result.radiance.y);
    sum.b += static_cast<double>(result.radiance.z);
    ++sum.samples;
  }
  pixel = sum;
}

}  // namespace pt
