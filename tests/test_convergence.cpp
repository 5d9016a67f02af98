// Checks that the error against a high-sample reference falls as 1/sqrt(samples per pixel): unbiased, converging.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "test_support.hpp"

namespace pt {
namespace {

// A small scene whose samples are bounded (sky light, diffuse and fuzzy-metal surfaces, no small bright lights),
// so that the squared error of an image is a sum of many well-behaved terms and its ratio between sample counts is
// stable; scenes with fireflies need far more pixels for the same stability.
const char* const kScene = R"({
  "render": {"width": 32, "height": 24, "max_depth": 8},
  "camera": {"look_from": [0, 1, 4], "look_at": [0, 0.5, 0], "vertical_fov": 45},
  "background": {"type": "sky"},
  "objects": [
    {"type": "sphere", "center": [0, -100, 0], "radius": 100,
     "material": {"type": "lambertian", "texture": {"type": "checker", "odd": [0.2, 0.3, 0.1], "even": [0.9, 0.9, 0.9], "frequency": 10}}},
    {"type": "sphere", "center": [-1.1, 0.5, 0], "radius": 0.5, "material": {"type": "lambertian", "albedo": [0.8, 0.3, 0.2]}},
    {"type": "sphere", "center": [0, 0.5, 0], "radius": 0.5, "material": {"type": "metal", "albedo": [0.8, 0.8, 0.85], "fuzz": 0.3}},
    {"type": "box", "min": [0.7, 0, -0.4], "max": [1.5, 0.8, 0.4], "material": {"type": "lambertian", "albedo": [0.3, 0.5, 0.8]},
     "transform": {"rotate": [0, 20, 0]}}
  ]})";

template <class T>
LinearImage render_at(u32 spp, u32 seed, SamplerKind sampler = SamplerKind::kIndependent) {
  SceneDescription scene = test::parse(kScene, "convergence.json");
  scene.render.samples_per_pixel = spp;
  scene.render.seed = seed;
  scene.render.sampler = sampler;
  return test::render(test::flatten<T>(scene), 2).image;
}

double rmse(const LinearImage& a, const LinearImage& b) {
  double sum = 0;
  for (std::size_t i = 0; i < a.rgb.size(); ++i) {
    const double d = static_cast<double>(a.rgb[i]) - b.rgb[i];
    sum += d * d;
  }
  return std::sqrt(sum / a.rgb.size());
}

template <class T>
class ErrorFallsAsInverseSqrtOfSamples : public ::testing::Test {};
using ScalarTypes = ::testing::Types<float, double>;
TYPED_TEST_SUITE(ErrorFallsAsInverseSqrtOfSamples, ScalarTypes);

TYPED_TEST(ErrorFallsAsInverseSqrtOfSamples, FourTimesTheSamplesHalvesTheRmse) {
  using T = TypeParam;
  // Independent samples (stratified ones converge faster: below), and independent seeds at every level; the
  // reference's own noise (2048 samples) lowers the expected ratio between 16 and 64 samples only to 1.97.
  const LinearImage reference = render_at<T>(2048, 1000);
  const double e4 = rmse(render_at<T>(4, 1), reference);
  const double e16 = rmse(render_at<T>(16, 2), reference);
  const double e64 = rmse(render_at<T>(64, 3), reference);
  EXPECT_GT(e4 / e16, 1.6) << e4 << " " << e16;
  EXPECT_LT(e4 / e16, 2.5) << e4 << " " << e16;
  EXPECT_GT(e16 / e64, 1.6) << e16 << " " << e64;
  EXPECT_LT(e16 / e64, 2.5) << e16 << " " << e64;
  // The scene is noisy at all: an image that converged at once would make the ratios meaningless.
  EXPECT_GT(e4, 0.02);
}

TEST(StratifiedSamples, ErrorFallsAtLeastAsFastAsTheInverseSqrtAndStaysBelowIndependentSamples) {
  const LinearImage reference = render_at<float>(2048, 1000);
  const double e4 = rmse(render_at<float>(4, 1, SamplerKind::kSobol), reference);
  const double e16 = rmse(render_at<float>(16, 2, SamplerKind::kSobol), reference);
  const double e64 = rmse(render_at<float>(64, 3, SamplerKind::kSobol), reference);
  EXPECT_GT(e4 / e16, 1.8) << e4 << " " << e16;
  EXPECT_GT(e16 / e64, 1.8) << e16 << " " << e64;
  EXPECT_LT(e64, 0.9 * rmse(render_at<float>(64, 3, SamplerKind::kIndependent), reference));
}

TEST(ErrorFallsAsInverseSqrtOfSamplesGuard, BiasedImageStopsConverging) {
  // A render that is wrong (paths cut at 2 bounces) keeps a fixed error, so the ratio collapses towards 1: the
  // check above can tell convergence from bias.
  const LinearImage reference = render_at<float>(2048, 1000);
  SceneDescription scene = test::parse(kScene, "convergence.json");
  scene.render.max_depth = 2;
  scene.render.samples_per_pixel = 16;
  scene.render.seed = 2;
  const double e16 = rmse(test::render(test::flatten<float>(scene), 2).image, reference);
  scene.render.samples_per_pixel = 64;
  scene.render.seed = 3;
  const double e64 = rmse(test::render(test::flatten<float>(scene), 2).image, reference);
  EXPECT_LT(e16 / e64, 1.6);
}

}  // namespace
}  // namespace pt
