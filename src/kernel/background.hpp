// The background: the radiance a path that leaves the scene gathers, and its sampling as a light (direction, radiance,
// density in solid angle), one definition for every background kind, integrator and backend.
#pragma once

#include "kernel/vec3.hpp"

namespace pt {

// The arrays of an environment image, built on the host (flat/environment.hpp). They are float whatever the scalar
// type: HDR radiance reaches values no fixed-point format holds, and the distribution's CDFs need more resolution
// than the narrow fixed-point formats have. Kernels convert the values they look up.
struct EnvironmentArrays {
  const float* rgb = nullptr;          // linear RGB, 3 floats a texel, times the strength; rows from the top (zenith)
  const float* density = nullptr;      // per texel: the sampling density over the image's (u, v) unit square
  const float* row_cdf = nullptr;      // height + 1 entries from 0 to 1: the marginal distribution of the rows
  const float* column_cdfs = nullptr;  // per row, width + 1 entries from 0 to 1: the distribution of its columns
};

// A rotation as the rows of its matrix; its inverse is its transpose.
template <class T>
struct Rotation {
  Vec3<T> rows[3] = {Vec3<T>{T(1), T(0), T(0)}, Vec3<T>{T(0), T(1), T(0)}, Vec3<T>{T(0), T(0), T(1)}};
  PT_HD Vec3<T> apply(const Vec3<T>& v) const { return {dot(rows[0], v), dot(rows[1], v), dot(rows[2], v)}; }
  PT_HD Vec3<T> apply_inverse(const Vec3<T>& v) const { return rows[0] * v.x + rows[1] * v.y + rows[2] * v.z; }
};

// An equirectangular image around the scene (docs/environment-lighting.md): in the image's own frame, column u in
// [0, 1) is the azimuth, u = 0.5 looking along -z and growing towards +x, and row v in [0, 1) the polar angle
// theta = pi v from +y. Each texel is constant over its patch (no filtering), so that the radiance seen and the
// sampling density are proportional on every texel and a light sample's radiance / pdf is constant over it.
template <class T>
struct EnvironmentMap {
  EnvironmentArrays arrays;
  u32 width = 0, height = 0;  // 0: no image (the gradient is the background)
  Rotation<T> to_map;         // world directions into the image's frame: the inverse of the map's rotation
};

template <class T>
struct Background {
  Color<T> horizon, zenith;       // the sky gradient; equal colours give a constant background
  EnvironmentMap<T> environment;  // replaces the gradient where its width is not 0
};

// A direction sampled on the background as a light: its radiance and the density it was drawn with, per unit solid
// angle (0 where the direction could not have been drawn).
template <class T>
struct BackgroundSample {
  Vec3<T> direction;
  Color<T> radiance;
  T pdf;
};

// What an environment image gives a direction: radiance and sampling density.
template <class T>
struct EnvironmentLookup {
  Color<T> radiance;
  T pdf;
};

// 1 / (4 pi): uniform sampling of the sphere.
template <class T>
PT_HD constexpr T uniform_sphere_pdf() {
  return constant<T>(0.0795774715459476679);
}

// The texel a unit direction sees, its radiance and the density of environment_sample there. The density of the
// (u, v) square becomes one per solid angle through dOmega = 2 pi^2 sin(theta) du dv.
template <class T>
PT_HD inline EnvironmentLookup<T> environment_lookup(const EnvironmentMap<T>& map, const Vec3<T>& direction) {
  const Vec3<T> d = map.to_map.apply(direction);
  const T y = clamp(d.y, T(-1), T(1));
  // The texel's position in float: u times the width does not fit the narrow fixed-point formats.
  const float u = static_cast<float>(atan2(d.x, -d.z) * constant<T>(0.159154943091895336)) + 0.5f;  // 1 / (2 pi)
  const float v = 0.5f - static_cast<float>(asin(y) * constant<T>(0.318309886183790672));           // 1 / pi
  const float column_f = u * static_cast<float>(map.width), row_f = v * static_cast<float>(map.height);
  // Clamped, for u = 1 and v = 1 exactly (and the comparison keeps a NaN at 0).
  const u32 column = column_f > 0.0f ? (column_f < static_cast<float>(map.width - 1) ? static_cast<u32>(column_f) : map.width - 1) : 0u;
  const u32 row = row_f > 0.0f ? (row_f < static_cast<float>(map.height - 1) ? static_cast<u32>(row_f) : map.height - 1) : 0u;
  const u32 texel = row * map.width + column;
  const float* rgb = map.arrays.rgb + 3u * texel;
  const T sin_theta = sqrt(max(T(0), T(1) - y * y));
  const float s = static_cast<float>(sin_theta);
  // In float, then converted once: a concentrated map's density exceeds the fixed-point formats' range before the
  // division by sin(theta) brings it back.
  const float pdf = s > 0.0f ? map.arrays.density[texel] / (19.7392088021787172f * s) : 0.0f;  // 2 pi^2
  return EnvironmentLookup<T>{Color<T>{T(rgb[0]), T(rgb[1]), T(rgb[2])}, T(pdf)};
}

// Picks the interval i of a CDF over n intervals (n + 1 entries rising from 0 to 1) with cdf[i] <= u < cdf[i + 1],
// by bisection; an interval of zero width is never picked for u < 1. Returns where u lies within it, in [0, 1).
PT_HD inline float sample_cdf(const float* cdf, u32 n, float u, u32& index) {
  u32 lo = 0, hi = n;
  while (hi - lo > 1) {
    const u32 mid = lo + (hi - lo) / 2;
    if (cdf[mid] <= u)
      lo = mid;
    else
      hi = mid;
  }
  index = lo;
  const float width = cdf[lo + 1] - cdf[lo];
  const float t = width > 0.0f ? (u - cdf[lo]) / width : 0.0f;
  return t < 1.0f ? (t > 0.0f ? t : 0.0f) : 0x1.fffffep-1f;
}

// A direction drawn from the image's distribution (a row by the marginal CDF, a column by that row's CDF, a point
// uniformly within the texel's (u, v) patch), with its radiance and density taken from the direction itself by
// environment_lookup, so that background_pdf gives exactly the same density for it.
template <class T>
PT_HD inline BackgroundSample<T> environment_sample(const EnvironmentMap<T>& map, T u1, T u2) {
  u32 row = 0, column = 0;
  const float dv = sample_cdf(map.arrays.row_cdf, map.height, static_cast<float>(u1), row);
  const float du = sample_cdf(map.arrays.column_cdfs + row * (map.width + 1), map.width, static_cast<float>(u2), column);
  const float u = (static_cast<float>(column) + du) / static_cast<float>(map.width);
  const float v = (static_cast<float>(row) + dv) / static_cast<float>(map.height);
  T cos_azimuth, sin_azimuth, cos_theta, sin_theta;
  cos_sin_turns(T(u - 0.5f), cos_azimuth, sin_azimuth);  // the azimuth is 2 pi (u - 0.5)
  cos_sin_turns(T(0.5f * v), cos_theta, sin_theta);      // theta = pi v
  const Vec3<T> in_map{sin_theta * sin_azimuth, cos_theta, -(sin_theta * cos_azimuth)};
  const Vec3<T> direction = map.to_map.apply_inverse(in_map);
  const EnvironmentLookup<T> at = environment_lookup(map, direction);
  return BackgroundSample<T>{direction, at.radiance, at.pdf};
}

// The radiance arriving from unit direction `direction`.
template <class T>
PT_HD inline Color<T> background_radiance(const Background<T>& background, const Vec3<T>& direction) {
  if (background.environment.width != 0) return environment_lookup(background.environment, direction).radiance;
  const T a = constant<T>(0.5) * (direction.y + T(1));
  return lerp(background.horizon, background.zenith, a);
}

// A direction drawn on the background as a light from two uniform numbers in [0, 1): the environment image by its
// luminance, the gradient and the constant uniformly over the sphere (their radiance varies too little to gain
// from more).
template <class T>
PT_HD inline BackgroundSample<T> background_sample(const Background<T>& background, T u1, T u2) {
  if (background.environment.width != 0) return environment_sample(background.environment, u1, u2);
  const T y = T(1) - constant<T>(2) * u1;
  const T r = sqrt(max(T(0), T(1) - y * y));
  T c, s;
  cos_sin_turns(u2, c, s);
  const Vec3<T> direction{r * c, y, r * s};
  return BackgroundSample<T>{direction, background_radiance(background, direction), uniform_sphere_pdf<T>()};
}

// The density per unit solid angle with which background_sample draws unit direction `direction`: the same value
// the sample carries.
template <class T>
PT_HD inline T background_pdf(const Background<T>& background, const Vec3<T>& direction) {
  if (background.environment.width != 0) return environment_lookup(background.environment, direction).pdf;
  return uniform_sphere_pdf<T>();
}

}  // namespace pt
