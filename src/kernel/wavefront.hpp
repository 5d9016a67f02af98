// Wavefront path tracing: the integrator split into stages, each a function of one queue entry that every backend
// runs over a whole queue (a kernel launch, a parallel loop). Paths live in a fixed pool stored structure-of-arrays;
// hits are queued by material class, so that each shading launch runs one material's code. Every stage calls the
// same path steps as the megakernel (start_path, closest_hit, path_escaped, path_shade), and random numbers are
// keyed by (pixel, sample, bounce, dimension), so both integrators compute the same samples.
#pragma once

#include <variant>

#include "kernel/integrator.hpp"

namespace pt {

inline constexpr u32 kMaterialClasses = static_cast<u32>(std::variant_size_v<Material<float>>);

// Queue counters: the paths that continue, the paths that escaped, and one queue per material class.
enum WavefrontCounter : u32 { kCounterNextPaths = 0, kCounterEscaped = 1, kCounterFirstMaterial = 2 };
inline constexpr u32 kWavefrontCounters = kCounterFirstMaterial + kMaterialClasses;

// A pool of paths, structure-of-arrays. `item` names the work item (pixel and sample) the path belongs to.
template <class T>
struct PathPool {
  Vec3<T>* origin;
  Vec3<T>* direction;
  T* time;
  Color<T>* radiance;
  Color<T>* throughput;
  u32* bounce;
  u32* item;

  PT_HD PathState<T> load(u32 i) const { return PathState<T>{Ray<T>{origin[i], direction[i], time[i]}, radiance[i], throughput[i], bounce[i]}; }
  PT_HD void store(u32 i, const PathState<T>& path, u32 work_item) const {
    origin[i] = path.ray.origin;
    direction[i] = path.ray.direction;
    time[i] = path.ray.time;
    radiance[i] = path.radiance;
    throughput[i] = path.throughput;
    bounce[i] = path.bounce;
    item[i] = work_item;
  }
};

// Bytes of one path in a pool, and all it costs: two pools (current and next), its hit, and a slot in the
// escaped queue and in every material queue.
template <class T>
inline constexpr u32 kPathPoolBytes = 2 * sizeof(Vec3<T>) + sizeof(T) + 2 * sizeof(Color<T>) + 2 * sizeof(u32);
template <class T>
inline constexpr u32 kWavefrontBytesPerPath = 2 * kPathPoolBytes<T> + 3 * sizeof(T) + sizeof(u32) + (1 + kMaterialClasses) * sizeof(u32);

// Work items of a batch are sample-major: item = (sample - first_sample) * pixels + pixel.
template <class T>
struct WavefrontView {
  PathPool<T> current, next;
  T* hit_t;
  T* hit_b1;
  T* hit_b2;
  u32* hit_primitive;
  u32* escaped;
  u32* material_queue[kMaterialClasses];
  u32* counters;             // kWavefrontCounters entries
  SampleResult<T>* results;  // one per work item of the batch
  u32 first_sample;
  u32 pixels;

  PT_HD u32 pixel_of(u32 item) const { return item % pixels; }
  // The paths that go on were written to `next`; they become the current ones (host side, between bounces).
  void swap_pools() {
    const PathPool<T> done = current;
    current = next;
    next = done;
  }
  PT_HD u32 sample_of(u32 item) const { return first_sample + item / pixels; }
};

template <class T>
PT_HD inline SampleRandom wavefront_random(const SceneView<T>& scene, const WavefrontView<T>& w, u32 item) {
  return path_random(scene.params, w.pixel_of(item), w.sample_of(item));
}

template <class T>
PT_HD inline void wavefront_finish(const WavefrontView<T>& w, const PathState<T>& path, u32 item) {
  w.results[item] = SampleResult<T>{path.radiance, path.bounce};
}

// Stage 1: a new camera path for work item `item`, in slot `slot` of the current pool.
template <class T>
PT_HD inline void wavefront_generate(const SceneView<T>& scene, const WavefrontView<T>& w, u32 slot, u32 item) {
  const u32 pixel = w.pixel_of(item);
  const SampleRandom random = wavefront_random(scene, w, item);
  w.current.store(slot, start_path(scene, pixel % scene.params.width, pixel / scene.params.width, random), item);
}

// Stage 2: the closest hit of the path in `slot` (media sample their free-flight distance here, as primitives);
// the path joins its material's queue or the escaped queue.
template <class T>
PT_HD inline void wavefront_intersect(const SceneView<T>& scene, const WavefrontView<T>& w, u32 slot) {
  const PathState<T> path = w.current.load(slot);
  const SampleRandom random = wavefront_random(scene, w, w.current.item[slot]);
  Hit<T> hit{};
  if (closest_hit(scene, path.ray, IntersectContext<T>{scene.boundaries, &random, path.bounce}, hit)) {
    w.hit_t[slot] = hit.t;
    w.hit_b1[slot] = hit.b1;
    w.hit_b2[slot] = hit.b2;
    w.hit_primitive[slot] = hit.primitive;
    const u32 material_class = hit_material_class(scene, hit);
    w.material_queue[material_class][queue_push(w.counters + kCounterFirstMaterial + material_class)] = slot;
  } else {
    w.escaped[queue_push(w.counters + kCounterEscaped)] = slot;
  }
}

// Stage 3: escaped paths gather the background and end.
template <class T>
PT_HD inline void wavefront_escaped(const SceneView<T>& scene, const WavefrontView<T>& w, u32 queue_index) {
  const u32 slot = w.escaped[queue_index];
  PathState<T> path = w.current.load(slot);
  path_escaped(scene, path);
  wavefront_finish(w, path, w.current.item[slot]);
}

// Stage 4, once per material class: shade and scatter; paths that go on are compacted into the next pool.
template <class T>
PT_HD inline void wavefront_shade(const SceneView<T>& scene, const WavefrontView<T>& w, u32 material_class, u32 queue_index) {
  const u32 slot = w.material_queue[material_class][queue_index];
  PathState<T> path = w.current.load(slot);
  const u32 item = w.current.item[slot];
  const SampleRandom random = wavefront_random(scene, w, item);
  const Hit<T> hit{w.hit_t[slot], w.hit_b1[slot], w.hit_b2[slot], w.hit_primitive[slot]};
  if (path_shade(scene, path, hit, random) && path.bounce < scene.params.max_depth)
    w.next.store(queue_push(w.counters + kCounterNextPaths), path, item);
  else
    wavefront_finish(w, path, item);
}

// Stage 5, once per batch: each pixel adds its samples in sample order, exactly as the megakernel does.
template <class T>
PT_HD inline void wavefront_accumulate(const WavefrontView<T>& w, FilmPixel* film, u32 pixel, u32 sample_count) {
  FilmPixel sum = film[pixel];
  for (u32 s = 0; s < sample_count; ++s) add_sample(sum, w.results[s * w.pixels + pixel]);
  film[pixel] = sum;
}

}  // namespace pt
