// The scalar type's traits: every transcendental and constant a kernel needs goes through here, so a new
// number format (double, fixed point) plugs in by specialising ScalarTraits, without touching any kernel.
#pragma once

#include <cfloat>
#include <cmath>
#include <type_traits>

#include "kernel/platform.hpp"

namespace pt {

template <class T>
struct ScalarTraits;

template <>
struct ScalarTraits<float> {
  PT_HD static float sqrt(float x) { return ::sqrtf(x); }
  PT_HD static float sin(float x) { return ::sinf(x); }
  PT_HD static float cos(float x) { return ::cosf(x); }
  PT_HD static float atan2(float y, float x) { return ::atan2f(y, x); }
  PT_HD static float asin(float x) { return ::asinf(x); }
  PT_HD static float log(float x) { return ::logf(x); }
  PT_HD static float exp(float x) { return ::expf(x); }
  PT_HD static float floor(float x) { return ::floorf(x); }
  PT_HD static float abs(float x) { return ::fabsf(x); }
  // Comparisons rather than fminf/fmaxf: those are library calls on x86-64 (they must order NaN), which cost
  // half the render time in the BVH slab test; the kernels keep NaN out of the values they compare.
  PT_HD static float min(float a, float b) { return a < b ? a : b; }
  PT_HD static float max(float a, float b) { return a > b ? a : b; }
  // Comparisons only: NaN fails both, infinities fail the range. (An arithmetic test such as x - x == 0 is not
  // safe: after inlining, FMA contraction may evaluate the two x differently and reject finite values.)
  PT_HD static bool is_finite(float x) { return x >= -FLT_MAX && x <= FLT_MAX; }
  PT_HD static float largest() { return FLT_MAX; }
  PT_HD static float from_unit_bits(u32 bits24) { return static_cast<float>(bits24) * 0x1p-24f; }
  // The rounding error of one operation: relative (half an ulp, the unit roundoff) plus absolute (none for floating
  // point). Error bounds of hit points are built from these (robust ray spawning, kernel/shapes.hpp).
  PT_HD static float rounding_unit() { return 0x1p-24f; }
  PT_HD static float rounding_step() { return 0.0f; }
  // cos and sin of a fraction of a full turn, 2 pi turns, for sampling directions. A quarter turn is taken off at a
  // time (exact in float) and the rest, within 1/8 turn, goes through short Taylor polynomials: within 2e-7 of
  // the library's, at a fraction of the cost of its call (sampling draws one angle per bounce).
  PT_HD static void cos_sin_turns(float turns, float& c, float& s) {
    const float quarters = turns * 4.0f;
    const float nearest = ::floorf(quarters + 0.5f);
    const float a = (quarters - nearest) * 1.57079632679489662f;  // |a| <= pi / 4
    const float a2 = a * a;
    const float sa = a * (1.0f + a2 * (-1.0f / 6 + a2 * (1.0f / 120 + a2 * (-1.0f / 5040 + a2 * (1.0f / 362880)))));
    const float ca = 1.0f + a2 * (-0.5f + a2 * (1.0f / 24 + a2 * (-1.0f / 720 + a2 * (1.0f / 40320))));
    // The quadrant (whole quarter turns) is random, so it is applied with bit masks rather than branches, which
    // would be mispredicted every other time: an odd quadrant swaps the pair and negates the new cosine, the
    // quadrants 2 and 3 negate both.
    const u32 quadrant = static_cast<u32>(static_cast<int>(nearest)) & 3u;
    const u32 swap = 0u - (quadrant & 1u);
    const u32 sign = (quadrant & 2u) << 30;
    const u32 sin_bits = bits_of(sa), cos_bits = bits_of(ca);
    c = float_of(((cos_bits & ~swap) | ((sin_bits ^ 0x80000000u) & swap)) ^ sign);
    s = float_of(((sin_bits & ~swap) | (cos_bits & swap)) ^ sign);
  }
  PT_HD static u32 bits_of(float x) {
    u32 bits;
    __builtin_memcpy(&bits, &x, sizeof bits);
    return bits;
  }
  PT_HD static float float_of(u32 bits) {
    float x;
    __builtin_memcpy(&x, &bits, sizeof x);
    return x;
  }
  // BVH slab distances, (bound - origin) / direction, as bound * (1 / d) - origin * (1 / d): one fused multiply-add
  // per plane. A zero component is nudged so that the reciprocal stays finite (no inf - inf).
  PT_HD static float slab_reciprocal(float d) { return 1.0f / (::fabsf(d) > 1e-20f ? d : (d < 0.0f ? -1e-20f : 1e-20f)); }
  PT_HD static float slab_origin_term(float origin, float reciprocal) { return origin * reciprocal; }
  PT_HD static float slab_distance(float bound, float reciprocal, float origin_term) { return bound * reciprocal - origin_term; }
  // Floating point rounds every product (kernel/shapes.hpp has the formulations of fixed point, which keeps them
  // exact), and stores a quad's dual edges as they are (an extent of 1, see Quad).
  static constexpr bool kExactProducts = false;
  static constexpr bool kReciprocalLightDensity = false;  // light densities as they are (kernel/lights.hpp)
  static double quad_extent(double) { return 1; }
  // (index + offset) / count: where a sample lies across the image, for pixel `index` of `count`.
  PT_HD static float index_fraction(u32 index, float offset, u32 count) { return (static_cast<float>(index) + offset) / static_cast<float>(count); }
  // Where w (in [0, 1]) falls among `count` texels centred at (i + 1/2) / count: the texel at or below it (-1 below
  // the first centre) and the fraction of the way to the next.
  PT_HD static void texel_position(float w, u32 count, i32& index, float& fraction) {
    const float x = w * static_cast<float>(count) - 0.5f;
    const float below = ::floorf(x);
    index = static_cast<i32>(below);
    fraction = x - below;
  }
};

template <>
struct ScalarTraits<double> {
  PT_HD static double sqrt(double x) { return ::sqrt(x); }
  PT_HD static double sin(double x) { return ::sin(x); }
  PT_HD static double cos(double x) { return ::cos(x); }
  PT_HD static double atan2(double y, double x) { return ::atan2(y, x); }
  PT_HD static double asin(double x) { return ::asin(x); }
  PT_HD static double log(double x) { return ::log(x); }
  PT_HD static double exp(double x) { return ::exp(x); }
  PT_HD static double floor(double x) { return ::floor(x); }
  PT_HD static double abs(double x) { return ::fabs(x); }
  PT_HD static double min(double a, double b) { return a < b ? a : b; }
  PT_HD static double max(double a, double b) { return a > b ? a : b; }
  PT_HD static bool is_finite(double x) { return x >= -DBL_MAX && x <= DBL_MAX; }
  PT_HD static double largest() { return DBL_MAX; }
  PT_HD static double from_unit_bits(u32 bits24) { return static_cast<double>(bits24) * 0x1p-24; }
  PT_HD static double rounding_unit() { return 0x1p-53; }
  PT_HD static double rounding_step() { return 0.0; }
  PT_HD static void cos_sin_turns(double turns, double& c, double& s) {
    const double angle = 6.283185307179586477 * turns;
    c = ::cos(angle);
    s = ::sin(angle);
  }
  PT_HD static double slab_reciprocal(double d) { return 1.0 / (::fabs(d) > 1e-20 ? d : (d < 0.0 ? -1e-20 : 1e-20)); }
  PT_HD static double slab_origin_term(double origin, double reciprocal) { return origin * reciprocal; }
  PT_HD static double slab_distance(double bound, double reciprocal, double origin_term) { return bound * reciprocal - origin_term; }
  static constexpr bool kExactProducts = false;
  static constexpr bool kReciprocalLightDensity = false;
  static double quad_extent(double) { return 1; }
  PT_HD static double index_fraction(u32 index, double offset, u32 count) {
    return (static_cast<double>(index) + offset) / static_cast<double>(count);
  }
  PT_HD static void texel_position(double w, u32 count, i32& index, double& fraction) {
    const double x = w * static_cast<double>(count) - 0.5;
    const double below = ::floor(x);
    index = static_cast<i32>(below);
    fraction = x - below;
  }
};

// Short names used throughout the kernels; they only forward to the traits.
template <class T>
PT_HD inline T sqrt(T x) {
  return ScalarTraits<T>::sqrt(x);
}
template <class T>
PT_HD inline T sin(T x) {
  return ScalarTraits<T>::sin(x);
}
template <class T>
PT_HD inline T cos(T x) {
  return ScalarTraits<T>::cos(x);
}
// cos and sin of 2 pi turns.
template <class T>
PT_HD inline void cos_sin_turns(T turns, T& c, T& s) {
  ScalarTraits<T>::cos_sin_turns(turns, c, s);
}
template <class T>
PT_HD inline T atan2(T y, T x) {
  return ScalarTraits<T>::atan2(y, x);
}
template <class T>
PT_HD inline T asin(T x) {
  return ScalarTraits<T>::asin(x);
}
template <class T>
PT_HD inline T log(T x) {
  return ScalarTraits<T>::log(x);
}
template <class T>
PT_HD inline T exp(T x) {
  return ScalarTraits<T>::exp(x);
}
template <class T>
PT_HD inline T floor(T x) {
  return ScalarTraits<T>::floor(x);
}
template <class T>
PT_HD inline T abs(T x) {
  return ScalarTraits<T>::abs(x);
}
template <class T>
PT_HD inline T min(T a, T b) {
  return ScalarTraits<T>::min(a, b);
}
template <class T>
PT_HD inline T max(T a, T b) {
  return ScalarTraits<T>::max(a, b);
}
template <class T>
PT_HD inline bool is_finite(T x) {
  return ScalarTraits<T>::is_finite(x);
}
template <class T>
PT_HD inline T largest() {
  return ScalarTraits<T>::largest();
}
template <class T>
PT_HD inline T clamp(T x, T lo, T hi) {
  return min(max(x, lo), hi);
}
// A bound on the rounding error of `roundings` operations on values of size `magnitude`: relative for floating
// point, absolute (a step each) for fixed point.
template <class T>
PT_HD inline T rounding_error(T magnitude, T roundings) {
  // Constants first, so that they fold. Floating point has no absolute part: adding its zero would still cost an
  // addition per value (x + 0 is not x for x = -0, so the compiler keeps it).
  if constexpr (std::is_floating_point_v<T>)
    return magnitude * (roundings * ScalarTraits<T>::rounding_unit());
  else
    return magnitude * (roundings * ScalarTraits<T>::rounding_unit()) + roundings * ScalarTraits<T>::rounding_step();
}

// Constants are written in double and converted once, so that a scalar type only needs a conversion from double.
template <class T>
PT_HD constexpr T constant(double value) {
  return static_cast<T>(value);
}
template <class T>
PT_HD constexpr T pi() {
  return constant<T>(3.14159265358979323846);
}

}  // namespace pt
