// Textures: what colour a surface has at a point. One variant alternative per kind, evaluated by pt::visit.
#pragma once

#include <variant>

#include "kernel/vec3.hpp"
#include "kernel/visit.hpp"

namespace pt {

template <class T>
struct SolidTexture {
  Color<T> color;
};

// 3-D checker: `odd` where sin(f x) sin(f y) sin(f z) < 0 (the seed's pattern with frequency f), which is cells
// pi / f wide: stored as cells per unit length, f / pi, worked out once on the host rather than at every lookup.
template <class T>
struct CheckerTexture {
  Color<T> odd, even;
  T cells_per_unit;
};

// Checker in texture coordinates: `columns` x `rows` cells over [0,1]^2.
template <class T>
struct UvCheckerTexture {
  Color<T> odd, even;
  T columns, rows;
};

// An image in the scene's shared texel buffer, starting at texel `offset`, times a colour factor (glTF's base colour
// and emissive factors; 1 for a scene's own image textures). `linear`: the bytes are data read as they are, byte / 255
// (glTF's metallic-roughness maps), rather than sRGB-encoded colours.
template <class T>
struct ImageTexture {
  u32 width, height, offset;
  T repeat;
  Color<T> factor;
  u32 linear = 0;
};

enum class NoiseKind : u32 { kPerlin = 0, kTurbulence = 1, kMarble = 2 };
// `scale` multiplies the position the noise reads. The marble's turbulence reads the position itself, in the scene's
// units as written: `unscale` (1 as written) undoes the lengths' scaling by flatten_scene (fixed point), so that the
// veins stay where they are.
template <class T>
struct NoiseTexture {
  T scale;
  NoiseKind kind;
  u32 turbulence_depth;
  T unscale;
};

template <class T>
using Texture = std::variant<SolidTexture<T>, CheckerTexture<T>, UvCheckerTexture<T>, ImageTexture<T>, NoiseTexture<T>>;

inline constexpr u32 kPerlinPoints = 256;

// Read-only data textures index into: the shared texel buffer and the Perlin tables.
template <class T>
struct TextureData {
  const u8* texels = nullptr;                 // 3 sRGB-encoded bytes per texel
  const float* srgb_decode = nullptr;         // 256 entries: the linear value of each byte
  const Vec3<T>* perlin_gradients = nullptr;  // kPerlinPoints unit vectors
  const u32* perlin_permutations = nullptr;   // 3 * kPerlinPoints entries: x, y and z permutations
};

// Where a texture is looked up.
template <class T>
struct TexturePoint {
  T u, v;
  Vec3<T> p;
};

// 1 where floor(a) is odd, 0 where it is even (exact for every representable a).
template <class T>
PT_HD inline T half_period_parity(T a) {
  const T whole = floor(a);
  return whole - constant<T>(2) * floor(whole * constant<T>(0.5));
}

template <class T>
PT_HD inline T perlin_noise(const TextureData<T>& data, const Vec3<T>& p) {
  const T fx = floor(p.x), fy = floor(p.y), fz = floor(p.z);
  const T u = p.x - fx, v = p.y - fy, w = p.z - fz;
  const i32 i = static_cast<i32>(fx), j = static_cast<i32>(fy), k = static_cast<i32>(fz);
  // Hermite smoothing hides the lattice.
  const T uu = u * u * (constant<T>(3) - constant<T>(2) * u);
  const T vv = v * v * (constant<T>(3) - constant<T>(2) * v);
  const T ww = w * w * (constant<T>(3) - constant<T>(2) * w);
  const u32* perm = data.perlin_permutations;
  T sum = T(0);
  for (int di = 0; di < 2; ++di)
    for (int dj = 0; dj < 2; ++dj)
      for (int dk = 0; dk < 2; ++dk) {
        const u32 index = perm[static_cast<u32>(i + di) & 255u] ^ perm[kPerlinPoints + (static_cast<u32>(j + dj) & 255u)] ^
                          perm[2 * kPerlinPoints + (static_cast<u32>(k + dk) & 255u)];
        const Vec3<T> gradient = data.perlin_gradients[index];
        const Vec3<T> offset{u - T(di), v - T(dj), w - T(dk)};
        const T wx = di ? uu : T(1) - uu;
        const T wy = dj ? vv : T(1) - vv;
        const T wz = dk ? ww : T(1) - ww;
        sum += wx * wy * wz * dot(gradient, offset);
      }
  return sum;
}

template <class T>
PT_HD inline T perlin_turbulence(const TextureData<T>& data, Vec3<T> p, u32 depth) {
  T sum = T(0);
  T weight = T(1);
  for (u32 i = 0; i < depth; ++i) {
    sum += weight * perlin_noise(data, p);
    weight *= constant<T>(0.5);
    p *= constant<T>(2);
  }
  return abs(sum);
}

// Bilinear lookup with wrap-around; v = 1 is the top row of the image.
template <class T>
PT_HD inline Color<T> image_lookup(const TextureData<T>& data, const ImageTexture<T>& image, T u, T v) {
  const T su = u * image.repeat, sv = v * image.repeat;
  const T wu = su - floor(su), wv = sv - floor(sv);
  i32 column, row;
  T fx, fy;
  ScalarTraits<T>::texel_position(wu, image.width, column, fx);
  ScalarTraits<T>::texel_position(T(1) - wv, image.height, row, fy);
  const i32 w = static_cast<i32>(image.width), h = static_cast<i32>(image.height);
  // Neighbours of a texel inside the image need no division; the modulo is for the wrap-around.
  auto wrap = [](i32 a, i32 n) { return a >= 0 && a < n ? a : ((a % n) + n) % n; };
  const i32 x0 = wrap(column, w), x1 = wrap(column + 1, w);
  const i32 y0 = wrap(row, h), y1 = wrap(row + 1, h);
  auto texel = [&](i32 px, i32 py) {
    const u8* t = data.texels + 3u * (image.offset + static_cast<u32>(py) * image.width + static_cast<u32>(px));
    if (image.linear) return Color<T>{T(t[0]), T(t[1]), T(t[2])} * constant<T>(1.0 / 255.0);
    return Color<T>{T(data.srgb_decode[t[0]]), T(data.srgb_decode[t[1]]), T(data.srgb_decode[t[2]])};
  };
  const Color<T> top = lerp(texel(x0, y0), texel(x1, y0), fx);
  const Color<T> bottom = lerp(texel(x0, y1), texel(x1, y1), fx);
  return lerp(top, bottom, fy);
}

template <class T>
PT_HD inline Color<T> texture_value(const Texture<T>& texture, const TexturePoint<T>& at, const TextureData<T>& data) {
  struct Evaluate {
    const TexturePoint<T>& at;
    const TextureData<T>& data;
    PT_HD Color<T> operator()(const SolidTexture<T>& t) const { return t.color; }
    PT_HD Color<T> operator()(const CheckerTexture<T>& t) const {
      // sin(a) < 0 exactly where floor(a / pi) is odd, so the product of the three sines is negative where an odd
      // number of the three half-period counts are odd: the same cells without evaluating a sine.
      const T odd_count = half_period_parity(t.cells_per_unit * at.p.x) + half_period_parity(t.cells_per_unit * at.p.y) +
                          half_period_parity(t.cells_per_unit * at.p.z);
      return odd_count == T(1) || odd_count == T(3) ? t.odd : t.even;
    }
    PT_HD Color<T> operator()(const UvCheckerTexture<T>& t) const {
      const i32 column = static_cast<i32>(floor(at.u * t.columns));
      const i32 row = static_cast<i32>(floor(at.v * t.rows));
      return ((column + row) & 1) ? t.odd : t.even;
    }
    PT_HD Color<T> operator()(const ImageTexture<T>& t) const { return t.factor * image_lookup(data, t, at.u, at.v); }
    PT_HD Color<T> operator()(const NoiseTexture<T>& t) const {
      const Vec3<T> p = t.scale * at.p;
      T value;
      switch (t.kind) {
        case NoiseKind::kPerlin: value = constant<T>(0.5) * (T(1) + perlin_noise(data, p)); break;
        case NoiseKind::kTurbulence: value = perlin_turbulence(data, p, t.turbulence_depth); break;
        default:
          value = constant<T>(0.5) * (T(1) + sin(p.z + constant<T>(10) * perlin_turbulence(data, t.unscale * at.p, t.turbulence_depth)));
          break;
      }
      return Color<T>::splat(value);
    }
  };
  return visit(Evaluate{at, data}, texture);
}

}  // namespace pt
