// Wavefront path tracing: the integrator split into stages, each a function of one queue entry that every backend
// runs over a whole queue (a kernel launch, a parallel loop). Paths live in a fixed pool stored structure-of-arrays;
// hits are queued by material class, so that each shading launch runs one material's code. Every stage calls the
// same path steps as the megakernel (start_path, closest_hit, path_escaped, path_shade), and random numbers are
// keyed by (pixel, sample, bounce, dimension), so both integrators compute the same samples.
#pragma once

#include <cstddef>
#include <variant>

#include "kernel/integrator.hpp"

namespace pt {

inline constexpr u32 kMaterialClasses = static_cast<u32>(std::variant_size_v<Material<float>>);

// Queue counters: the paths that continue, the paths that escaped, the shadow rays, and one queue per material class.
enum WavefrontCounter : u32 { kCounterNextPaths = 0, kCounterEscaped = 1, kCounterShadow = 2, kCounterFirstMaterial = 3 };
inline constexpr u32 kWavefrontCounters = kCounterFirstMaterial + kMaterialClasses;

// What the stages keep of each path between them, each field listed once as (type, array, member of the state it
// holds): the pool's arrays (structure-of-arrays), their loads and stores, its bytes per path and its allocation all
// follow from these lists. The *_TAGS lists are what a pool keeps beside the state, written by its store's extra
// arguments. A member added to PathState, Hit or ShadowRay and not listed here fails the size checks below.

// A path between bounces. `item` names the work item (pixel and sample) the path belongs to.
#define PT_PATH_POOL_FIELDS(FIELD)         \
  FIELD(Vec3<T>, origin, ray.origin)       \
  FIELD(Vec3<T>, direction, ray.direction) \
  FIELD(T, time, ray.time)                 \
  FIELD(Color<T>, radiance, radiance)      \
  FIELD(Color<T>, throughput, throughput)  \
  FIELD(u32, bounce, bounce)               \
  FIELD(u32, shadow_rays, shadow_rays)     \
  FIELD(T, scatter_pdf, scatter_pdf)
#define PT_PATH_POOL_TAGS(TAG) TAG(u32, item)

// The closest hit found for each slot by the intersect stage, read by the shade stage.
#define PT_PATH_HIT_FIELDS(FIELD)  \
  FIELD(T, t, t)                   \
  FIELD(T, b1, b1)                 \
  FIELD(T, b2, b2)                 \
  FIELD(u32, primitive, primitive) \
  FIELD(u32, triangle, triangle)
#define PT_PATH_HIT_TAGS(TAG)

// The shadow rays the shade stage queued, traced in the next intersect launch; `item` is the path's work item and
// `slot` where it went on in the next pool (kNoLight: it ended, and its result is final but for this ray's share).
#define PT_SHADOW_FIELDS(FIELD)            \
  FIELD(Vec3<T>, origin, ray.origin)       \
  FIELD(Vec3<T>, direction, ray.direction) \
  FIELD(T, time, ray.time)                 \
  FIELD(Color<T>, weight, weight)          \
  FIELD(T, scatter_pdf, scatter_pdf)       \
  FIELD(T, distance, distance)             \
  FIELD(T, light_pdf, light_pdf)           \
  FIELD(u32, entry, entry)                 \
  FIELD(u32, triangle, triangle)
#define PT_SHADOW_TAGS(TAG) TAG(u32, item) TAG(u32, slot)

#define PT_DECLARE_ARRAY(Type, name, ...) Type* name;
#define PT_ADD_BYTES(Type, name, ...) +sizeof(Type)
#define PT_VISIT_ARRAY(Type, name, ...) visit(name);
#define PT_LOAD_FIELD(Type, name, member) value.member = name[i];
#define PT_STORE_FIELD(Type, name, member) name[i] = value.member;

// A structure-of-arrays pool of `State` values with the arrays FIELDS and TAGS list.
#define PT_SOA_POOL(Pool, State, FIELDS, TAGS)                                                                    \
  FIELDS(PT_DECLARE_ARRAY)                                                                                        \
  TAGS(PT_DECLARE_ARRAY)                                                                                          \
  static constexpr u32 kBytesPerPath = 0 FIELDS(PT_ADD_BYTES) TAGS(PT_ADD_BYTES);                                 \
  static_assert(sizeof(State) == 0 FIELDS(PT_ADD_BYTES), #Pool " lists every member of " #State);                 \
  /* visit(array) for every array of the pool (host side: allocation) */                                          \
  template <class Visit>                                                                                          \
  void for_each_array(Visit&& visit){FIELDS(PT_VISIT_ARRAY) TAGS(PT_VISIT_ARRAY)} PT_HD State load(u32 i) const { \
    State value;                                                                                                  \
    FIELDS(PT_LOAD_FIELD)                                                                                         \
    return value;                                                                                                 \
  }                                                                                                               \
  PT_HD void store_state(u32 i, const State& value) const { FIELDS(PT_STORE_FIELD) }

// A pool of paths.
template <class T>
struct PathPool {
  PT_SOA_POOL(PathPool, PathState<T>, PT_PATH_POOL_FIELDS, PT_PATH_POOL_TAGS)
  PT_HD void store(u32 i, const PathState<T>& path, u32 work_item) const {
    store_state(i, path);
    item[i] = work_item;
  }
};

// The queued shadow rays.
template <class T>
struct ShadowQueue {
  PT_SOA_POOL(ShadowQueue, ShadowRay<T>, PT_SHADOW_FIELDS, PT_SHADOW_TAGS)
  PT_HD void store(u32 i, const ShadowRay<T>& shadow, u32 work_item, u32 next_slot) const {
    store_state(i, shadow);
    item[i] = work_item;
    slot[i] = next_slot;
  }
};

// The hits of a pool's paths.
template <class T>
struct PathHits {
  PT_SOA_POOL(PathHits, Hit<T>, PT_PATH_HIT_FIELDS, PT_PATH_HIT_TAGS)
  PT_HD void store(u32 i, const Hit<T>& hit) const { store_state(i, hit); }
};

// Work items of a batch are sample-major: item = (sample - first_sample) * pixels + pixel.
template <class T>
struct WavefrontView {
  PathPool<T> current, next;
  PathHits<T> hits;
  ShadowQueue<T> shadows;
  u32* escaped;
  // The material queues one after another, pool_capacity entries each. One pointer, not an array of them: a kernel
  // that picks an array element by a run-time index makes SYCL compilers keep the whole kernel object in local
  // memory (seen through AdaptiveCpp on the H200: a 704-byte copy read by local loads, the intersect stage 3.5x
  // slower than nvcc's).
  u32* material_queues;
  u32 pool_capacity;
  u32* counters;             // kWavefrontCounters entries
  SampleResult<T>* results;  // one per work item of the batch
  u32 first_sample;
  u32 pixels;           // taking samples in the band being rendered (the whole image, or rows of it: docs/distributed.md)
  u32 first_pixel = 0;  // the image's index of the band's first pixel; film and results are indexed within the band
  // The band's pixels that take samples, where adaptive sampling has stopped some (in any order: each pixel's
  // samples depend only on the pixel and the sample number, and are added in sample order); null: all of them.
  const u32* active_pixels = nullptr;

  // Bytes of one path in flight: two pools (current and next), its hit, its shadow ray, and a slot in the escaped
  // queue and in every material queue.
  static constexpr u32 kBytesPerPath =
      2 * PathPool<T>::kBytesPerPath + PathHits<T>::kBytesPerPath + ShadowQueue<T>::kBytesPerPath + (1 + kMaterialClasses) * sizeof(u32);

  // visit(array, entries) for every array, sized for `pool_capacity` paths and `work_items` results (host side:
  // allocation).
  template <class Visit>
  void for_each_array(u32 pool_capacity, std::size_t work_items, Visit&& visit) {
    auto sized = [&](auto*& array) { visit(array, pool_capacity); };
    current.for_each_array(sized);
    next.for_each_array(sized);
    hits.for_each_array(sized);
    shadows.for_each_array(sized);
    sized(escaped);
    this->pool_capacity = pool_capacity;
    visit(material_queues, static_cast<std::size_t>(pool_capacity) * kMaterialClasses);
    visit(counters, kWavefrontCounters);
    visit(results, work_items);
  }

  PT_HD u32 pixel_of(u32 item) const {
    const u32 index = item % pixels;
    return active_pixels ? active_pixels[index] : index;
  }
  PT_HD u32 image_pixel_of(u32 item) const { return first_pixel + pixel_of(item); }
  PT_HD u32* material_queue(u32 material_class) const { return material_queues + static_cast<std::size_t>(material_class) * pool_capacity; }
  // The paths that go on were written to `next`; they become the current ones (host side, between bounces).
  void swap_pools() {
    const PathPool<T> done = current;
    current = next;
    next = done;
  }
  PT_HD u32 sample_of(u32 item) const { return first_sample + item / pixels; }
};

#undef PT_SOA_POOL
#undef PT_DECLARE_ARRAY
#undef PT_ADD_BYTES
#undef PT_VISIT_ARRAY
#undef PT_LOAD_FIELD
#undef PT_STORE_FIELD

template <class T>
PT_HD inline SampleRandom wavefront_random(const SceneView<T>& scene, const WavefrontView<T>& w, u32 item) {
  return path_random(scene.params, w.image_pixel_of(item), w.sample_of(item));
}

template <class T>
PT_HD inline void wavefront_finish(const WavefrontView<T>& w, const PathState<T>& path, u32 item) {
  w.results[item] = SampleResult<T>{path.radiance, path.bounce + path.shadow_rays};
}

// Stage 1: a new camera path for work item `item`, in slot `slot` of the current pool.
template <class T>
PT_HD inline void wavefront_generate(const SceneView<T>& scene, const WavefrontView<T>& w, u32 slot, u32 item) {
  const u32 pixel = w.image_pixel_of(item);
  const SampleRandom random = wavefront_random(scene, w, item);
  w.current.store(slot, start_path(scene, pixel % scene.params.width, pixel / scene.params.width, random), item);
}

// Stage 2: the closest hit of the path in `slot` (media sample their free-flight distance here, as primitives);
// the path joins its material's queue or the escaped queue (wavefront_queue_hit).
template <class T>
PT_HD inline void wavefront_queue_hit(const WavefrontView<T>& w, const SceneView<T>& scene, u32 slot, bool found, const Hit<T>& hit) {
  if (found) {
    w.hits.store(slot, hit);
    const u32 material_class = hit_material_class(scene, hit);
    w.material_queue(material_class)[queue_push(w.counters + kCounterFirstMaterial + material_class)] = slot;
  } else {
    w.escaped[queue_push(w.counters + kCounterEscaped)] = slot;
  }
}

template <class T>
PT_HD inline void wavefront_intersect(const SceneView<T>& scene, const WavefrontView<T>& w, u32 slot) {
  const PathState<T> path = w.current.load(slot);
  const SampleRandom random = wavefront_random(scene, w, w.current.item[slot]);
  Hit<T> hit{};
  const bool found = closest_hit(scene, path.ray, IntersectContext<T>{scene.boundaries, &random, path.bounce}, hit);
  wavefront_queue_hit(w, scene, slot, found, hit);
}

// Stage 3: escaped paths gather the background and end.
template <class T>
PT_HD inline void wavefront_escaped(const SceneView<T>& scene, const WavefrontView<T>& w, u32 queue_index) {
  const u32 slot = w.escaped[queue_index];
  PathState<T> path = w.current.load(slot);
  path_escaped(scene, path);
  wavefront_finish(w, path, w.current.item[slot]);
}

// Stage 4, once per material class: shade and scatter; paths that go on are compacted into the next pool, and
// shadow rays queued with where their share goes.
template <class T>
PT_HD inline void wavefront_shade(const SceneView<T>& scene, const WavefrontView<T>& w, u32 material_class, u32 queue_index) {
  const u32 slot = w.material_queue(material_class)[queue_index];
  PathState<T> path = w.current.load(slot);
  const u32 item = w.current.item[slot];
  const SampleRandom random = wavefront_random(scene, w, item);
  const Hit<T> hit = w.hits.load(slot);
  ShadowRay<T> shadow;
  u32 next_slot = kNoLight;
  if (path_shade(scene, path, hit, random, shadow) && path.bounce < scene.params.max_depth) {
    next_slot = queue_push(w.counters + kCounterNextPaths);
    w.next.store(next_slot, path, item);
  } else {
    wavefront_finish(w, path, item);
  }
  if (shadow.entry != kNoLight) w.shadows.store(queue_push(w.counters + kCounterShadow), shadow, item, next_slot);
}

// Stage 2 too: the shadow rays the last shade stage queued, traced in the intersect launch that follows it (the
// pools have been swapped since: a path that went on is in the current pool). What each brings is added to its
// path's radiance exactly where the megakernel adds it, after the emission of the same bounce and before anything
// of the next (the escaped and shade stages come after this launch).
template <class T>
PT_HD inline void wavefront_add_shadow(const WavefrontView<T>& w, u32 queue_index, const Color<T>& contribution) {
  const u32 slot = w.shadows.slot[queue_index];
  if (slot != kNoLight)
    w.current.radiance[slot] += contribution;
  else
    w.results[w.shadows.item[queue_index]].radiance += contribution;
}

template <class T>
PT_HD inline void wavefront_shadow(const SceneView<T>& scene, const WavefrontView<T>& w, u32 queue_index) {
  const u32 item = w.shadows.item[queue_index];
  wavefront_add_shadow(w, queue_index, shadow_contribution(scene, w.shadows.load(queue_index), wavefront_random(scene, w, item)));
}

// Stage 6, once per batch: each pixel adds its samples in sample order, exactly as the megakernel does (`index`
// counts the pixels that take samples).
template <class T>
PT_HD inline void wavefront_accumulate(const WavefrontView<T>& w, FilmPixel* film, u32 index, u32 sample_count) {
  FilmPixel& pixel = film[w.pixel_of(index)];
  FilmPixel sum = pixel;
  for (u32 s = 0; s < sample_count; ++s) add_sample(sum, w.results[s * w.pixels + index], w.first_sample + s);
  pixel = sum;
}

// Before a batch: the band's pixels that adaptive sampling has not stopped, listed at `list` (counted at `count`).
struct WavefrontActivePixels {
  const FilmPixel* film;
  u32* list;
  u32* count;
  PT_HD void operator()(u32 pixel) const {
    if (film[pixel].stopped_at == 0) list[queue_push(count)] = pixel;
  }
};

// The stages as kernels over a queue (or the pixels, for accumulate): what each backend launches.
template <class T>
struct WavefrontGenerate {
  SceneView<T> scene;
  WavefrontView<T> view;
  u32 first_slot, first_item;
  PT_HD void operator()(u32 i) const { wavefront_generate(scene, view, first_slot + i, first_item + i); }
};

template <class T>
struct WavefrontIntersect {
  SceneView<T> scene;
  WavefrontView<T> view;
  PT_HD void operator()(u32 i) const { wavefront_intersect(scene, view, i); }
};

// Where shadow rays are queued, one launch for the live paths' closest hits and the shadow rays: threads below
// `paths` take a path, the rest a shadow ray. A launch of the shadow rays alone, a few for every ten paths, left most
// of a GPU idle (it ran at a third of the intersect launch's rays per second). Without shadow rays the plain kernel
// runs: this one needs more registers (92 against 80 on sm_90), which cost the paths' launch 4-9 %.
template <class T>
struct WavefrontIntersectAndShadow {
  SceneView<T> scene;
  WavefrontView<T> view;
  u32 paths;
  PT_HD void operator()(u32 i) const {
    if (i < paths)
      wavefront_intersect(scene, view, i);
    else
      wavefront_shadow(scene, view, i - paths);
  }
};

template <class T>
struct WavefrontEscaped {
  SceneView<T> scene;
  WavefrontView<T> view;
  PT_HD void operator()(u32 i) const { wavefront_escaped(scene, view, i); }
};

template <class T>
struct WavefrontShade {
  SceneView<T> scene;
  WavefrontView<T> view;
  u32 material_class;
  PT_HD void operator()(u32 i) const { wavefront_shade(scene, view, material_class, i); }
};

template <class T>
struct WavefrontAccumulate {
  WavefrontView<T> view;
  FilmPixel* film;
  u32 sample_count;
  PT_HD void operator()(u32 index) const { wavefront_accumulate(view, film, index, sample_count); }
};

}  // namespace pt
