// Checks a fresh render of scenes/tiny.json against the stored high-sample reference, pixel by pixel, statistically.
//
// The reference is scenes/tiny.json at 4096 samples per pixel in double precision: tests/data/tiny-reference.pfm
// holds the image and tests/data/tiny-reference-variance.pfm the per-sample variance of each pixel and channel.
// The comparison is statistical, so a change of sampling or random streams that keeps the expected image does not
// need a new reference. Regenerate both files with the pt_make_reference_image tool (tests/make_reference_image.cpp)
// after a change that is meant to change the expected image (a new material model, a changed scene):
//   cmake --build build/<folder> --target pt_make_reference_image && build/<folder>/tests/pt_make_reference_image
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

#include "test_support.hpp"

namespace pt {
namespace {

constexpr u32 kSamples = 64;
constexpr u32 kSeed = 7;  // independent of the reference's seed

struct Comparison {
  std::size_t values = 0, beyond_4_sigma = 0;
  double worst_z = 0;
};

// |mean - reference| in standard errors of the difference. The per-sample variance is the larger of the test's own
// estimate (64 samples) and the reference's (4096 samples): a pixel that is mostly one colour with a rare other one
// (a checker edge, a caustic) often shows no variance in 64 samples, but does in 4096. A small absolute slack covers
// pixels of zero variance and float rounding.
Comparison compare(const test::PixelStatistics& stats, const LinearImage& reference, const LinearImage& reference_variance) {
  Comparison c;
  for (std::size_t i = 0; i < stats.values(); ++i) {
    const double ref = reference.rgb[i], ref_variance = reference_variance.rgb[i];
    const double variance = std::max(stats.variance[i], ref_variance);
    const double sigma = std::sqrt(variance / stats.samples + ref_variance / test::kReferenceSamples);
    const double z = std::abs(stats.mean[i] - ref) / (sigma + 1e-5 * (1 + std::abs(ref)));
    ++c.values;
    if (z > 4) ++c.beyond_4_sigma;
    c.worst_z = std::max(c.worst_z, z);
  }
  return c;
}

class ReferenceImage : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    reference_ = std::make_unique<LinearImage>(test::read_pfm(test::reference_image_path()));
    variance_ = std::make_unique<LinearImage>(test::read_pfm(test::reference_variance_path()));
  }
  static void TearDownTestSuite() {
    reference_.reset();
    variance_.reset();
  }
  static test::PixelStatistics render_statistics(u32 max_depth) {
    SceneDescription scene = load_scene_file(test::scene_path("tiny.json"));
    scene.render.samples_per_pixel = kSamples;
    scene.render.seed = kSeed;
    scene.render.max_depth = max_depth;
    return test::sample_statistics(test::flatten<float>(scene), kSamples);
  }
  static std::unique_ptr<LinearImage> reference_, variance_;
};
std::unique_ptr<LinearImage> ReferenceImage::reference_, ReferenceImage::variance_;

TEST_F(ReferenceImage, StoredReferenceMatchesTheScene) {
  const FlatScene<float> scene = test::tiny_reference_scene<float>(1, kSeed);
  for (const LinearImage* image : {reference_.get(), variance_.get()}) {
    ASSERT_EQ(image->width, scene.params.width);
    ASSERT_EQ(image->height, scene.params.height);
    for (float v : image->rgb) {
      ASSERT_TRUE(std::isfinite(v));
      ASSERT_GE(v, 0.0f);
    }
  }
}

TEST_F(ReferenceImage, FreshRenderAgreesPerPixelWithinStandardErrors) {
  const test::PixelStatistics stats = render_statistics(8);
  ASSERT_EQ(stats.non_finite, 0u);
  // The statistics are those of the image the backend renders.
  const LinearImage image = test::render(test::tiny_reference_scene<float>(kSamples, kSeed), 2).image;
  ASSERT_EQ(image.rgb.size(), stats.values());
  for (std::size_t i = 0; i < stats.values(); ++i) ASSERT_NEAR(image.rgb[i], stats.mean[i], 1e-6 * (1 + std::abs(stats.mean[i])));

  // Normally distributed differences would put 0.006% of the 9216 values beyond 4 sigma: allow 0.1%.
  const Comparison c = compare(stats, *reference_, *variance_);
  EXPECT_LE(c.beyond_4_sigma, c.values / 1000) << "worst z " << c.worst_z;
  EXPECT_LT(c.worst_z, 8.0);
  // The image means, channel by channel.
  for (int k = 0; k < 3; ++k) {
    double reference_mean = 0, variance_sum = 0;
    for (std::size_t i = k; i < reference_->rgb.size(); i += 3) {
      reference_mean += reference_->rgb[i];
      variance_sum += std::max(stats.variance[i], static_cast<double>(variance_->rgb[i]));
    }
    const double pixels = static_cast<double>(reference_->rgb.size() / 3);
    const double se = std::sqrt(variance_sum * (1.0 / kSamples + 1.0 / test::kReferenceSamples)) / pixels;
    EXPECT_NEAR(stats.image_mean(k), reference_mean / pixels, 4 * se) << "channel " << k;
  }
}

TEST_F(ReferenceImage, ComparisonDetectsABiasedRender) {
  // The same comparison applied to a render that is wrong in a modest way (paths cut at 3 bounces instead of 8)
  // must fail clearly, or the test above could not catch a real bug.
  const Comparison c = compare(render_statistics(3), *reference_, *variance_);
  EXPECT_GT(c.beyond_4_sigma, c.values / 50);
}

}  // namespace
}  // namespace pt
