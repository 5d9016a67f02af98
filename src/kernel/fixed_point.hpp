// Fixed<IntegerBits, FractionBits>: a signed, saturating fixed-point scalar for the kernels, with every function
// ScalarTraits needs computed in integer arithmetic, so a host render shows what a fixed-point datapath would draw.
#pragma once

#include <cmath>
#include <cstdint>
#include <type_traits>

#include "kernel/scalar.hpp"

#if !defined(__SIZEOF_INT128__)
#error "Fixed<> needs a 128-bit integer type for its 64-bit formats (GCC, Clang and nvcc provide __int128)"
#endif

namespace pt {

namespace fixed_detail {

using i64 = std::int64_t;
using i128 = __int128;
using u128 = unsigned __int128;

// The smallest signed integer holding `bits` bits, and the type its products and quotients are formed in.
template <int bits>
using Storage =
    std::conditional_t<bits <= 8, std::int8_t, std::conditional_t<bits <= 16, std::int16_t, std::conditional_t<bits <= 32, std::int32_t, i64>>>;
template <class S>
using Wide = std::conditional_t<(sizeof(S) <= 2), std::int32_t, std::conditional_t<sizeof(S) == 4, i64, i128>>;

// Saturation events of this host thread. Per-thread counters need no synchronisation; the CPU backend adds up
// each tile's increase. Device code does not count (a GPU render reports zero).
#if !defined(__CUDA_ARCH__)
inline std::uint64_t& saturation_counter() {
  thread_local std::uint64_t count = 0;
  return count;
}
#endif

PT_HD constexpr void note_saturation() {
#if !defined(__CUDA_ARCH__)
  if (!std::is_constant_evaluated()) ++saturation_counter();
#endif
}

// The functions below work in an internal format of 60 fraction bits in 64 bits (range +-8), wider than any
// supported format's fraction, so that a single rounding at the end dominates their error.
inline constexpr int kUnitBits = 60;
inline constexpr i64 kOne = i64(1) << kUnitBits;
inline constexpr i64 kPi = 3622009729038561421LL;          // pi * 2^60
inline constexpr i64 kHalfPi = 1811004864519280711LL;      // pi/2 * 2^60
inline constexpr i64 kQuarterPi = 905502432259640355LL;    // pi/4 * 2^60
inline constexpr i64 kLn2 = 799144290325165979LL;          // ln 2 * 2^60
inline constexpr i64 kTanEighthPi = 477555723559750801LL;  // (sqrt 2 - 1) * 2^60

PT_HD constexpr i64 mul_unit(i64 a, i64 b) { return static_cast<i64>((static_cast<i128>(a) * b + (i128(1) << (kUnitBits - 1))) >> kUnitBits); }
PT_HD constexpr i64 div_unit(i64 a, i64 b) { return static_cast<i64>((static_cast<i128>(a) << kUnitBits) / b); }

// Integer square root rounded to nearest, digit by digit (shifts, compares and subtractions only).
template <class U>
PT_HD constexpr U isqrt(U v) {
  U result = 0;
  U bit = U(1) << (sizeof(U) * 8 - 2);
  while (bit > v) bit >>= 2;
  U rest = v;
  while (bit != 0) {
    if (rest >= result + bit) {
      rest -= result + bit;
      result = (result >> 1) + bit;
    } else {
      result >>= 1;
    }
    bit >>= 2;
  }
  // rest = v - result^2; round up when v > (result + 1/2)^2 = result^2 + result + 1/4.
  return rest > result ? result + 1 : result;
}

// sin and cos of r, |r| <= pi/4, by their Taylor series in Horner form; 12 terms leave an error below 2^-70.
PT_HD constexpr void sin_cos_unit(i64 r, i64& s, i64& c) {
  const i64 r2 = mul_unit(r, r);
  i64 ps = kOne, pc = kOne;
  for (i64 n = 12; n >= 1; --n) {
    ps = kOne - mul_unit(r2, ps) / ((2 * n) * (2 * n + 1));
    pc = kOne - mul_unit(r2, pc) / ((2 * n - 1) * (2 * n));
  }
  s = mul_unit(r, ps);
  c = pc;
}

// atan(t) for 0 <= t <= 1: shifted by pi/4 above tan(pi/8), then the alternating series (30 terms suffice for
// |t| <= tan(pi/8)).
PT_HD constexpr i64 atan_unit(i64 t) {
  i64 base = 0;
  if (t > kTanEighthPi) {
    t = div_unit(t - kOne, t + kOne);
    base = kQuarterPi;
  }
  const i64 t2 = mul_unit(t, t);
  i64 sum = kOne / 61;
  for (i64 n = 29; n >= 0; --n) sum = kOne / (2 * n + 1) - mul_unit(t2, sum);
  return base + mul_unit(t, sum);
}

// atan2 from the magnitudes of y and x (same scale, any scale) and their signs.
PT_HD constexpr i64 atan2_unit(u128 ay, u128 ax, bool y_negative, bool x_negative) {
  if (ay == 0 && ax == 0) return 0;
  i64 angle = ay <= ax ? atan_unit(static_cast<i64>((ay << kUnitBits) / ax)) : kHalfPi - atan_unit(static_cast<i64>((ax << kUnitBits) / ay));
  if (x_negative) angle = kPi - angle;
  return y_negative ? -angle : angle;
}

}  // namespace fixed_detail

// Signed fixed point with IntegerBits (the sign bit included) and FractionBits: Q16.16 spans [-32768, 32768) in
// steps of 2^-16. The range is kept symmetric (the most negative code is never produced), so negation and abs
// never overflow. Every result out of range saturates and is counted; nothing wraps.
template <int IntegerBits, int FractionBits>
class Fixed {
  static_assert(IntegerBits >= 1 && FractionBits >= 1 && IntegerBits + FractionBits <= 64, "1 to 64 bits in all");
  static_assert(FractionBits <= fixed_detail::kUnitBits, "at most 60 fraction bits");

