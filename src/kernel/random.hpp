// Counter-based random numbers: every draw is a pure function of (seed, pixel, sample, bounce, dimension),
// so an image never depends on thread count, tile order or backend, and no generator state is shared.
#pragma once

#include "kernel/vec3.hpp"

namespace pt {

// The 64-bit finaliser of MurmurHash3: a bijection whose output bits all depend on all input bits.
PT_HD inline u64 mix64(u64 x) {
  x ^= x >> 33;
  x *= 0xff51afd7ed558ccdULL;
  x ^= x >> 33;
  x *= 0xc4ceb9fe1a85ec53ULL;
  x ^= x >> 33;
  return x;
}

// Which random dimension each decision of a bounce uses. Fixed numbers, so that two integrators that make the
// same decisions draw the same numbers. A pair dimension gives the two coordinates of a 2-D sample from one hash
// (SampleRandom::uniform_pair).
enum RandomDimension : u32 {
  kDimPixel = 0,  // pair: jitter in x and y
  kDimLens = 2,   // pair: point on the lens
  kDimTime = 4,
  kDimScatter = 8,         // pair: scattered direction
  kDimScatterChoice = 10,  // reflect or refract
  kDimRoulette = 12,
  kDimLobe = 14,           // which lobe of a layered material (metallic-roughness: specular or diffuse) draws the direction
  kDimLightChoice = 20,    // next-event estimation: the light's index (its bits) ...
  kDimLightAlias = 21,     // ... the alias table's choice between the entry and its alias
  kDimLightPoint = 22,     // pair: the point on the light (or the direction towards it)
  kDimLightTriangle = 24,  // the triangle of an emitting mesh
  kDimLightRoulette = 25,  // whether a light sample that can add little is drawn at all (kernel/integrator.hpp) ...
  kDimShadowRoulette = 26, // ... and whether its shadow ray is traced, once the material's side is known
  // A medium draws its free-flight distance from dimension kDimMediumBase + its primitive index, so the draw
  // does not depend on the order in which the acceleration structure visits primitives.
  kDimMediumBase = 64,
};

// Bit i of the result is bit 31 - i of x.
PT_HD inline u32 reverse_bits(u32 x) {
  x = (x << 16) | (x >> 16);
  x = ((x & 0x00ff00ffu) << 8) | ((x >> 8) & 0x00ff00ffu);
  x = ((x & 0x0f0f0f0fu) << 4) | ((x >> 4) & 0x0f0f0f0fu);
  x = ((x & 0x33333333u) << 2) | ((x >> 2) & 0x33333333u);
  x = ((x & 0x55555555u) << 1) | ((x >> 1) & 0x55555555u);
  return x;
}

// A random bijection of 32-bit words in which each output bit depends only on the input bits below it and on the
// seed (additions, odd multiplications and x ^= x * even all carry information upwards only). Applied to a binary
// fraction with its bits reversed, that is Owen's nested uniform scrambling, in the hash-based form of Burley,
// "Practical Hash-based Owen Scrambling" (JCGT 2020), with the multipliers Vegdahl proposed for it.
PT_HD inline u32 owen_hash(u32 x, u32 seed) {
  x ^= x * 0x3d20adeau;
  x += seed;
  x *= (seed >> 16) | 1u;
  x ^= x * 0x05526c56u;
  x ^= x * 0x53a22864u;
  return x;
}

// Owen scrambling of the binary fraction x / 2^32: which half it falls in is flipped at random, then which quarter
// within that half, and so on, each choice keyed by the digits above it. Every scrambled point is uniform on
// [0, 1), and a set of points that was stratified stays stratified.
PT_HD inline u32 owen_scramble(u32 x, u32 seed) { return reverse_bits(owen_hash(reverse_bits(x), seed)); }

// The second dimension of Sobol's sequence (the first is the bit reversal of the index), with its bits reversed:
// digit r of the point (bit r of the result) is the parity of the index's bits i whose binomial(i, r) is odd (the
// generator is the Pascal matrix modulo 2), which by Lucas' theorem are the i whose set bits include r's. Summing
// over supersets one bit of the position at a time takes five shifts instead of a loop over the 32 bits.
PT_HD inline u32 sobol_second_reversed(u32 index) {
  index ^= (index >> 1) & 0x55555555u;
  index ^= (index >> 2) & 0x33333333u;
  index ^= (index >> 4) & 0x0f0f0f0fu;
  index ^= (index >> 8) & 0x00ff00ffu;
  index ^= (index >> 16) & 0x0000ffffu;
  return index;
}

// How the samples of a pixel are placed in each dimension of the path.
enum class SamplerKind : u32 {
  // Each number its own hash of (seed, pixel, sample, bounce, dimension): samples are independent.
  kIndependent = 0,
  // The samples of a pixel, in each dimension pair (a pair dimension) or single dimension, are the points of
  // Sobol's (0, 2)-sequence (the van der Corput sequence), Owen-scrambled and visited in a random order, both keyed
  // by (seed, pixel, bounce, dimension). The first 2^k samples of a pixel cover each of the 2^k strata of every
  // elementary partition once, so smooth integrands and edges converge faster than 1 / sqrt(samples); different
  // dimensions are shuffled apart, so they do not correlate (Burley 2020).
  kSobol = 1,
};

// The random stream of one sample of one pixel, indexed by (bounce, dimension).
struct SampleRandom {
  u64 key;     // the hash of seed and pixel (and, for independent samples, the sample)
  u32 sample;  // the sample's index within the pixel's sequence (stratified samples)
  u32 stratified;

