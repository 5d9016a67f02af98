// Checks that a render is bitwise the same for any thread count and any split of its samples into passes.
#include <gtest/gtest.h>

#include <cstring>
#include <vector>

#include "test_support.hpp"

namespace pt {
namespace {

// tiny.json at its own 64x48 with few samples: every object, material and texture type, in a fraction of a second.
template <class T>
FlatScene<T> tiny_scene(u32 spp, u32 seed = 1) {
  SceneDescription scene = load_scene_file(test::scene_path("tiny.json"));
  scene.render.samples_per_pixel = spp;
  scene.render.seed = seed;
  return test::flatten<T>(scene);
}

bool same_bits(const LinearImage& a, const LinearImage& b) {
  return a.width == b.width && a.height == b.height && a.rgb.size() == b.rgb.size() &&
         std::memcmp(a.rgb.data(), b.rgb.data(), a.rgb.size() * sizeof(float)) == 0;
}

// An image that is flat or black would make any comparison pass: require real content.
void expect_nontrivial(const LinearImage& image) {
  double lo = 1e30, hi = -1e30;
  for (float v : image.rgb) {
    lo = std::min(lo, static_cast<double>(v));
    hi = std::max(hi, static_cast<double>(v));
  }
  EXPECT_GT(hi - lo, 0.5);
}

TEST(ImageIdenticalForAnyThreadCount, OneAndFourThreadsFloat) {
  const FlatScene<float> scene = tiny_scene<float>(4);
  const RenderResult one = test::render(scene, 1);
  const RenderResult four = test::render(scene, 4);
  expect_nontrivial(one.image);
  EXPECT_TRUE(same_bits(one.image, four.image));
  EXPECT_EQ(one.stats.rays, four.stats.rays);
  EXPECT_EQ(one.stats.samples, 64u * 48u * 4u);
  EXPECT_TRUE(test::same_film(test::render_film(scene, 1, {4}), test::render_film(scene, 4, {4})));
}

TEST(ImageIdenticalForAnyThreadCount, OneAndTwoThreadsDouble) {
  const FlatScene<double> scene = tiny_scene<double>(2);
  const RenderResult one = test::render(scene, 1);
  const RenderResult two = test::render(scene, 2);
  expect_nontrivial(one.image);
  EXPECT_TRUE(same_bits(one.image, two.image));
}

TEST(ImageIdenticalForAnySplitIntoPasses, OnePassEqualsSeveralPasses) {
  const FlatScene<float> scene = tiny_scene<float>(8);
  const std::vector<FilmPixel> whole = test::render_film(scene, 2, {8});
  EXPECT_TRUE(test::same_film(whole, test::render_film(scene, 2, {1, 3, 4})));
  EXPECT_TRUE(test::same_film(whole, test::render_film(scene, 1, {1, 1, 1, 1, 1, 1, 1, 1})));
  EXPECT_TRUE(test::same_film(whole, test::render_film(scene, 3, {5, 3})));
  // render_scene picks its own passes; its image is the one-pass film resolved.
  const LinearImage resolved = resolve_film(whole, scene.params.width, scene.params.height);
  EXPECT_TRUE(same_bits(resolved, test::render(scene, 2).image));
}

TEST(ImageIdenticalForAnySplitIntoPasses, SamplesBeyondTheFirstPassAreNotRepeats) {
  // Passes must add new samples: the film of samples [0, 4) + [4, 8) differs from [0, 4) twice.
  const FlatScene<float> scene = tiny_scene<float>(8);
  const std::unique_ptr<RenderBackend<float>> backend = make_cpu_backend<float>(2);
  backend->upload(scene);
  backend->render(0, 4);
  backend->render(0, 4);
  std::vector<FilmPixel> repeated;
  backend->read_film(repeated);
  EXPECT_FALSE(test::same_film(repeated, test::render_film(scene, 2, {4, 4})));
  // Uploading clears the film.
  backend->upload(scene);
  backend->render(0, 8);
  std::vector<FilmPixel> fresh;
  backend->read_film(fresh);
  EXPECT_TRUE(test::same_film(fresh, test::render_film(scene, 1, {8})));
}

TEST(ImageIdenticalForEitherIntegrator, WavefrontEqualsMegakernel) {
  // Both integrators run the same path steps with the same random numbers, so they compute the same samples.
  const FlatScene<float> scene = tiny_scene<float>(4);
  const std::vector<FilmPixel> megakernel = test::render_film(scene, 2, {4}, Integrator::kMegakernel);
  EXPECT_TRUE(test::same_film(megakernel, test::render_film(scene, 2, {4}, Integrator::kWavefront)));
  const FlatScene<double> scene_double = tiny_scene<double>(2);
  EXPECT_TRUE(test::same_film(test::render_film(scene_double, 2, {2}, Integrator::kMegakernel),
                              test::render_film(scene_double, 2, {2}, Integrator::kWavefront)));
}

TEST(ImageIdenticalForEitherIntegrator, WavefrontIndependentOfThreadsAndPasses) {
  const FlatScene<float> scene = tiny_scene<float>(6);
  const std::vector<FilmPixel> whole = test::render_film(scene, 1, {6}, Integrator::kWavefront);
  EXPECT_TRUE(test::same_film(whole, test::render_film(scene, 4, {6}, Integrator::kWavefront)));
  EXPECT_TRUE(test::same_film(whole, test::render_film(scene, 2, {1, 2, 3}, Integrator::kWavefront)));
  EXPECT_TRUE(same_bits(resolve_film(whole, scene.params.width, scene.params.height), test::render(scene, 2, Integrator::kWavefront).image));
}

TEST(ImageDependsOnlyOnTheSeed, SameSeedSameImageOtherSeedOtherImage) {
  const LinearImage a = test::render(tiny_scene<float>(2, 7), 2).image;
  const LinearImage b = test::render(tiny_scene<float>(2, 7), 1).image;
  const LinearImage c = test::render(tiny_scene<float>(2, 8), 2).image;
  EXPECT_TRUE(same_bits(a, b));
  EXPECT_FALSE(same_bits(a, c));
}

TEST(RenderProgress, ReportsIncreasingSampleCountsUpToTheTotal) {
  const FlatScene<float> scene = tiny_scene<float>(6);
  const std::unique_ptr<RenderBackend<float>> backend = make_cpu_backend<float>(2);
  std::vector<u32> done;
  render_scene(*backend, scene, [&](const Progress& p) {
    EXPECT_EQ(p.samples_total, 6u);
    done.push_back(p.samples_done);
  });
  ASSERT_FALSE(done.empty());
  EXPECT_EQ(done.back(), 6u);
  for (std::size_t i = 1; i < done.size(); ++i) EXPECT_GT(done[i], done[i - 1]);
}

}  // namespace
}  // namespace pt
