// Checks the stratified sampler: each pixel's samples cover every elementary stratum of each dimension once per
// power of two, different dimensions and pixels do not correlate, the error falls faster than with independent
// samples, and the expected value of every shipped scene stays where independent samples put it.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "scene_cases.hpp"
#include "test_support.hpp"

namespace pt {
namespace {

using test::case_settings;
using test::expect_blocks_agree;
using test::load_case_scene;
using test::scene_case;
using test::SceneCase;
using test::statistics_on;

SampleRandom sobol(u32 seed, u32 pixel, u32 sample) { return SampleRandom::make(seed, pixel, sample, SamplerKind::kSobol); }

// True when the 2^k points, in [0, 1)^2, put exactly one point in every box 2^-a wide and 2^-(k-a) high, for
// every a: a (0, k, 2)-net in base 2.
bool is_net(const std::vector<std::pair<double, double>>& points, u32 k) {
  const u32 n = 1u << k;
  if (points.size() != n) return false;
  for (u32 a = 0; a <= k; ++a) {
    std::vector<int> hits(n, 0);
    for (const auto& [x, y] : points) {
      const u32 column = static_cast<u32>(x * (1u << a));
      const u32 row = static_cast<u32>(y * (1u << (k - a)));
      if (++hits[(row << a) | column] > 1) return false;
    }
  }
  return true;
}

TEST(SobolSampler, EveryAlignedPowerOfTwoBlockOfSamplesOfAPairIsANet) {
  // The first 2^k samples of a pixel (a render of 2^k samples a pixel) and any later aligned block of 2^k (a
  // render resumed or split into passes at such boundaries) are stratified in every pair dimension.
  for (u32 pixel : {0u, 1u, 77u, 123456u})
    for (u32 bounce : {0u, 1u, 9u})
      for (u32 dimension : {u32{kDimPixel}, u32{kDimScatter}, u32{kDimLightPoint}})
        for (u32 k = 0; k <= 10; ++k)
          for (u32 block : {0u, 1u, 5u}) {
            std::vector<std::pair<double, double>> points;
            for (u32 s = block << k; s < (block + 1) << k; ++s) {
              double u, v;
              sobol(3, pixel, s).uniform_pair(bounce, dimension, u, v);
              ASSERT_GE(u, 0.0);
              ASSERT_LT(u, 1.0);
              ASSERT_GE(v, 0.0);
              ASSERT_LT(v, 1.0);
              points.emplace_back(u, v);
            }
            ASSERT_TRUE(is_net(points, k)) << "pixel " << pixel << " bounce " << bounce << " dimension " << dimension << " 2^" << k
                                           << " samples from " << (block << k);
          }
}

TEST(SobolSampler, EveryAlignedPowerOfTwoBlockOfSamplesOfOneDimensionFillsEachStratumOnce) {
  for (u32 pixel : {0u, 9u, 4242u})
    for (u32 dimension : {u32{kDimTime}, u32{kDimRoulette}, u32{kDimLightChoice}, u32{kDimMediumBase + 17}})
      for (u32 k = 0; k <= 12; ++k)
        for (u32 block : {0u, 3u}) {
          std::vector<int> hits(1u << k, 0);
          for (u32 s = block << k; s < (block + 1) << k; ++s) {
            const double u = sobol(5, pixel, s).uniform<double>(2, dimension);
            ++hits[static_cast<u32>(u * (1u << k))];
          }
          for (u32 i = 0; i < hits.size(); ++i) ASSERT_EQ(hits[i], 1) << "dimension " << dimension << " 2^" << k << " stratum " << i;
        }
}

TEST(SobolSampler, OneSampleIsUniformOverPixels) {
  // Across pixels, a given sample of a given dimension is uniform (each pixel's sequence is scrambled apart).
  constexpr u32 n = 100000, kBins = 20;
  for (u32 sample : {0u, 1u, 200u}) {
    std::vector<long> first(kBins, 0), second(kBins, 0), single(kBins, 0);
    for (u32 p = 0; p < n; ++p) {
      const SampleRandom random = sobol(7, p, sample);
      double u, v;
      random.uniform_pair(0, kDimPixel, u, v);
      ++first[static_cast<u32>(u * kBins)];
      ++second[static_cast<u32>(v * kBins)];
      ++single[static_cast<u32>(random.uniform<double>(3, kDimLobe) * kBins)];
    }
    // 19 degrees of freedom: P(chi2 > 43.8) = 0.001, P(chi2 < 6.8) = 0.005.
    for (const auto* counts : {&first, &second, &single}) {
      const double chi2 = test::chi_square(*counts, n);
      EXPECT_GT(chi2, 4.0) << "sample " << sample;
      EXPECT_LT(chi2, 50.0) << "sample " << sample;
    }
  }
}

TEST(SobolSampler, DimensionsAndPixelsDoNotCorrelate) {
  // 4096 samples of one pixel: the first coordinates of two different dimensions (or of one dimension at two
  // bounces) are uncorrelated, as are neighbouring pixels' values of one sample. The bound is 5 standard errors of
  // a correlation of independent values.
  constexpr u32 n = 4096;
  const double bound = 5 / std::sqrt(static_cast<double>(n));
  auto correlation = [](auto draw) {
    double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
    for (u32 i = 0; i < n; ++i) {
      const auto [a, b] = draw(i);
      sa += a, sb += b, saa += a * a, sbb += b * b, sab += a * b;
    }
    const double cov = sab / n - (sa / n) * (sb / n);
    return cov / std::sqrt((saa / n - (sa / n) * (sa / n)) * (sbb / n - (sb / n) * (sb / n)));
  };
  const struct {
    const char* what;
    u32 bounce_a, dimension_a, bounce_b, dimension_b;
  } pairs[] = {{"pixel jitter against the first scatter", 0, kDimPixel, 0, kDimScatter},
               {"one dimension at two bounces", 0, kDimScatter, 1, kDimScatter},
               {"scatter against the light's point", 2, kDimScatter, 2, kDimLightPoint},
               {"lens against time", 0, kDimLens, 0, kDimTime}};
  for (const auto& pair : pairs) {
    const double r = correlation([&](u32 s) {
      const SampleRandom random = sobol(11, 321, s);
      return std::pair{random.uniform<double>(pair.bounce_a, pair.dimension_a), random.uniform<double>(pair.bounce_b, pair.dimension_b)};
    });
    EXPECT_LT(std::abs(r), bound) << pair.what;
  }
  const double r_pixels = correlation([](u32 p) {
    return std::pair{sobol(1, p, 5).uniform<double>(0, kDimPixel), sobol(1, p + 1, 5).uniform<double>(0, kDimPixel)};
  });
  EXPECT_LT(std::abs(r_pixels), bound);
}

TEST(SobolSampler, IndependentSamplesAreTheDefaultOfTheStreamAndDiffer) {
  // Stream construction without a kind keeps the independent numbers (tests and tools that need independent draws
  // rely on it), and the two samplers draw different numbers.
  const SampleRandom plain = SampleRandom::make(4, 10, 20);
  EXPECT_EQ(plain.stratified, 0u);
  EXPECT_EQ(plain.bits(1, kDimScatter), SampleRandom::make(4, 10, 20, SamplerKind::kIndependent).bits(1, kDimScatter));
  EXPECT_NE(plain.bits(1, kDimScatter), sobol(4, 10, 20).bits(1, kDimScatter));
}

// The error of a pixel mean over replicas with independent seeds: a scene whose pixels see a floor lit by a small
// square light (direct light: a smooth integrand over the light and the pixel) and the light's edges.
double replica_error(SamplerKind kind, u32 samples) {
  const SceneDescription scene = test::parse(R"({
    "render": {"width": 16, "height": 16, "max_depth": 2},
    "camera": {"look_from": [0, 6, 0.01], "look_at": [0, 0, 0], "vertical_fov": 40},
    "background": {"type": "constant", "color": [0, 0, 0]},
    "objects": [
      {"type": "quad", "corner": [-4, 0, -4], "u": [8, 0, 0], "v": [0, 0, 8], "material": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}},
      {"type": "quad", "corner": [-0.5, 3, -0.5], "u": [1, 0, 0], "v": [0, 0, 1], "material": {"type": "diffuse_light", "emission": [10, 10, 10]}}
    ]})");
  constexpr u32 kReplicas = 12;
  std::vector<test::PixelStatistics> replicas;
  for (u32 r = 0; r < kReplicas; ++r) {
    RenderSettings settings = scene.render;
    settings.sampler = kind;
    settings.seed = 100 + r;
    replicas.push_back(test::sample_statistics(flatten_scene<double>(scene, settings), samples));
  }
  // The variance of each pixel's mean across replicas, summed over the image.
  double total = 0;
  for (std::size_t i = 0; i < replicas[0].values(); ++i) {
    double sum = 0, sum2 = 0;
    for (const auto& r : replicas) sum += r.mean[i], sum2 += r.mean[i] * r.mean[i];
    total += (sum2 - sum * sum / kReplicas) / (kReplicas - 1);
  }
  return total;
}

