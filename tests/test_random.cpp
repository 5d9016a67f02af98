// Checks the counter-based random numbers: a pure function of their inputs, uniform, uncorrelated, never stuck.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <functional>
#include <set>
#include <vector>

#include "test_support.hpp"

namespace pt {
namespace {

// The five inputs of one draw.
struct DrawInputs {
  u32 seed, pixel, sample, bounce, dimension;
};

u32 draw_bits(const DrawInputs& in) { return SampleRandom::make(in.seed, in.pixel, in.sample).bits(in.bounce, in.dimension); }
double draw_uniform(const DrawInputs& in) { return SampleRandom::make(in.seed, in.pixel, in.sample).uniform<double>(in.bounce, in.dimension); }

// Varies one input of a base draw: axis 0 seed, 1 pixel, 2 sample, 3 bounce, 4 dimension.
DrawInputs vary(DrawInputs base, int axis, u32 value) {
  switch (axis) {
    case 0: base.seed = value; break;
    case 1: base.pixel = value; break;
    case 2: base.sample = value; break;
    case 3: base.bounce = value; break;
    default: base.dimension = value; break;
  }
  return base;
}

const char* const kAxisNames[5] = {"seed", "pixel", "sample", "bounce", "dimension"};
constexpr DrawInputs kBase{1, 1234, 5, 2, kDimScatter};

TEST(RandomIsPureFunctionOfInputs, SameInputsGiveSameBits) {
  test::TestRandom rng(1);
  for (int i = 0; i < 10000; ++i) {
    const DrawInputs in{static_cast<u32>(rng.next()), static_cast<u32>(rng.next()), static_cast<u32>(rng.next()), rng.below(64), rng.below(256)};
    const SampleRandom a = SampleRandom::make(in.seed, in.pixel, in.sample);
    const SampleRandom b = SampleRandom::make(in.seed, in.pixel, in.sample);
    ASSERT_EQ(a.key, b.key);
    ASSERT_EQ(a.bits(in.bounce, in.dimension), b.bits(in.bounce, in.dimension));
    // Drawing other numbers in between changes nothing: the stream has no state.
    (void)a.bits(in.bounce + 1, in.dimension);
    ASSERT_EQ(a.uniform<float>(in.bounce, in.dimension), b.uniform<float>(in.bounce, in.dimension));
  }
}

TEST(RandomIsPureFunctionOfInputs, ChangingAnyOneInputChangesTheBits) {
  for (int axis = 0; axis < 5; ++axis) {
    std::set<u32> values;
    const u32 count = axis == 4 ? 256 : 2000;
    for (u32 v = 0; v < count; ++v) values.insert(draw_bits(vary(kBase, axis, v)));
    // 2000 distinct inputs, 2000 distinct 32-bit outputs (a collision would be a one-in-a-thousand accident).
    EXPECT_EQ(values.size(), count) << kAxisNames[axis];
  }
}

TEST(RandomIsPureFunctionOfInputs, BounceRandomIsTheStreamAtItsBounce) {
  const SampleRandom stream = SampleRandom::make(3, 4, 5);
  for (u32 bounce = 0; bounce < 8; ++bounce) {
    const BounceRandom at_bounce{&stream, bounce};
    for (u32 dim = 0; dim < 16; ++dim) {
      EXPECT_EQ(at_bounce.uniform<float>(dim), stream.uniform<float>(bounce, dim));
      EXPECT_EQ(at_bounce.uniform<double>(dim), stream.uniform<double>(bounce, dim));
    }
  }
}

TEST(UniformDraws, LieInHalfOpenUnitIntervalAndAgreeAcrossScalarTypes) {
  EXPECT_EQ(ScalarTraits<float>::from_unit_bits(0), 0.0f);
  EXPECT_LT(ScalarTraits<float>::from_unit_bits(0xffffffu), 1.0f);
  EXPECT_LT(ScalarTraits<double>::from_unit_bits(0xffffffu), 1.0);
  double lowest = 1, highest = 0;
  for (u32 pixel = 0; pixel < 1000; ++pixel)
    for (u32 dim = 0; dim < 300; ++dim) {
      const SampleRandom stream = SampleRandom::make(9, pixel, 0);
      const float f = stream.uniform<float>(0, dim);
      const double d = stream.uniform<double>(0, dim);
      ASSERT_GE(f, 0.0f);
      ASSERT_LT(f, 1.0f);
      ASSERT_GE(d, 0.0);
      ASSERT_LT(d, 1.0);
      // 24 random bits: exactly representable in float, so both types draw the same number.
      ASSERT_EQ(static_cast<double>(f), d);
      lowest = std::min(lowest, d);
      highest = std::max(highest, d);
    }
  EXPECT_LT(lowest, 1e-4);
  EXPECT_GT(highest, 1 - 1e-4);
}

TEST(UniformDraws, ChiSquareUniformAlongEveryInput) {
  // 2^17 draws into 64 bins along each input: chi-square with 63 degrees of freedom, bounds at p = 1e-6 each side
  // (too uniform would also be suspicious: a plain counter is perfectly uniform).
  constexpr int kBins = 64;
  constexpr u32 kDraws = 1u << 17;
  for (int axis = 0; axis < 5; ++axis) {
    std::vector<long> counts(kBins, 0);
    for (u32 i = 0; i < kDraws; ++i) {
      // Along `axis` the index runs fast; the other inputs take a few values so that the draws are not all one stream.
      DrawInputs in = vary(kBase, axis, i & 0x7ff);
      in = vary(in, (axis + 1) % 5, i >> 11);
      ++counts[static_cast<int>(draw_uniform(in) * kBins)];
    }
    const double chi2 = test::chi_square(counts, kDraws);
    EXPECT_GT(chi2, 22.9) << kAxisNames[axis];
    EXPECT_LT(chi2, 131.7) << kAxisNames[axis];
  }
}

TEST(UniformDraws, PairsAndTwoDimensionsAreUniformInTheUnitSquare) {
  // The two numbers of the jitter pair of one sample, and two dimensions of it, 16 x 16 bins: chi-square with
  // 255 degrees of freedom.
  constexpr int kBins = 16;
  const u32 draws = 1u << 18;
  for (bool pair : {true, false}) {
    std::vector<long> counts(kBins * kBins, 0);
    for (u32 i = 0; i < draws; ++i) {
      const SampleRandom stream = SampleRandom::make(5, i >> 4, i & 15);
      double a, b;
      if (pair) {
        stream.uniform_pair(0, kDimPixel, a, b);
      } else {
        a = stream.uniform<double>(0, kDimPixel);
        b = stream.uniform<double>(0, kDimTime);
      }
      ++counts[static_cast<int>(a * kBins) * kBins + static_cast<int>(b * kBins)];
    }
    const double chi2 = test::chi_square(counts, draws);
    EXPECT_GT(chi2, 161.5) << (pair ? "pair" : "dimensions");
    EXPECT_LT(chi2, 377.2) << (pair ? "pair" : "dimensions");
  }
}

TEST(UniformDraws, FirstOfAPairIsTheDrawOfItsDimension) {
  test::TestRandom rng(9);
  for (int i = 0; i < 10000; ++i) {
    const SampleRandom stream = SampleRandom::make(static_cast<u32>(rng.next()), static_cast<u32>(rng.next()), static_cast<u32>(rng.next()));
    const u32 bounce = rng.below(64), dimension = rng.below(256);
    float first, second;
    stream.uniform_pair(bounce, dimension, first, second);
    ASSERT_EQ(first, stream.uniform<float>(bounce, dimension));
    ASSERT_GE(second, 0.0f);
    ASSERT_LT(second, 1.0f);
    const BounceRandom at_bounce{&stream, bounce};
    float again_first, again_second;
    at_bounce.uniform_pair(dimension, again_first, again_second);
    ASSERT_EQ(again_first, first);
    ASSERT_EQ(again_second, second);
  }
}

TEST(UniformDraws, NeighbouringInputsAreUncorrelated) {
  // Pearson correlation of the draws at inputs i and i + 1 along each input, and between neighbouring dimensions of
  // one stream; |r| below 5 / sqrt(n).
  constexpr u32 n = 100000;
  auto correlation = [&](const std::function<std::pair<double, double>(u32)>& pair) {
    double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
    for (u32 i = 0; i < n; ++i) {
      const auto [a, b] = pair(i);
      sa += a;
      sb += b;
      saa += a * a;
      sbb += b * b;
      sab += a * b;
    }
    const double cov = sab / n - (sa / n) * (sb / n);
    return cov / std::sqrt((saa / n - (sa / n) * (sa / n)) * (sbb / n - (sb / n) * (sb / n)));
  };
  const double bound = 5 / std::sqrt(static_cast<double>(n));
  for (int axis = 0; axis < 5; ++axis) {
    const double r = correlation([&](u32 i) {
      // Index i spread over the other inputs, neighbours along `axis`.
      DrawInputs base = vary(kBase, (axis + 1) % 5, i);
      const u32 start = axis == 3 || axis == 4 ? (i % 64) : i * 7;
      return std::pair{draw_uniform(vary(base, axis, start)), draw_uniform(vary(base, axis, start + 1))};
    });
    EXPECT_LT(std::abs(r), bound) << kAxisNames[axis];
  }
  // Neighbouring pixels at the same sample and dimension, as an image sees them.
  const double r_pixels = correlation([](u32 i) {
    return std::pair{SampleRandom::make(1, i, 0).uniform<double>(0, kDimPixel), SampleRandom::make(1, i + 1, 0).uniform<double>(0, kDimPixel)};
  });
  EXPECT_LT(std::abs(r_pixels), bound);
  // The two numbers of a pair.
  const double r_pair = correlation([](u32 i) {
    double a, b;
    SampleRandom::make(2, i, 3).uniform_pair(1, kDimScatter, a, b);
    return std::pair{a, b};
  });
  EXPECT_LT(std::abs(r_pair), bound);
}

TEST(UniformDraws, PixelZeroSampleZeroIsNotStuck) {
  // The seed implementation's generator was stuck at zero for the first pixel's first sample.
  for (u32 seed = 0; seed < 16; ++seed) {
    const SampleRandom stream = SampleRandom::make(seed, 0, 0);
    EXPECT_NE(stream.key, 0u);
    std::set<u32> distinct;
    double sum = 0;
    int zeros = 0;
    for (u32 bounce = 0; bounce < 4; ++bounce)
      for (u32 dim = 0; dim < 256; ++dim) {
        const u32 bits = stream.bits(bounce, dim);
        distinct.insert(bits);
        const double u = stream.uniform<double>(bounce, dim);
        sum += u;
        zeros += u == 0.0;
      }
    EXPECT_EQ(distinct.size(), 1024u) << "seed " << seed;
    EXPECT_LE(zeros, 1) << "seed " << seed;
    // Mean of 1024 uniform draws: 0.5 with standard deviation 0.009.
    EXPECT_NEAR(sum / 1024, 0.5, 0.05) << "seed " << seed;
  }
  // And the first draw of pixel 0 differs between seeds and from that of pixel 1.
  std::set<u32> first;
  for (u32 seed = 0; seed < 100; ++seed) first.insert(SampleRandom::make(seed, 0, 0).bits(0, 0));
  EXPECT_EQ(first.size(), 100u);
  EXPECT_NE(SampleRandom::make(0, 0, 0).bits(0, 0), SampleRandom::make(0, 1, 0).bits(0, 0));
}

TEST(SamplingHelpers, UnitVectorsAreUnitAndUniformOnTheSphere) {
  // z is uniform in [-1, 1] and the mean vector is zero for the uniform distribution on the sphere.
  constexpr int n = 100000, kBins = 20;
  std::vector<long> counts(kBins, 0);
  Vec3d sum{};
  for (int i = 0; i < n; ++i) {
    const SampleRandom stream = SampleRandom::make(2, static_cast<u32>(i), 0);
    const Vec3<float> v = uniform_unit_vector(stream.uniform<float>(0, 0), stream.uniform<float>(0, 1));
    ASSERT_NEAR(length(v), 1.0f, 1e-6f);
    sum += Vec3d{v.x, v.y, v.z};
    ++counts[std::min(kBins - 1, static_cast<int>((v.z + 1) / 2 * kBins))];
  }
  const double chi2 = test::chi_square(counts, n);
  EXPECT_GT(chi2, 2.0);
  EXPECT_LT(chi2, 64.4);
  // Each component has variance 1/3.
  EXPECT_LT(length(sum / static_cast<double>(n)), 5 * std::sqrt(1.0 / (3 * n)));
}

TEST(SamplingHelpers, CosSinOfTurnsIsWithinTwoTenthsOfAMillionthOfTheLibrary) {
  // Every 24-bit draw a sampler can pass (uniform<float> has 24 random bits), against double-precision cos and sin.
  double worst = 0, worst_norm = 0;
  for (u32 bits = 0; bits < (1u << 24); bits += 7) {
    const float turns = ScalarTraits<float>::from_unit_bits(bits);
    float c, s;
    cos_sin_turns(turns, c, s);
    const double angle = 2 * 3.14159265358979323846 * double(turns);
    worst = std::max({worst, std::abs(double(c) - std::cos(angle)), std::abs(double(s) - std::sin(angle))});
    worst_norm = std::max(worst_norm, std::abs(double(c) * c + double(s) * s - 1));
  }
  EXPECT_LT(worst, 2e-7);
  EXPECT_LT(worst_norm, 4e-7);
  // Whole quarter turns are exact.
  const float quarters[4][3] = {{0.0f, 1.0f, 0.0f}, {0.25f, 0.0f, 1.0f}, {0.5f, -1.0f, 0.0f}, {0.75f, 0.0f, -1.0f}};
  for (const auto& q : quarters) {
    float c, s;
    cos_sin_turns(q[0], c, s);
    EXPECT_EQ(c, q[1]) << q[0];
    EXPECT_EQ(s, q[2]) << q[0];
  }
  // The other scalar types agree with the float one.
  for (const double turns : {0.1, 0.3, 0.55, 0.9}) {
    double c, s;
    cos_sin_turns(turns, c, s);
    float cf, sf;
    cos_sin_turns(float(turns), cf, sf);
    EXPECT_NEAR(c, cf, 3e-7) << turns;
    EXPECT_NEAR(s, sf, 3e-7) << turns;
  }
}

TEST(SamplingHelpers, DiskPointsAreUniformInTheUnitDisk) {
  // Uniform over the area: r^2 is uniform in [0, 1], and the angle is uniform.
  constexpr int n = 100000, kBins = 20;
  std::vector<long> radial(kBins, 0), angular(kBins, 0);
  for (int i = 0; i < n; ++i) {
    const SampleRandom stream = SampleRandom::make(4, static_cast<u32>(i), 0);
    double u1, u2;
    stream.uniform_pair(0, kDimLens, u1, u2);
    const Vec3<double> p = uniform_in_unit_disk(u1, u2);
    const double r2 = p.x * p.x + p.y * p.y;
    ASSERT_LT(r2, 1.0);
    ASSERT_EQ(p.z, 0.0);
    ++radial[std::min(kBins - 1, static_cast<int>(r2 * kBins))];
    const double angle = std::atan2(p.y, p.x) + 3.14159265358979323846;
    ++angular[std::min(kBins - 1, static_cast<int>(angle / (2 * 3.14159265358979323846) * kBins))];
  }
  for (const auto* counts : {&radial, &angular}) {
    const double chi2 = test::chi_square(*counts, n);
    EXPECT_GT(chi2, 2.0);
    EXPECT_LT(chi2, 64.4);
  }
}

}  // namespace
}  // namespace pt
