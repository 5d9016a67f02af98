// Materials: how a surface scatters or emits light. One definition of each, used by every integrator.
#pragma once

#include <variant>

#include "kernel/microfacet.hpp"
#include "kernel/random.hpp"
#include "kernel/texture.hpp"

namespace pt {

template <class T> struct Lambertian { u32 texture; };
template <class T> struct Metal { Color<T> albedo; T fuzz; };
template <class T> struct Dielectric { T ior; Color<T> tint; };
template <class T> struct DiffuseLight { u32 texture; };
template <class T> struct Isotropic { u32 texture; };
// glTF 2.0's metallic-roughness material (kernel/microfacet.hpp). Both are texture indices, so that constants and
// maps take one path: `base_color` gives the base colour; `metallic_roughness` gives roughness in its green channel
// and metallic in its blue one (glTF's layout), its factors folded in (a solid colour (0, roughness, metallic), or
// an image whose factor is (1, roughness factor, metallic factor)).
template <class T> struct MetallicRoughness { u32 base_color; u32 metallic_roughness; };

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
  const T signed_offset = dot(direction, at.geometric_normal) < T(0) ? -at.offset : at.offset;
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
// with these, in the frame frame_from_normal(at.normal), as scattering does.)
template <class T>
PT_HD inline MetallicRoughnessParams<T> metallic_roughness_params(const MetallicRoughness<T>& m, const SurfacePoint<T>& at, const Texture<T>* textures,
                                                                  const TextureData<T>& data) {
  const TexturePoint<T> point{at.u, at.v, at.p};
  const Color<T> metallic_roughness = texture_value(textures[m.metallic_roughness], point, data);
  return MetallicRoughnessParams<T>{texture_value(textures[m.base_color], point, data), metallic_roughness.z, metallic_roughness.y};
}

// Samples the next direction. Returns false when the material absorbs the ray (or only emits).
template <class T>
PT_HD inline bool material_scatter(const Material<T>& material, const Ray<T>& in, const SurfacePoint<T>& at,
                                   const Texture<T>* textures, const TextureData<T>& data, const BounceRandom& random,
                                   Scatter<T>& out) {
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
      const T eta = at.front_face ? T(1) / m.ior : m.ior;
      const T cos_i = min(-dot(in.direction, at.normal), T(1));
      const T sin_t2 = eta * eta * (T(1) - cos_i * cos_i);
      Vec3<T> direction;
      if (sin_t2 > T(1) || schlick_reflectance(cos_i, eta) > random.template uniform<T>(kDimScatterChoice))
        direction = reflect(in.direction, at.normal);
      else
        direction = refract(in.direction, at.normal, eta, cos_i);
      out = {m.tint, spawn_ray(at, normalize(direction), in.time), T(0)};
      return true;
    }
    PT_HD bool operator()(const DiffuseLight<T>&) const { return false; }
    PT_HD bool operator()(const Isotropic<T>& m) const {
      out = {albedo(m.texture), spawn_ray(at, random_direction(), in.time), T(1) / (constant<T>(4) * pi<T>())};
      return true;
    }
    PT_HD bool operator()(const MetallicRoughness<T>& m) const {
      // Two-sided: the normal faces the incoming ray, so wo is above the local surface.
      const ShadingFrame<T> frame = frame_from_normal(at.normal);
      T u1, u2;
      random.uniform_pair(kDimScatter, u1, u2);
      const BsdfSample<T> s = sample_metallic_roughness(metallic_roughness_params(m, at, textures, data), frame.to_local(-in.direction),
                                                        random.template uniform<T>(kDimLobe), u1, u2);
      if (!s.valid) return false;
      out = {s.weight, spawn_ray(at, frame.to_world(s.wi), in.time), s.pdf};
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
    const ShadingFrame<T> frame = frame_from_normal(at.normal);
    const BsdfEval<T> e = evaluate_metallic_roughness(metallic_roughness_params(*m, at, textures, data), frame.to_local(wo), frame.to_local(wi));
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
      return texture_needs_uv(textures[m.base_color]) || texture_needs_uv(textures[m.metallic_roughness]);
    }
  };
  return visit(NeedsUv{textures}, material);
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
