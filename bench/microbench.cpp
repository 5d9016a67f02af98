// Micro-benchmarks of the per-ray kernels on one CPU thread: closest-hit queries against the BVH and brute
// force, and whole camera samples, on the seed's default scene.
#include <benchmark/benchmark.h>

#include <vector>

#include "flat/flat_scene.hpp"
#include "loading/scene_loader.hpp"

namespace {

const pt::FlatScene<float>& seed_scene() {
  static const pt::FlatScene<float> scene = [] {
    const pt::SceneDescription description = pt::load_scene_file(PT_SOURCE_DIR "/scenes/seed-default.json");
    return pt::flatten_scene<float>(description, description.render);
  }();
  return scene;
}

// Camera rays of the seed scene: a realistic mix of near, far and grazing rays.
std::vector<pt::Ray<float>> camera_rays(const pt::FlatScene<float>& scene, std::size_t count) {
  std::vector<pt::Ray<float>> rays;
  for (std::size_t i = 0; i < count; ++i) {
    const pt::SampleRandom random = pt::SampleRandom::make(7, static_cast<pt::u32>(i), 0);
    const pt::u32 x = random.bits(0, 100) % scene.params.width, y = random.bits(0, 101) % scene.params.height;
    rays.push_back(pt::camera_ray(scene.camera, scene.params.width, scene.params.height, x, y, random));
  }
  return rays;
}

void closest_hit_bvh(benchmark::State& state) {
  const auto& scene = seed_scene();
  const auto rays = camera_rays(scene, 4096);
  const pt::SceneView<float> view = scene.view();
  const pt::SampleRandom random = pt::SampleRandom::make(1, 0, 0);
  std::size_t i = 0;
  for (auto _ : state) {
    pt::Hit<float> hit{};
    const bool found = pt::closest_hit(view, rays[i++ & 4095], pt::IntersectContext<float>{view.boundaries, &random, 0}, hit);
    benchmark::DoNotOptimize(found);
    benchmark::DoNotOptimize(hit);
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(closest_hit_bvh);

void closest_hit_brute_force(benchmark::State& state) {
  const auto& scene = seed_scene();
  const auto rays = camera_rays(scene, 4096);
  const pt::SampleRandom random = pt::SampleRandom::make(1, 0, 0);
  std::size_t i = 0;
  for (auto _ : state) {
    pt::Hit<float> hit{};
    const bool found = pt::closest_hit_brute_force(scene, rays[i++ & 4095], pt::IntersectContext<float>{scene.boundaries.data(), &random, 0}, hit);
    benchmark::DoNotOptimize(found);
    benchmark::DoNotOptimize(hit);
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(closest_hit_brute_force);

void camera_sample(benchmark::State& state) {
  const auto& scene = seed_scene();
  const pt::SceneView<float> view = scene.view();
  pt::u32 n = 0;
  for (auto _ : state) {
    const pt::u32 x = (n * 7919u) % scene.params.width, y = (n * 104729u) % scene.params.height;
    benchmark::DoNotOptimize(pt::trace_sample(view, x, y, n++));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(camera_sample);

}  // namespace

BENCHMARK_MAIN();
