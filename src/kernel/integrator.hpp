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

// Everything a path carries from one bounce to the next. `bounce` counts the closest-hit queries made so far.
template <class T>
struct PathState {
  Ray<T> ray;
  Color<T> radiance;
  Color<T> throughput;
  u32 bounce;
};

template <class T>
PT_HD inline SampleRandom path_random(const RenderParams<T>& params, u32 pixel, u32 sample) {
  return SampleRandom::make(params.seed, pixel, sample);
}

// A new path: the camera ray of one sample of pixel (x, y).
template <class T>
PT_HD inline PathState<T> start_path(const SceneView<T>& scene, u32 x, u32 y, const SampleRandom& random) {
  return PathState<T>{camera_ray(scene.camera, scene.params.width, scene.params.height, x, y, random), Color<T>{}, Color<T>::splat(T(1)), 0};
}

// The path left the scene: it gathers the background, and ends.
template <class T>
PT_HD inline void path_escaped(const SceneView<T>& scene, PathState<T>& path) {
  path.radiance += path.throughput * background_radiance(scene.background, path.ray.direction);
  ++path.bounce;
}

// The path hit something: it gathers the emission there and scatters. Returns whether it goes on (with its new
// ray); either way the bounce is counted.
template <class T>
PT_HD inline bool path_shade(const SceneView<T>& scene, PathState<T>& path, const Hit<T>& hit, const SampleRandom& random) {
  const u32 bounce = path.bounce++;
  const Primitive<T>& primitive = scene.primitives[hit.primitive];
  const Material<T>& material = scene.materials[material_of_hit(primitive, scene.meshes, hit)];
  const bool needs_uv = material_needs_uv(material, scene.textures);
  const SurfacePoint<T> at = describe_hit(primitive, scene.triangle_attributes, scene.meshes, path.ray, hit, needs_uv);
  // Emission counts with the throughput of the path that reached it (the seed dropped this factor).
  path.radiance += path.throughput * material_emitted(material, at, scene.textures, scene.texture_data);
  Scatter<T> scatter;
  const BounceRandom bounce_random{&random, bounce};
  if (!material_scatter(material, path.ray, at, scene.textures, scene.texture_data, bounce_random, scatter)) return false;
  path.throughput *= scatter.attenuation;
  path.ray = scatter.ray;
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
    if (!path_shade(scene, path, hit, random)) break;
  }
  return SampleResult<T>{path.radiance, path.bounce};
}

// One pixel of the film: the sum of its finite samples (in double, so long renders lose no precision),
// how many there were, and how many rays they cost. Non-finite samples are left out and counted by the host
// as requested minus accumulated.
struct FilmPixel {
  double r, g, b;
  u32 samples;
  u32 rays;
};

// Adds one sample to a film pixel; a non-finite sample is left out (and so counted as dropped).
template <class T>
PT_HD inline void add_sample(FilmPixel& pixel, const SampleResult<T>& result) {
  pixel.rays += result.rays;
  if (!is_finite(result.radiance)) return;
  pixel.r += static_cast<double>(result.radiance.x);
  pixel.g += static_cast<double>(result.radiance.y);
  pixel.b += static_cast<double>(result.radiance.z);
  ++pixel.samples;
}

// Adds samples [first_sample, first_sample + sample_count) of pixel (x, y). Samples are always added in
// increasing order, so the sum does not depend on how a render is split into passes, launches or threads.
template <class T>
PT_HD inline void accumulate_pixel(const SceneView<T>& scene, u32 x, u32 y, u32 first_sample, u32 sample_count, FilmPixel& pixel) {
  FilmPixel sum = pixel;
  for (u32 s = first_sample; s < first_sample + sample_count; ++s) add_sample(sum, trace_sample(scene, x, y, s));
  pixel = sum;
}

// The megakernel on host devices, a kernel over the image: samples [first_sample, first_sample + sample_count) of
// pixel (x, y) added to the film.
template <class T>
struct MegakernelPass {
  SceneView<T> scene;
  FilmPixel* film;
  u32 first_sample, sample_count;
  PT_HD void operator()(u32 x, u32 y) const {
    accumulate_pixel(scene, x, y, first_sample, sample_count, film[static_cast<std::size_t>(y) * scene.params.width + x]);
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
  PT_HD void operator()(u32 x, u32 y) const {
    FilmPixel& pixel = film[static_cast<std::size_t>(y) * scene.params.width + x];
    FilmPixel sum = pixel;
    add_sample(sum, trace_sample(scene, x, y, sample));
    pixel = sum;
  }
};

}  // namespace pt