  PT_HD static SampleRandom make(u32 seed, u32 pixel, u32 sample, SamplerKind kind = SamplerKind::kIndependent) {
    const u64 seed_and_pixel = (static_cast<u64>(seed) << 32) | pixel;
    const u64 pixel_key = mix64(seed_and_pixel + 0x9e3779b97f4a7c15ULL);
    if (kind == SamplerKind::kSobol) return SampleRandom{pixel_key, sample, 1u};
    return SampleRandom{mix64(pixel_key ^ (static_cast<u64>(sample) * 0xd1b54a32d192ed03ULL)), sample, 0u};
  }

  PT_HD u64 hash(u32 bounce, u32 dimension) const {
    const u64 counter = (static_cast<u64>(bounce) << 32) | dimension;
    return mix64(key + (counter + 1) * 0x9e3779b97f4a7c15ULL);
  }

  // The position of this sample in the pixel's sequence for one dimension: the sample index, Owen-scrambled as a
  // base-2 integer (digit i keyed by the digits below it), so that the first 2^k samples take the indices of one
  // aligned block of 2^k, whose Sobol points form a (0, k, 2)-net.
  PT_HD u32 shuffled_index(u32 seed) const { return owen_scramble(sample, seed); }

  // The Owen-scrambled Sobol points of an index. Scrambling works on the reversed bits of a point, which for the
  // first dimension (the van der Corput sequence) are the index itself.
  PT_HD static u32 scrambled_first(u32 index, u32 seed) { return reverse_bits(owen_hash(index, seed)); }
  PT_HD static u32 scrambled_second(u32 index, u32 seed) { return reverse_bits(owen_hash(sobol_second_reversed(index), seed)); }

  PT_HD u32 bits(u32 bounce, u32 dimension) const {
    const u64 h = hash(bounce, dimension);
    if (!stratified) return static_cast<u32>(h >> 32);
    return scrambled_first(shuffled_index(static_cast<u32>(h)), static_cast<u32>(h >> 32));
  }

  // Uniform in [0, 1), with 24 random bits (exactly representable in every supported scalar type).
  template <class T>
  PT_HD T uniform(u32 bounce, u32 dimension) const {
    return ScalarTraits<T>::from_unit_bits(bits(bounce, dimension) >> 8);
  }

  // A 2-D sample, its two coordinates stratified jointly where samples are. Independent samples take both from one
  // hash (the first is uniform(bounce, dimension), the second 24 bits of the hash's lower half; every output bit of
  // the mix depends on every input bit): half the hashing of two draws. Likewise
  // a stratified pair takes its second scrambling key from a multiple of the hash (whose high half depends on all its
  // bits).
  template <class T>
  PT_HD void uniform_pair(u32 bounce, u32 dimension, T& first, T& second) const {
    const u64 h = hash(bounce, dimension);
    if (!stratified) {
      first = ScalarTraits<T>::from_unit_bits(static_cast<u32>(h >> 40));
      second = ScalarTraits<T>::from_unit_bits(static_cast<u32>(h >> 8) & 0xffffffu);
      return;
    }
    const u32 index = shuffled_index(static_cast<u32>(h));
    first = ScalarTraits<T>::from_unit_bits(scrambled_first(index, static_cast<u32>(h >> 32)) >> 8);
    second = ScalarTraits<T>::from_unit_bits(scrambled_second(index, static_cast<u32>((h * 0xd1b54a32d192ed03ULL) >> 32)) >> 8);
  }
};

// The draws of one bounce: fixes the bounce so materials only name dimensions.
struct BounceRandom {
  const SampleRandom* stream;
  u32 bounce;
  template <class T>
  PT_HD T uniform(u32 dimension) const {
    return stream->template uniform<T>(bounce, dimension);
  }
  template <class T>
  PT_HD void uniform_pair(u32 dimension, T& first, T& second) const {
    stream->uniform_pair(bounce, dimension, first, second);
  }
};

// Uniformly distributed direction on the unit sphere.
template <class T>
PT_HD inline Vec3<T> uniform_unit_vector(T u1, T u2) {
  const T z = T(1) - constant<T>(2) * u1;
  const T r = sqrt(max(T(0), T(1) - z * z));
  T c, s;
  cos_sin_turns(u2, c, s);
  return {r * c, r * s, z};
}

// Uniformly distributed point in the unit disk (polar mapping with the square root for uniform area).
template <class T>
PT_HD inline Vec3<T> uniform_in_unit_disk(T u1, T u2) {
  const T r = sqrt(u1);
  T c, s;
  cos_sin_turns(u2, c, s);
  return {r * c, r * s, T(0)};
}

}  // namespace pt