TEST(SobolSampler, LeavesLessErrorThanIndependentSamples) {
  // At 64 samples a pixel, stratified light points and pixel positions cut the variance of the pixel means many
  // times (jittered sampling of a smooth 2-D integrand: error variance falling as N^-2 rather than N^-1; of an
  // edge, as N^-1.5). Half is a loose bound: independent samples give a ratio near 1.
  const double stratified = replica_error(SamplerKind::kSobol, 64);
  const double independent = replica_error(SamplerKind::kIndependent, 64);
  EXPECT_LT(stratified, 0.5 * independent) << stratified << " against " << independent;
}

// The expected value does not move: stratified samples against independent ones, block means within the noise
// bound of the statistical tests (for stratified samples the variance estimate, made as if samples were
// independent, is an overestimate, so the bound only loosens).
class SobolMatchesIndependent : public ::testing::TestWithParam<std::string> {};

TEST_P(SobolMatchesIndependent, BlockMeansAgreeWithinNoise) {
  const std::string name = GetParam();
  const SceneDescription scene = load_case_scene(name);
  const SceneCase& c = scene_case(name);
  const u32 samples = c.nee_samples ? c.nee_samples : c.samples;
  RenderSettings stratified = case_settings(scene, c, samples, 505);
  RenderSettings independent = case_settings(scene, c, samples, 606);
  stratified.sampler = SamplerKind::kSobol;
  independent.sampler = SamplerKind::kIndependent;
  const test::PixelStatistics a = statistics_on<float>("cpu", flatten_scene<float>(scene, stratified));
  const test::PixelStatistics b = statistics_on<float>("cpu", flatten_scene<float>(scene, independent));
  EXPECT_EQ(a.non_finite, 0u);
  expect_blocks_agree(a, b, "sobol", "independent", name);
}

INSTANTIATE_TEST_SUITE_P(Scenes, SobolMatchesIndependent, ::testing::Values("tiny", "book1-final", "book2-final", "cornell-smoke"),
                         test::scene_test_name);

}  // namespace
}  // namespace pt
