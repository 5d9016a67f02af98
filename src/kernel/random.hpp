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
  kDimScatter = 8,  // pair: scattered direction
  kDimScatterChoice = 10,  // reflect or refract
  kDimRoulette = 12,
  kDimLobe = 14,  // which lobe of a layered material (metallic-roughness: specular or diffuse) draws the direction
  kDimLightChoice = 20,    // next-event estimation: the light's index (its bits) ...
  kDimLightAlias = 21,     // ... the alias table's choice between the entry and its alias
  kDimLightPoint = 22,     // pair: the point on the light (or the direction towards it)
  kDimLightTriangle = 24,  // the triangle of an emitting mesh
  // A medium draws its free-flight distance from dimension kDimMediumBase + its primitive index, so the draw
  // does not depend on the order in which the acceleration structure visits primitives.
  kDimMediumBase = 64,
};

// The random stream of one sample of one pixel: a SplitMix-style generator indexed by (bounce, dimension).
struct SampleRandom {
  u64 key;

  PT_HD static SampleRandom make(u32 seed, u32 pixel, u32 sample) {
    const u64 seed_and_pixel = (static_cast<u64>(seed) << 32) | pixel;
    return SampleRandom{mix64(mix64(seed_and_pixel + 0x9e3779b97f4a7c15ULL) ^ (static_cast<u64>(sample) * 0xd1b54a32d192ed03ULL))};
  }

  PT_HD u64 hash(u32 bounce, u32 dimension) const {
    const u64 counter = (static_cast<u64>(bounce) << 32) | dimension;
    return mix64(key + (counter + 1) * 0x9e3779b97f4a7c15ULL);
  }

  PT_HD u32 bits(u32 bounce, u32 dimension) const { return static_cast<u32>(hash(bounce, dimension) >> 32); }

  // Uniform in [0, 1), with 24 random bits (exactly representable in every supported scalar type).
  template <class T>
  PT_HD T uniform(u32 bounce, u32 dimension) const {
    return ScalarTraits<T>::from_unit_bits(bits(bounce, dimension) >> 8);
  }

  // Two uniforms from one hash: the first is uniform(bounce, dimension), the second takes 24 bits of the hash's
  // lower half (every output bit of the mix depends on every input bit). Half the hashing of two draws.
  template <class T>
  PT_HD void uniform_pair(u32 bounce, u32 dimension, T& first, T& second) const {
    const u64 h = hash(bounce, dimension);
    first = ScalarTraits<T>::from_unit_bits(static_cast<u32>(h >> 40));
    second = ScalarTraits<T>::from_unit_bits(static_cast<u32>(h >> 8) & 0xffffffu);
  }
};

// The draws of one bounce: fixes the bounce so materials only name dimensions.
struct BounceRandom {
  const SampleRandom* stream;
  u32 bounce;
  template <class T>
  PT_HD T uniform(u32 dimension) const { return stream->template uniform<T>(bounce, dimension); }
  template <class T>
  PT_HD void uniform_pair(u32 dimension, T& first, T& second) const { stream->uniform_pair(bounce, dimension, first, second); }
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