 public:
  using Storage = fixed_detail::Storage<IntegerBits + FractionBits>;
  using Wide = fixed_detail::Wide<Storage>;
  static constexpr int kIntegerBits = IntegerBits;
  static constexpr int kFractionBits = FractionBits;
  static constexpr int kTotalBits = IntegerBits + FractionBits;
  static constexpr Storage kMaxRaw = static_cast<Storage>((fixed_detail::i128(1) << (kTotalBits - 1)) - 1);

  Storage raw;

  Fixed() = default;  // trivial, like float: value-initialisation gives zero
  PT_HD static constexpr Fixed from_raw(Storage r) {
    Fixed f;
    f.raw = r;
    return f;
  }
  // Rounds to nearest; out of range saturates (NaN becomes 0).
  PT_HD constexpr explicit Fixed(double v) : raw(0) {
    const double scaled = v * static_cast<double>(fixed_detail::i128(1) << FractionBits);
    if (scaled >= static_cast<double>(kMaxRaw)) {
      raw = kMaxRaw;
      fixed_detail::note_saturation();
    } else if (scaled <= -static_cast<double>(kMaxRaw)) {
      raw = -kMaxRaw;
      fixed_detail::note_saturation();
    } else if (scaled == scaled) {
      raw = static_cast<Storage>(static_cast<fixed_detail::i64>(scaled + (scaled >= 0 ? 0.5 : -0.5)));
    }
  }
  PT_HD constexpr explicit Fixed(float v) : Fixed(static_cast<double>(v)) {}
  // Integers convert exactly (a shift) when in range.
  template <class I, std::enable_if_t<std::is_integral_v<I> && sizeof(I) <= 4, int> = 0>
  PT_HD constexpr explicit Fixed(I v) : raw(saturate(static_cast<fixed_detail::i128>(v) << FractionBits)) {}

  PT_HD constexpr explicit operator double() const { return static_cast<double>(raw) / static_cast<double>(fixed_detail::i128(1) << FractionBits); }
  PT_HD constexpr explicit operator float() const { return static_cast<float>(static_cast<double>(*this)); }
  // Truncates toward zero, as a float-to-integer conversion does.
  template <class I, std::enable_if_t<std::is_integral_v<I>, int> = 0>
  PT_HD constexpr explicit operator I() const {
    return static_cast<I>(static_cast<fixed_detail::i64>(raw) / (fixed_detail::i64(1) << FractionBits));
  }

