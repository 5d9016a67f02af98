// Materials: how a surface scatters or emits light. One definition of each, used by every integrator.
#pragma once

#include <variant>

#include "kernel/microfacet.hpp"
#include "kernel/random.hpp"
#include "kernel/texture.hpp"

namespace pt {

template <class T>
struct Lambertian {
  u32 texture;
};
template <class T>
struct Metal {
  Color<T> albedo;
  T fuzz;
};
template <class T>
struct Dielectric {
  T ior;
  Color<T> tint;
};
template <class T>
struct DiffuseLight {
  u32 texture;
};
template <class T>
struct Isotropic {
  u32 texture;
};
// glTF 2.0's metallic-roughness material (kernel/microfacet.hpp). Both are texture indices, so that constants and
// maps take one path: `base_color` gives the base colour; `metallic_roughness` gives roughness in its green channel
// and metallic in its blue one (glTF's layout), its factors folded in (a solid colour (0, roughness, metallic), or
// an image whose factor is (1, roughness factor, metallic factor)). `normal_map` is a linear image texture holding a
// tangent-space normal map (glTF's normalTexture), or kNoNormalMap; `normal_scale` multiplies the map's x and y.
inline constexpr u32 kNoNormalMap = 0xffffffffu;
template <class T>
struct MetallicRoughness {
  u32 base_color;
  u32 metallic_roughness;
  u32 normal_map = kNoNormalMap;
  T normal_scale = T(1);
};

template <class T>
using Material = std::variant<Lambertian<T>, Metal<T>, Dielectric<T>, DiffuseLight<T>, Isotropic<T>, MetallicRoughness<T>>;

// Where a ray met a surface (or a scattering point in a medium).
template <class T>
struct SurfacePoint {
  Vec3<T> p;
  Vec3<T> normal;  // unit, facing against the incoming ray
  T u, v;
  bool front_face;  // the ray came from the side the geometric normal points to
  u32 material;
  // The geometric normal (unit, pointing out of the shape) and how far along it a ray leaving p starts: just beyond
  // the rounding error of p (see describe_hit). Zero for a scattering point in a medium.
  Vec3<T> geometric_normal;
  T offset;
  // The tangent frame a normal map is read in, set by describe_hit only where asked (material_needs_tangent): a unit
  // tangent along increasing u, perpendicular to `normal`, and the handedness h (+1 or -1) that puts the bitangent,
  // along increasing v, at h normal x tangent. Both are turned with the normal on a back face, so that the frame
  // stays the mirror image of the front's. The tangent is zero where there is no frame (no texture coordinates, or a
  // mapping that does not vary): normal maps are then not applied.
  Vec3<T> tangent;
  T handedness;
};

// A scattered ray and its weight (the BSDF times the cosine over the density). `pdf` is the density of its
// direction per unit solid angle, or 0 where the choice was specular (a mirror, glass, a fuzzy metal: directions
// light sampling cannot find), so that the emission the ray meets counts in full.
template <class T>
struct Scatter {
  Color<T> attenuation;
  Ray<T> ray;
  T pdf;
};

// The BSDF times the cosine (the phase function in a medium) for given directions, and the density with which
// material_scatter would have chosen `wi`: what next-event estimation needs of a material.
template <class T>
struct ScatterValue {
  Color<T> value;
  T pdf;
};

// A ray leaving a surface point: it starts at the point moved by its offset to the side the direction goes to, where
// the surface it leaves can no longer be met again (robust ray spawning, see describe_hit). No minimum distance
// is needed: every hit beyond zero counts.
// The side is taken from the unit normal, not from the offset vector: in fixed point the offset is a few steps, and its
// product with a grazing direction would round to zero.
template <class T>
PT_HD inline Ray<T> spawn_ray(const SurfacePoint<T>& at, const Vec3<T>& direction, T time) {
  // The side the direction goes to. With exact products (fixed point) from the exact dot product, the sign a quad's
  // test forms: a direction within rounding of the surface is sent off on the side the test will see it go.
  bool inwards;
  if constexpr (ScalarTraits<T>::kExactProducts) {
    using S = ScalarTraits<T>;
    inwards = S::exact(direction.x) * S::exact(at.geometric_normal.x) + S::exact(direction.y) * S::exact(at.geometric_normal.y) +
                  S::exact(direction.z) * S::exact(at.geometric_normal.z) <
              0;
  } else {
    inwards = dot(direction, at.geometric_normal) < T(0);
  }
  const T signed_offset = inwards ? -at.offset : at.offset;
  return Ray<T>{at.p + signed_offset * at.geometric_normal, direction, time};
}

// Schlick's approximation of the Fresnel reflectance of a dielectric.
template <class T>
PT_HD inline T schlick_reflectance(T cosine, T eta) {
  T r0 = (T(1) - eta) / (T(1) + eta);
  r0 = r0 * r0;
  const T m = T(1) - cosine;
  const T m2 = m * m;
  return r0 + (T(1) - r0) * (m2 * m2 * m);
}

// The metallic-roughness parameters at a surface point: its textures looked up. (Light sampling evaluates the BSDF
// with these, in the frame of metallic_roughness_normal, as scattering does.)
template <class T>
PT_HD inline MetallicRoughnessParams<T> metallic_roughness_params(const MetallicRoughness<T>& m, const SurfacePoint<T>& at,
                                                                  const Texture<T>* textures, const TextureData<T>& data) {
  const TexturePoint<T> point{at.u, at.v, at.p};
  const Color<T> metallic_roughness = texture_value(textures[m.metallic_roughness], point, data);
  return MetallicRoughnessParams<T>{texture_value(textures[m.base_color], point, data), metallic_roughness.z, metallic_roughness.y};
}

// ---- Normal maps ----
// The normal a tangent-space normal map gives (glTF 2.0's normalTexture): the texel c, read as linear data in [0, 1],
// is the vector 2c - 1 with x and y multiplied by `scale`; x runs along the tangent (increasing u), y along the
// bitangent (increasing v, up the image: OpenGL's convention, which glTF uses), z along the shading normal.
// Returns it normalised, or the shading normal where the texel gives no direction (a zero vector).
template <class T>
PT_HD inline Vec3<T> normal_from_map(const Vec3<T>& normal, const Vec3<T>& tangent, T handedness, const Color<T>& texel, T scale) {
  const T x = (constant<T>(2) * texel.x - T(1)) * scale;
  const T y = (constant<T>(2) * texel.y - T(1)) * scale;
  const T z = constant<T>(2) * texel.z - T(1);
  const Vec3<T> bitangent = handedness * cross(normal, tangent);
  const Vec3<T> mapped = x * tangent + y * bitangent + z * normal;
  const T length2 = length_squared(mapped);
  if (!(length2 > T(0))) return normal;
  return mapped / sqrt(length2);
}

// A mapped normal can lean so far from the surface that the mirror direction of wo about it points below the
// geometric surface (or wo itself lies below it): the specular lobe would then reflect into the surface, and the
// picture shows black patches where the map tilts away from the viewer. Cycles' answer (Blender's
// ensure_valid_specular_reflection, used for its bump and normal maps) is kept here: where the reflection R of wo
// about n is below a small height t = min(0.9 wo.ng, 0.01) above the geometric surface, n is turned towards the
// geometric normal ng, in the plane of the two, just far enough that R.ng = t. With ng the z axis and X the unit
// direction of n's part along the surface, n' = sqrt(1 - z^2) X + z ng solves 2 (n'.wo) n'.z - wo.z = t, which
// squared is 4 a z^4 - 2 b z^2 + c = 0 with a = wo.x^2 + wo.z^2, b = 2 (a + wo.z t), c = (wo.z + t)^2; of its two
// roots in z^2 the one that makes n'.wo largest is taken (which one depends on the sign of wo.x). `ng` faces wo.
// Cycles assumes n on wo's side; a map's normal may face away from wo altogether (wo.n <= 0, blue below one half),
// and is turned the same way.
template <class T>
PT_HD inline Vec3<T> ensure_valid_reflection(const Vec3<T>& ng, const Vec3<T>& wo, const Vec3<T>& n) {
  const T wo_n = dot(wo, n);
  const T wo_z = max(dot(wo, ng), T(0));
  const T threshold = min(constant<T>(0.9) * wo_z, constant<T>(0.01));
  if (wo_n > T(0) && constant<T>(2) * wo_n * dot(n, ng) - wo_z >= threshold) return n;
  const Vec3<T> along = n - dot(n, ng) * ng;
  const T along2 = length_squared(along);
  if (!(along2 > T(0))) return ng;
  const Vec3<T> x_axis = along / sqrt(along2);
  const T wo_x = dot(wo, x_axis);
  const T a = wo_x * wo_x + wo_z * wo_z;
  if (!(a > T(0))) return ng;
  const T b = constant<T>(2) * (a + wo_z * threshold);
  const T c = (threshold + wo_z) * (threshold + wo_z);
  const T root = sqrt(max(b * b - constant<T>(4) * a * c, T(0)));
  const T z2 = clamp(constant<T>(0.25) * (wo_x < T(0) ? b + root : b - root) / a, T(0), T(1));
  return sqrt(T(1) - z2) * x_axis + sqrt(z2) * ng;
}

// The normal a metallic-roughness material shades with at `at`, seen along wo (unit, leaving the surface): the
// surface's own, or, where the material has a normal map and the point a tangent frame, the map's normal, kept
// valid by ensure_valid_reflection. The one definition scattering and evaluation both use, so that a direction is
// sampled and evaluated in the same frame.
template <class T>
PT_HD inline Vec3<T> metallic_roughness_normal(const MetallicRoughness<T>& m, const SurfacePoint<T>& at, const Vec3<T>& wo,
                                               const Texture<T>* textures, const TextureData<T>& data) {
  if (m.normal_map == kNoNormalMap || !(length_squared(at.tangent) > T(0))) return at.normal;
  const Color<T> texel = texture_value(textures[m.normal_map], TexturePoint<T>{at.u, at.v, at.p}, data);
  const Vec3<T> mapped = normal_from_map(at.normal, at.tangent, at.handedness, texel, m.normal_scale);
  return ensure_valid_reflection(at.front_face ? at.geometric_normal : -at.geometric_normal, wo, mapped);
}

// With a normal map the shading hemisphere and the geometric one differ: a direction above the first may be below
// the second, where a ray would leave through the surface's other side (light leaking through it). Such directions
// are not reflected (pbrt's rule: reflection is told by the geometric normal): the sampler refuses them and
// evaluation gives them zero.
template <class T>
PT_HD inline bool leaves_on_the_wrong_side(const MetallicRoughness<T>& m, const SurfacePoint<T>& at, const Vec3<T>& wi) {
  if (m.normal_map == kNoNormalMap) return false;
  const T side = dot(wi, at.geometric_normal);
  return at.front_face ? !(side > T(0)) : !(side < T(0));
}

// Glass's two ways on from a surface point, reflected and refracted, and the one a scattering takes: reflected with
// probability Schlick's reflectance, else refracted (reflected always under total internal reflection, where the other
// way's share is 0). Each way's value is the tint times its share, so the way taken carries the tint alone. The other
// way's direction is made only where `both` asks for it (the path tracer takes one way; `other` is then `taken`).
template <class T>
struct DielectricWays {
  Vec3<T> taken, other;  // unit directions
  T taken_share, other_share;
};

template <class T>
PT_HD inline DielectricWays<T> dielectric_ways(const Dielectric<T>& m, const Ray<T>& in, const SurfacePoint<T>& at, const BounceRandom& random,
                                               bool both = false) {
  const T eta = at.front_face ? T(1) / m.ior : m.ior;
  const T cos_i = min(-dot(in.direction, at.normal), T(1));
  const T sin_t2 = eta * eta * (T(1) - cos_i * cos_i);
  if (sin_t2 > T(1)) {
    const Vec3<T> reflected = normalize(reflect(in.direction, at.normal));
    return DielectricWays<T>{reflected, reflected, T(1), T(0)};
  }
  const T reflectance = schlick_reflectance(cos_i, eta);
  const bool reflects = reflectance > random.template uniform<T>(kDimScatterChoice);
  const Vec3<T> taken = normalize(reflects ? reflect(in.direction, at.normal) : refract(in.direction, at.normal, eta, cos_i));
  const Vec3<T> other = !both ? taken : normalize(reflects ? refract(in.direction, at.normal, eta, cos_i) : reflect(in.direction, at.normal));
  return DielectricWays<T>{taken, other, reflects ? reflectance : T(1) - reflectance, reflects ? T(1) - reflectance : reflectance};
}

// Glass's scattering along the way taken.
template <class T>
PT_HD inline Scatter<T> dielectric_scatter(const Dielectric<T>& m, const Ray<T>& in, const SurfacePoint<T>& at, const DielectricWays<T>& ways) {
  return Scatter<T>{m.tint, spawn_ray(at, ways.taken, in.time), T(0)};
}

// Samples the next direction. Returns false when the material absorbs the ray (or only emits).
template <class T>
PT_HD inline bool material_scatter(const Material<T>& material, const Ray<T>& in, const SurfacePoint<T>& at, const Texture<T>* textures,
                                   const TextureData<T>& data, const BounceRandom& random, Scatter<T>& out) {
  struct Sample {
    const Ray<T>& in;
    const SurfacePoint<T>& at;
    const Texture<T>* textures;
    const TextureData<T>& data;
    const BounceRandom& random;
    Scatter<T>& out;

    PT_HD Color<T> albedo(u32 texture) const { return texture_value(textures[texture], TexturePoint<T>{at.u, at.v, at.p}, data); }
    PT_HD Vec3<T> random_direction() const {
      T u1, u2;
      random.uniform_pair(kDimScatter, u1, u2);
      return uniform_unit_vector(u1, u2);
    }

    PT_HD bool operator()(const Lambertian<T>& m) const {
      // Normal plus a uniform unit vector is cosine-distributed about the normal.
      Vec3<T> direction = at.normal + random_direction();
      const T len2 = length_squared(direction);
      direction = len2 > constant<T>(1e-12) ? direction / sqrt(len2) : at.normal;
      out = {albedo(m.texture), spawn_ray(at, direction, in.time), max(dot(direction, at.normal), T(0)) / pi<T>()};
      return true;
    }
    PT_HD bool operator()(const Metal<T>& m) const {
      Vec3<T> direction = reflect(in.direction, at.normal) + m.fuzz * random_direction();
      const T len2 = length_squared(direction);
      if (!(len2 > T(0))) return false;
      direction = direction / sqrt(len2);
      out = {m.albedo, spawn_ray(at, direction, in.time), T(0)};
      return dot(direction, at.normal) > T(0);
    }
    PT_HD bool operator()(const Dielectric<T>& m) const {
      out = dielectric_scatter(m, in, at, dielectric_ways(m, in, at, random));
      return true;
    }
    PT_HD bool operator()(const DiffuseLight<T>&) const { return false; }
    PT_HD bool operator()(const Isotropic<T>& m) const {
      out = {albedo(m.texture), spawn_ray(at, random_direction(), in.time), T(1) / (constant<T>(4) * pi<T>())};
      return true;
    }
    PT_HD bool operator()(const MetallicRoughness<T>& m) const {
      // Two-sided: the normal faces the incoming ray, so wo is above the local surface.
      const Vec3<T> wo = -in.direction;
      const ShadingFrame<T> frame = frame_from_normal(metallic_roughness_normal(m, at, wo, textures, data));
      T u1, u2;
      random.uniform_pair(kDimScatter, u1, u2);
      const BsdfSample<T> s = sample_metallic_roughness(metallic_roughness_params(m, at, textures, data), frame.to_local(wo),
                                                        random.template uniform<T>(kDimLobe), u1, u2);
      if (!s.valid) return false;
      const Vec3<T> wi = frame.to_world(s.wi);
      if (leaves_on_the_wrong_side(m, at, wi)) return false;
      out = {s.weight, spawn_ray(at, wi, in.time), s.pdf};
      return true;
    }
  };
  return visit(Sample{in, at, textures, data, random, out}, material);
}

// Whether the material scatters with a density light sampling can meet (diffuse surfaces, media), so that a shadow
// ray towards a light is worth tracing from it.
template <class T>
PT_HD inline bool material_samples_lights(const Material<T>& material) {
  return std::holds_alternative<Lambertian<T>>(material) || std::holds_alternative<Isotropic<T>>(material) ||
         std::holds_alternative<MetallicRoughness<T>>(material);
}

// The scattering of light arriving along `wi` towards `wo` (both unit, leaving the point; wo back along the incoming
// ray) of a material for which material_samples_lights holds, and the density material_scatter gives wi; zero for the
// others.
template <class T>
PT_HD inline ScatterValue<T> material_evaluate(const Material<T>& material, const SurfacePoint<T>& at, const Vec3<T>& wo, const Vec3<T>& wi,
                                               const Texture<T>* textures, const TextureData<T>& data) {
  if (const auto* m = std::get_if<Lambertian<T>>(&material)) {
    const T cosine = dot(wi, at.normal);
    if (!(cosine > T(0))) return ScatterValue<T>{Color<T>{}, T(0)};
    const T pdf = cosine / pi<T>();
    return ScatterValue<T>{texture_value(textures[m->texture], TexturePoint<T>{at.u, at.v, at.p}, data) * pdf, pdf};
  }
  if (const auto* m = std::get_if<Isotropic<T>>(&material)) {
    const T pdf = T(1) / (constant<T>(4) * pi<T>());
    return ScatterValue<T>{texture_value(textures[m->texture], TexturePoint<T>{at.u, at.v, at.p}, data) * pdf, pdf};
  }
  if (const auto* m = std::get_if<MetallicRoughness<T>>(&material)) {
    const ShadingFrame<T> frame = frame_from_normal(metallic_roughness_normal(*m, at, wo, textures, data));
    const BsdfEval<T> e = evaluate_metallic_roughness(metallic_roughness_params(*m, at, textures, data), frame.to_local(wo), frame.to_local(wi));
    // A direction the sampler refuses keeps its density (the sampler's draws are not renormalised) but reflects nothing.
    if (leaves_on_the_wrong_side(*m, at, wi)) return ScatterValue<T>{Color<T>{}, e.pdf};
    return ScatterValue<T>{e.f_cos, e.pdf};
  }
  return ScatterValue<T>{Color<T>{}, T(0)};
}

// Whether the texture reads the texture coordinates (u, v); the others depend on the point only.
template <class T>
PT_HD inline bool texture_needs_uv(const Texture<T>& texture) {
  return std::holds_alternative<UvCheckerTexture<T>>(texture) || std::holds_alternative<ImageTexture<T>>(texture);
}

// Whether shading the material reads the hit's texture coordinates, so describe_hit may skip computing them
// where they are costly (spheres: an atan2 and an asin per hit).
template <class T>
PT_HD inline bool material_needs_uv(const Material<T>& material, const Texture<T>* textures) {
  struct NeedsUv {
    const Texture<T>* textures;
    PT_HD bool operator()(const Lambertian<T>& m) const { return texture_needs_uv(textures[m.texture]); }
    PT_HD bool operator()(const Metal<T>&) const { return false; }
    PT_HD bool operator()(const Dielectric<T>&) const { return false; }
    PT_HD bool operator()(const DiffuseLight<T>& m) const { return texture_needs_uv(textures[m.texture]); }
    PT_HD bool operator()(const Isotropic<T>& m) const { return texture_needs_uv(textures[m.texture]); }
    PT_HD bool operator()(const MetallicRoughness<T>& m) const {
      return texture_needs_uv(textures[m.base_color]) || texture_needs_uv(textures[m.metallic_roughness]) || m.normal_map != kNoNormalMap;
    }
  };
  return visit(NeedsUv{textures}, material);
}

// Whether shading the material reads the hit's tangent frame (a normal map), so that describe_hit works it out
// only then.
template <class T>
PT_HD inline bool material_needs_tangent(const Material<T>& material) {
  const auto* m = std::get_if<MetallicRoughness<T>>(&material);
  return m && m->normal_map != kNoNormalMap;
}

// Whether a material emits at all (what material_emitted gives is then not zero everywhere): where a hit is described
// only for its emission, the test before describing it.
template <class T>
PT_HD inline bool material_emits(const Material<T>& material) {
  return std::holds_alternative<DiffuseLight<T>>(material);
}

// Radiance the surface emits towards the incoming ray.
template <class T>
PT_HD inline Color<T> material_emitted(const Material<T>& material, const SurfacePoint<T>& at, const Texture<T>* textures,
                                       const TextureData<T>& data) {
  if (const auto* light = std::get_if<DiffuseLight<T>>(&material))
    return texture_value(textures[light->texture], TexturePoint<T>{at.u, at.v, at.p}, data);
  return Color<T>{};
}

}  // namespace pt
