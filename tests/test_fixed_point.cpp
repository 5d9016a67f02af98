// Fixed<I, F> against long double on random inputs over each format's range: arithmetic, every function the
// kernels call (with the error bound each must meet), conversions, and saturation that is counted, never wrapped.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "kernel/fixed_point.hpp"

namespace pt {
namespace {

template <class T>
class FixedPointTest : public ::testing::Test {};

// Every storage width (8, 16, 32 and 64 bits) and the shipped formats.
using Formats = ::testing::Types<Fixed<32, 32>, Fixed<16, 16>, Fixed<24, 8>, Fixed<12, 12>, Fixed<10, 10>, Fixed<8, 24>, Fixed<4, 12>, Fixed<3, 5>>;
TYPED_TEST_SUITE(FixedPointTest, Formats);

constexpr int kDraws = 20000;

// Exact for every format: long double has a 64-bit significand.
template <class T>
long double exact(T x) {
  return static_cast<long double>(x.raw) / std::ldexp(1.0L, T::kFractionBits);
}
template <class T>
long double ulp() {
  return std::ldexp(1.0L, -T::kFractionBits);
}
template <class T>
long double max_value() {
  return exact(largest<T>());
}
template <class T>
T from_raw(long double raw) {
  return T::from_raw(static_cast<typename T::Storage>(raw));
}

// A uniformly random code of the format, limited to magnitude `limit`.
template <class T>
T random_value(std::mt19937_64& rng, long double limit) {
  const long double top = std::min(limit, max_value<T>()) / ulp<T>();
  std::uniform_real_distribution<long double> pick(-top, top);
  return from_raw<T>(std::nearbyint(pick(rng)));
}
// Magnitudes spread evenly over the binades from one step to `limit`, either sign.
template <class T>
T random_log_value(std::mt19937_64& rng, long double limit) {
  const long double lo = std::log2(ulp<T>()), hi = std::log2(std::min(limit, max_value<T>()));
  std::uniform_real_distribution<long double> pick(lo, hi);
  const long double v = std::nearbyint(std::exp2(pick(rng)) / ulp<T>());
  return from_raw<T>(rng() & 1 ? v : -v);
}

TYPED_TEST(FixedPointTest, AddSubtractAreExactInRange) {
  using T = TypeParam;
  std::mt19937_64 rng(1);
  for (int i = 0; i < kDraws; ++i) {
    const T a = random_value<T>(rng, max_value<T>() / 2), b = random_value<T>(rng, max_value<T>() / 2);
    EXPECT_EQ(exact(a + b), exact(a) + exact(b));
    EXPECT_EQ(exact(a - b), exact(a) - exact(b));
    EXPECT_EQ(exact(-a), -exact(a));
  }
}

// Products round to nearest: error at most half a step. Quotients truncate: less than one step.
TYPED_TEST(FixedPointTest, MultiplyAndDivideWithinBounds) {
  using T = TypeParam;
  std::mt19937_64 rng(2);
  const long double root = std::sqrt(max_value<T>());
  for (int i = 0; i < kDraws; ++i) {
    const T a = random_log_value<T>(rng, root), b = random_log_value<T>(rng, root);
    EXPECT_LE(std::fabs(exact(a * b) - exact(a) * exact(b)), ulp<T>() / 2) << exact(a) << " * " << exact(b);
    const long double q = exact(a) / exact(b);
    if (std::fabs(q) < max_value<T>()) {
      EXPECT_LE(std::fabs(exact(a / b) - q), ulp<T>() + std::fabs(q) * 0x1p-62L) << exact(a) << " / " << exact(b);
    }
  }
}

TYPED_TEST(FixedPointTest, ComparisonsFloorAndConversions) {
  using T = TypeParam;
  std::mt19937_64 rng(3);
  for (int i = 0; i < kDraws; ++i) {
    const T a = random_value<T>(rng, max_value<T>() / 2), b = random_value<T>(rng, max_value<T>() / 2);
    EXPECT_EQ(a < b, exact(a) < exact(b));
    EXPECT_EQ(a <= b, exact(a) <= exact(b));
    EXPECT_EQ(a == b, exact(a) == exact(b));
    EXPECT_EQ(exact(floor(a)), std::floor(exact(a)));
    EXPECT_EQ(static_cast<i32>(a), static_cast<i32>(std::trunc(exact(a))));
    // Doubles convert to the nearest code (for 64-bit formats the double itself carries 53 bits).
    const double d = static_cast<double>(exact(a)) * 0.7;
    EXPECT_LE(std::fabs(exact(T(d)) - d), ulp<T>() / 2 + std::fabs(d) * 0x1p-52);
  }
  EXPECT_EQ(exact(T(3)), 3.0L);
  EXPECT_EQ(exact(T(-2)), -2.0L);
  EXPECT_EQ(exact(ScalarTraits<T>::from_unit_bits(0x800000u)), 0.5L);
}

// sqrt rounds to nearest: half a step.
TYPED_TEST(FixedPointTest, SqrtWithinHalfAStep) {
  using T = TypeParam;
  std::mt19937_64 rng(4);
  for (int i = 0; i < kDraws; ++i) {
    const T a = abs(random_log_value<T>(rng, max_value<T>()));
    EXPECT_LE(std::fabs(exact(sqrt(a)) - std::sqrt(exact(a))), ulp<T>() / 2 + 1e-15L) << exact(a);
  }
  EXPECT_EQ(exact(sqrt(T(0))), 0.0L);
}

// sin and cos: one step, plus the error of the pi/2 used for range reduction (2^-61 relative, times |x|).
TYPED_TEST(FixedPointTest, SinCosWithinOneStep) {
  using T = TypeParam;
  std::mt19937_64 rng(5);
  for (int i = 0; i < kDraws; ++i) {
    const T a = i % 2 ? random_value<T>(rng, max_value<T>()) : random_value<T>(rng, 8);
    const long double x = exact(a), bound = ulp<T>() + std::fabs(x) * 0x1p-60L + 1e-15L;
    EXPECT_LE(std::fabs(exact(sin(a)) - std::sin(x)), bound) << x;
    EXPECT_LE(std::fabs(exact(cos(a)) - std::cos(x)), bound) << x;
  }
}

// atan2 and asin: one step (results need three integer bits for +-pi; narrower formats saturate).
TYPED_TEST(FixedPointTest, Atan2AndAsinWithinOneStep) {
  using T = TypeParam;
  std::mt19937_64 rng(6);
  const bool holds_pi = max_value<T>() > 3.2L;
  for (int i = 0; i < kDraws; ++i) {
    const T y = i % 2 ? random_value<T>(rng, max_value<T>()) : random_log_value<T>(rng, max_value<T>());
    const T x = random_value<T>(rng, max_value<T>());
    if (holds_pi) {
      EXPECT_LE(std::fabs(exact(atan2(y, x)) - std::atan2(exact(y), exact(x))), ulp<T>() + 1e-15L) << exact(y) << ", " << exact(x);
    }
    const T s = random_value<T>(rng, 1);
    EXPECT_LE(std::fabs(exact(asin(s)) - std::asin(exact(s))), ulp<T>() + 1e-15L) << exact(s);
  }
}

// log: one step over (0, max].
TYPED_TEST(FixedPointTest, LogWithinOneStep) {
  using T = TypeParam;
  std::mt19937_64 rng(7);
  for (int i = 0; i < kDraws; ++i) {
    const T a = abs(random_log_value<T>(rng, max_value<T>()));
    if (a.raw == 0) continue;
    const long double expected = std::log(exact(a));
    if (std::fabs(expected) >= max_value<T>()) continue;
    EXPECT_LE(std::fabs(exact(log(a)) - expected), ulp<T>() + 1e-15L) << exact(a);
  }
}

// exp: one step, plus the series' relative error (2^-56) where results are large.
TYPED_TEST(FixedPointTest, ExpWithinOneStep) {
  using T = TypeParam;
  std::mt19937_64 rng(8);
  const long double top = std::log(max_value<T>());
  std::uniform_real_distribution<double> spread(-60.0, static_cast<double>(top));
  for (int i = 0; i < kDraws; ++i) {
    const T a = T(spread(rng));
    const long double expected = std::exp(exact(a));
    if (expected >= max_value<T>()) continue;
    EXPECT_LE(std::fabs(exact(exp(a)) - expected), ulp<T>() + expected * 0x1p-56L + 1e-15L) << exact(a);
  }
  EXPECT_EQ(exact(exp(T(0))), 1.0L);
  // The most negative value: 0 or the step nearest exp of it (narrow formats reach only -8 or -4).
  EXPECT_LE(std::fabs(exact(exp(-largest<T>())) - std::exp(-max_value<T>())), ulp<T>());
}

// Out of range saturates to the largest magnitude with the right sign, and every event is counted.
TYPED_TEST(FixedPointTest, OverflowSaturatesAndIsCounted) {
  using T = TypeParam;
  const T big = largest<T>(), two = T(2);
  const u64 before = fixed_saturations_this_thread();
  EXPECT_EQ(big + big, big);
  EXPECT_EQ(-big - big, -big);
  EXPECT_EQ(big * two, big);
  EXPECT_EQ(-big * two, -big);
  EXPECT_EQ(T(1) / T(0), big);
  EXPECT_EQ(T(1e300), big);
  EXPECT_EQ(T(-1e300), -big);
  EXPECT_EQ(log(T(0)), -big);
  EXPECT_EQ(fixed_saturations_this_thread() - before, 8u);
  // In-range arithmetic counts nothing.
  const T one = T(1);
  EXPECT_EQ(exact(one + one * one - one / one), 1.0L);
  EXPECT_EQ(fixed_saturations_this_thread() - before, 8u);
}

TEST(FixedPoint, StorageIsTheSmallestFittingInteger) {
  static_assert(sizeof(Fixed<3, 5>) == 1);
  static_assert(sizeof(Fixed<4, 12>) == 2);
  static_assert(sizeof(Fixed<12, 12>) == 4);
  static_assert(sizeof(Fixed<16, 16>) == 4);
  static_assert(sizeof(Fixed<20, 20>) == 8);
  static_assert(sizeof(Fixed<32, 32>) == 8);
  static_assert(std::is_trivially_copyable_v<Fixed<16, 16>>);
  static_assert(constant<Fixed<16, 16>>(0.5).raw == 0x8000);
}

}  // namespace
}  // namespace pt