  // Clamps a wide intermediate to the range, counting when it had to.
  template <class W>
  PT_HD static constexpr Storage saturate(W v) {
    if (v > static_cast<W>(kMaxRaw)) {
      fixed_detail::note_saturation();
      return kMaxRaw;
    }
    if (v < -static_cast<W>(kMaxRaw)) {
      fixed_detail::note_saturation();
      return -kMaxRaw;
    }
    return static_cast<Storage>(v);
  }
  // A value with `from_bits` fraction bits (from_bits >= FractionBits), rounded to nearest and saturated.
  PT_HD static constexpr Fixed from_wide(fixed_detail::i128 v, int from_bits) {
    const int shift = from_bits - FractionBits;
    if (shift > 0) v = (v + (fixed_detail::i128(1) << (shift - 1))) >> shift;
    return from_raw(saturate(v));
  }

  PT_HD constexpr Fixed operator-() const { return from_raw(static_cast<Storage>(-raw)); }
  PT_HD friend constexpr Fixed operator+(Fixed a, Fixed b) { return from_raw(saturate(static_cast<Wide>(a.raw) + b.raw)); }
  PT_HD friend constexpr Fixed operator-(Fixed a, Fixed b) { return from_raw(saturate(static_cast<Wide>(a.raw) - b.raw)); }
  // Products round to nearest (one adder more than truncation, and no drift towards minus infinity).
  PT_HD friend constexpr Fixed operator*(Fixed a, Fixed b) {
    const Wide product = static_cast<Wide>(a.raw) * b.raw;
    return from_raw(saturate((product + (static_cast<Wide>(1) << (FractionBits - 1))) >> FractionBits));
  }
  // Quotients truncate toward zero (a plain integer divider); division by zero saturates with the sign of a.
  PT_HD friend constexpr Fixed operator/(Fixed a, Fixed b) {
    if (b.raw == 0) {
      fixed_detail::note_saturation();
      return from_raw(a.raw < 0 ? -kMaxRaw : kMaxRaw);
    }
    return from_raw(saturate((static_cast<Wide>(a.raw) * (static_cast<Wide>(1) << FractionBits)) / b.raw));
  }
  PT_HD constexpr Fixed& operator+=(Fixed o) { return *this = *this + o; }
  PT_HD constexpr Fixed& operator-=(Fixed o) { return *this = *this - o; }
  PT_HD constexpr Fixed& operator*=(Fixed o) { return *this = *this * o; }
  PT_HD constexpr Fixed& operator/=(Fixed o) { return *this = *this / o; }

  PT_HD friend constexpr bool operator==(Fixed a, Fixed b) { return a.raw == b.raw; }
  PT_HD friend constexpr bool operator!=(Fixed a, Fixed b) { return a.raw != b.raw; }
  PT_HD friend constexpr bool operator<(Fixed a, Fixed b) { return a.raw < b.raw; }
  PT_HD friend constexpr bool operator>(Fixed a, Fixed b) { return a.raw > b.raw; }
  PT_HD friend constexpr bool operator<=(Fixed a, Fixed b) { return a.raw <= b.raw; }
  PT_HD friend constexpr bool operator>=(Fixed a, Fixed b) { return a.raw >= b.raw; }
};

template <class T>
struct IsFixed : std::false_type {};
template <int I, int F>
struct IsFixed<Fixed<I, F>> : std::true_type {};
template <class T>
inline constexpr bool is_fixed_v = IsFixed<T>::value;

#if !defined(__CUDA_ARCH__)
// Saturation events counted on the calling host thread so far.
inline std::uint64_t fixed_saturations_this_thread() { return fixed_detail::saturation_counter(); }
#endif

template <int I, int F>
struct ScalarTraits<Fixed<I, F>> {
  using T = Fixed<I, F>;
  using Raw = typename T::Storage;
  using i64 = fixed_detail::i64;
  using i128 = fixed_detail::i128;
  using u128 = fixed_detail::u128;
  // Narrow formats take the square root in 64 bits; 64-bit formats need 128.
  using Root = std::conditional_t<(sizeof(Raw) <= 4), std::uint64_t, u128>;

  // x < 0 gives 0 (the kernels only take roots of values that are non-negative up to rounding).
  PT_HD static constexpr T sqrt(T x) {
    if (x.raw <= 0) return T::from_raw(0);
    return T::from_raw(static_cast<Raw>(fixed_detail::isqrt<Root>(static_cast<Root>(x.raw) << F)));
  }
  // Range reduction by pi/2 in 128 bits, then the series on [-pi/4, pi/4]. The reduction constant carries
  // 2^-61 error, so |x| * 2^-61 / (pi/2) adds to the error for large arguments.
  PT_HD static constexpr void sin_cos(T x, i64& s, i64& c) {
    const i128 wide = static_cast<i128>(x.raw) * (i128(1) << (fixed_detail::kUnitBits - F));
    const i128 half = fixed_detail::kHalfPi / 2;
    const i128 k = (wide + (wide >= 0 ? half : -half)) / fixed_detail::kHalfPi;
    const i64 r = static_cast<i64>(wide - k * fixed_detail::kHalfPi);
    i64 sr, cr;
    fixed_detail::sin_cos_unit(r, sr, cr);
    switch (static_cast<int>(k & 3)) {  // two's complement: k & 3 is k mod 4 for negative k too
      case 0:
        s = sr;
        c = cr;
        break;
      case 1:
        s = cr;
        c = -sr;
        break;
      case 2:
        s = -sr;
        c = -cr;
        break;
      default:
        s = -cr;
        c = sr;
        break;
    }
  }
  PT_HD static constexpr T sin(T x) {
    i64 s, c;
    sin_cos(x, s, c);
    return T::from_wide(s, fixed_detail::kUnitBits);
  }
  PT_HD static constexpr T cos(T x) {
    i64 s, c;
    sin_cos(x, s, c);
    return T::from_wide(c, fixed_detail::kUnitBits);
  }
  PT_HD static constexpr void cos_sin_turns(T turns, T& c, T& s) {
    const T angle = T(2.0) * T(3.14159265358979323846) * turns;
    i64 sw, cw;
    sin_cos(angle, sw, cw);
    c = T::from_wide(cw, fixed_detail::kUnitBits);
    s = T::from_wide(sw, fixed_detail::kUnitBits);
  }
  PT_HD static constexpr T atan2(T y, T x) {
    const u128 ay = static_cast<u128>(y.raw < 0 ? -static_cast<i128>(y.raw) : static_cast<i128>(y.raw));
    const u128 ax = static_cast<u128>(x.raw < 0 ? -static_cast<i128>(x.raw) : static_cast<i128>(x.raw));
    return T::from_wide(fixed_detail::atan2_unit(ay, ax, y.raw < 0, x.raw < 0), fixed_detail::kUnitBits);
  }
  // asin x = atan2(x, sqrt(1 - x^2)), with the root taken in the internal format; |x| > 1 is clamped.
  PT_HD static constexpr T asin(T x) {
    const i64 one_raw = i64(1) << F;
    const i64 clamped = x.raw > one_raw ? one_raw : (x.raw < -one_raw ? -one_raw : static_cast<i64>(x.raw));
    const i64 u = clamped * (i64(1) << (fixed_detail::kUnitBits - F));
    const i64 c2 = fixed_detail::kOne - fixed_detail::mul_unit(u, u);
    const i64 c = static_cast<i64>(fixed_detail::isqrt<u128>(static_cast<u128>(c2 > 0 ? c2 : 0) << fixed_detail::kUnitBits));
    return T::from_wide(fixed_detail::atan2_unit(static_cast<u128>(u < 0 ? -u : u), static_cast<u128>(c), u < 0, false), fixed_detail::kUnitBits);
  }
  // x = m 2^e with m in [1, 2): log x = e ln 2 + 2 atanh((m - 1) / (m + 1)), the series in z^2 <= 1/9.
  // log of x <= 0 saturates to the most negative value.
  PT_HD static constexpr T log(T x) {
    if (x.raw <= 0) {
      fixed_detail::note_saturation();
      return T::from_raw(-T::kMaxRaw);
    }
    int top = 0;
    for (i64 v = x.raw; v > 1; v >>= 1) ++top;
    const i64 m = top <= fixed_detail::kUnitBits ? static_cast<i64>(x.raw) << (fixed_detail::kUnitBits - top)
                                                 : static_cast<i64>(x.raw) >> (top - fixed_detail::kUnitBits);
    const i64 z = fixed_detail::div_unit(m - fixed_detail::kOne, m + fixed_detail::kOne);
    const i64 z2 = fixed_detail::mul_unit(z, z);
    i64 sum = fixed_detail::kOne / 41;
    for (i64 n = 19; n >= 0; --n) sum = fixed_detail::kOne / (2 * n + 1) + fixed_detail::mul_unit(z2, sum);
    const i128 result = static_cast<i128>(top - F) * fixed_detail::kLn2 + 2 * static_cast<i128>(fixed_detail::mul_unit(z, sum));
    return T::from_wide(result, fixed_detail::kUnitBits);
  }
  // exp x = 2^k exp(r) with k = round(x / ln 2) and |r| <= ln 2 / 2, the series of exp(r) in the internal format.
  // Results below half a step round to 0; above the range they saturate.
  PT_HD static constexpr T exp(T x) {
    const i128 wide = static_cast<i128>(x.raw) * (i128(1) << (fixed_detail::kUnitBits - F));
    const i128 half = fixed_detail::kLn2 / 2;
    const i128 k = (wide + (wide >= 0 ? half : -half)) / fixed_detail::kLn2;
    const i64 r = static_cast<i64>(wide - k * fixed_detail::kLn2);
    i64 sum = fixed_detail::kOne;
    for (i64 n = 20; n >= 1; --n) sum = fixed_detail::kOne + fixed_detail::mul_unit(r, sum) / n;
    const i128 from_bits = fixed_detail::kUnitBits - k;  // sum 2^k, read with this many fraction bits
    if (from_bits > 120) return T::from_raw(0);
    if (from_bits >= F) return T::from_wide(sum, static_cast<int>(from_bits));
    const i128 shift = F - from_bits;
    if (shift > 62) {
      fixed_detail::note_saturation();
      return T::from_raw(T::kMaxRaw);
    }
    return T::from_wide(static_cast<i128>(sum) << shift, F);
  }
  PT_HD static constexpr T floor(T x) {
    const i64 floored = static_cast<i64>(x.raw) & ~((i64(1) << F) - 1);
    return T::from_raw(T::saturate(floored));
  }
  PT_HD static constexpr T abs(T x) { return x.raw < 0 ? -x : x; }
  PT_HD static constexpr T min(T a, T b) { return a < b ? a : b; }
  PT_HD static constexpr T max(T a, T b) { return a > b ? a : b; }
  PT_HD static constexpr bool is_finite(T) { return true; }  // saturation leaves no non-finite values
  PT_HD static constexpr T largest() { return T::from_raw(T::kMaxRaw); }
  // The 24 random bits placed at the binary point: a shift, exact when F >= 24, truncated otherwise.
  PT_HD static constexpr T from_unit_bits(u32 bits24) {
    if constexpr (F >= 24)
      return T::from_raw(static_cast<Raw>(static_cast<i64>(bits24) << (F - 24)));
    else
      return T::from_raw(static_cast<Raw>(bits24 >> (24 - F)));
  }
  // Every operation rounds to within one step (products to half a step, quotients truncate), whatever the size of
  // the values; but unit-size values (directions, normals) carry that step as a relative error into the lengths
  // they multiply, so the bound has a relative part of one step per unit of magnitude as well.
  PT_HD static constexpr T rounding_unit() { return T::from_raw(1); }
  PT_HD static constexpr T rounding_step() { return T::from_raw(1); }
  // BVH slab distances as (bound - origin) * (1 / d). The float form bound * (1 / d) - origin * (1 / d) would
  // saturate both products for near-axis directions and subtract them to zero. Here an out-of-range distance
  // means "beyond anything in the scene", a correct answer rather than an overflow, so it clamps uncounted.
  PT_HD static constexpr T slab_reciprocal(T d) {
    if (d.raw == 0) return T::from_raw(T::kMaxRaw);
    return T::from_raw(clamp_to_range((i128(1) << (2 * F)) / d.raw));
  }
  PT_HD static constexpr T slab_origin_term(T origin, T) { return origin; }
  PT_HD static constexpr T slab_distance(T bound, T reciprocal, T origin) {
    const i128 product = static_cast<i128>((bound - origin).raw) * reciprocal.raw;
    return T::from_raw(clamp_to_range((product + (i128(1) << (F - 1))) >> F));
  }
  // Intersection tests (kernel/shapes.hpp) in formats of up to 32 bits keep their products exact: a product of two
  // values has 2F fraction bits, and of three 3F, in at most 100 bits, which 128-bit integers hold. Sums of
  // products (dot and cross products) are then exact, nothing squared can overflow, and each result is rounded once.
  // A datapath forms full-width products anyway; it keeps them wide until the quotient or the root. 64-bit formats
  // would need 192 bits and keep the rounding of every operation.
  static constexpr bool kExactProducts = sizeof(Raw) <= 4;
  // Light densities carried as their reciprocals where the format has more fraction bits than integer bits
  // (kernel/lights.hpp): then the reciprocal's range covers far more of the densities lights have.
  static constexpr bool kReciprocalLightDensity = kExactProducts && F > I;
  using Exact = i128;
  PT_HD static constexpr i128 exact(T x) { return x.raw; }
  // A value with 2F fraction bits, rounded to nearest (half up, as products are) and saturated.
  PT_HD static constexpr T round_exact(i128 v) { return T::from_wide(v, 2 * F); }
  // The root of a value with 2F fraction bits (0 for a negative one), rounded to nearest.
  PT_HD static constexpr T exact_sqrt(i128 v) {
    if (v <= 0) return T::from_raw(0);
    // The same root either way; 64 bits where the value fits, the common case, which takes half the steps.
    if (v < (i128(1) << 64)) return T::from_raw(clamp_to_range(static_cast<i128>(fixed_detail::isqrt<std::uint64_t>(static_cast<std::uint64_t>(v)))));
    return T::from_raw(clamp_to_range(static_cast<i128>(fixed_detail::isqrt<u128>(static_cast<u128>(v)))));
  }
  // The root of a value with 4F fraction bits (0 for a negative one), rounded to nearest and kept exact, with 2F.
  PT_HD static constexpr i128 exact_root(i128 v) { return v <= 0 ? 0 : static_cast<i128>(fixed_detail::isqrt<u128>(static_cast<u128>(v))); }
  // The unit vector along (x, y, z) (exact values with 2F fraction bits, not all zero) and its length, each rounded
  // once: the vector is first shifted right until its components have at most 30 bits (its direction keeps 29 bits
  // at least, beyond any format of 32), so that the squares and their sum fit 64 bits. A triangle's normal from its
  // edges' exact cross product survives edges whose cross product is below one step.
  PT_HD static constexpr void exact_unit(i128 x, i128 y, i128 z, T& ux, T& uy, T& uz, T& length) {
    auto magnitude = [](i128 v) { return v < 0 ? -v : v; };
    i128 largest_component = magnitude(x) > magnitude(y) ? magnitude(x) : magnitude(y);
    if (magnitude(z) > largest_component) largest_component = magnitude(z);
    int shift = 0;
    while ((largest_component >> shift) >= (i128(1) << 30)) ++shift;
    const i64 sx = static_cast<i64>(x >> shift), sy = static_cast<i64>(y >> shift), sz = static_cast<i64>(z >> shift);
    const std::uint64_t norm = fixed_detail::isqrt<std::uint64_t>(static_cast<std::uint64_t>(sx * sx + sy * sy + sz * sz));
    if (norm == 0) {
      ux = uy = uz = length = T::from_raw(0);
      return;
    }
    ux = T::from_raw(clamp_to_range((static_cast<i128>(sx) << F) / static_cast<i128>(norm)));
    uy = T::from_raw(clamp_to_range((static_cast<i128>(sy) << F) / static_cast<i128>(norm)));
    uz = T::from_raw(clamp_to_range((static_cast<i128>(sz) << F) / static_cast<i128>(norm)));
    // norm 2^shift has 2F fraction bits; the length F.
    const int down = F - shift;
    const i128 wide_length =
        down >= 0 ? (static_cast<i128>(norm) + (down > 0 ? (i128(1) << (down - 1)) : 0)) >> down : static_cast<i128>(norm) << -down;
    length = T::from_raw(T::saturate(wide_length));
  }
  // numerator / denominator (both with the same fraction bits, the denominator nonzero), truncated toward zero as
  // a divider does. A quotient out of range is a distance beyond anything in the scene, so it clamps uncounted.
  // A zero denominator gives the largest value of the numerator's sign, as an infinite distance or density would.
  PT_HD static constexpr T exact_quotient(i128 numerator, i128 denominator) {
    if (denominator == 0) return T::from_raw(numerator < 0 ? -T::kMaxRaw : T::kMaxRaw);
    return T::from_raw(clamp_to_range(numerator * (i128(1) << F) / denominator));
  }
  // Quotients whose use tells the hardware more (tools/hardware reads these names from the kernel's dataflow): one
  // that lies in [0, 1] wherever it is used (a hit's barycentric coordinates; a divider of F + 1 quotient bits), and
  // one by a quad's extent, whose raw value is a power of two, of a numerator that is not negative where it is used
  // (a shift). Here both are exact_quotient.
  PT_HD static constexpr T exact_fraction(i128 numerator, i128 denominator) { return exact_quotient(numerator, denominator); }
  PT_HD static constexpr T exact_quotient_by_extent(i128 numerator, T extent) {
    return exact_quotient(numerator, exact(extent) * exact(T(1)));
  }
  // A quad stores its dual edges times a power of two near the edge's length (Quad in kernel/shapes.hpp): sizes
  // near 1, which keep every fraction bit, where 1 / length (1/555 has 7 significant bits in Q16.16) would not.
  // Within the format's range: at least one step, at most a quarter of the largest value.
  // Formats without exact products keep extents of 1 (the dual edges themselves), as floating point does.
  static double quad_extent(double length) {
    if constexpr (!kExactProducts) return 1;
    if (!(length > 0) || !(length < 1e300)) return 1;
    int exponent = 0;
    (void)std::frexp(length, &exponent);  // length = m 2^exponent, m in [0.5, 1)
    exponent -= 1;                        // 2^exponent <= length < 2^(exponent + 1)
    if (exponent < -F) exponent = -F;
    if (exponent > I - 3) exponent = I - 3;
    return std::ldexp(1.0, exponent);
  }
  // (index + offset) / count in integers, truncated as a divider does: the index and the count need not fit the
  // format (a 160-pixel-wide image in Q8.24, whose largest value is 128).
  PT_HD static constexpr T index_fraction(u32 index, T offset, u32 count) {
    return T::from_raw(clamp_to_range(((static_cast<i128>(index) << F) + offset.raw) / static_cast<i128>(count)));
  }
  // The texel position w count - 1/2 in integers: the count (an image's width, 1024 where Q8.24 reaches 128) need not
  // fit the format, and the index and fraction are exact.
  PT_HD static constexpr void texel_position(T w, u32 count, i32& index, T& fraction) {
    const i128 position = static_cast<i128>(w.raw) * count - (i128(1) << (F - 1));
    index = static_cast<i32>(position >> F);
    fraction = T::from_raw(static_cast<Raw>(position & ((i128(1) << F) - 1)));
  }
  PT_HD static constexpr Raw clamp_to_range(i128 v) {
    return v > T::kMaxRaw ? T::kMaxRaw : (v < -static_cast<i128>(T::kMaxRaw) ? -T::kMaxRaw : static_cast<Raw>(v));
  }
};

}  // namespace pt
