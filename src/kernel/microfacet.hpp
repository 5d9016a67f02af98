// GGX (Trowbridge-Reitz) microfacet functions and the glTF 2.0 metallic-roughness BSDF, in a local shading frame
// whose z axis is the shading normal. Evaluation, sampling and pdf are all here, so that scattering and light
// sampling (which weighs both strategies by their pdfs) use one definition of the physics.
#pragma once

#include <type_traits>

#include "kernel/vec3.hpp"

namespace pt {

// An orthonormal frame (s, t, n) about a unit normal n, without branches on the normal's direction beyond its
// hemisphere (the construction of Duff et al. 2017, "Building an Orthonormal Basis, Revisited"): it stays
// orthonormal to rounding for every n, where the classic cross product with a fixed axis loses precision near it.
template <class T>
struct ShadingFrame {
  Vec3<T> s, t, n;
  PT_HD Vec3<T> to_local(const Vec3<T>& v) const { return {dot(v, s), dot(v, t), dot(v, n)}; }
  PT_HD Vec3<T> to_world(const Vec3<T>& v) const { return s * v.x + t * v.y + n * v.z; }
};

template <class T>
PT_HD inline ShadingFrame<T> frame_from_normal(const Vec3<T>& n) {
  const T sign = n.z >= T(0) ? T(1) : T(-1);
  const T a = T(-1) / (sign + n.z);
  const T b = n.x * n.y * a;
  return ShadingFrame<T>{Vec3<T>{T(1) + sign * n.x * n.x * a, sign * b, -sign * n.x}, Vec3<T>{b, sign + n.y * n.y * a, -n.y}, n};
}

// The smallest GGX alpha used. alpha = 0 would make D a delta (infinite at one normal), so perceptual roughness 0
// renders as a very sharp lobe instead. Floating point takes 1e-3 (D at most 1 / (pi 1e-6), well inside float's
// range). A fixed-point type needs alpha^2 to be many of its steps, or D and the Smith terms lose every digit:
// alpha at least 4 sqrt(step), i.e. alpha^2 at least 16 steps.
template <class T>
PT_HD inline T ggx_min_alpha() {
  if constexpr (std::is_floating_point_v<T>)
    return constant<T>(1e-3);
  else
    return max(constant<T>(1e-3), constant<T>(4) * sqrt(ScalarTraits<T>::rounding_step()));
}

// glTF's perceptual roughness to GGX alpha: alpha = roughness^2 (glTF 2.0 appendix B), clamped.
template <class T>
PT_HD inline T ggx_alpha(T roughness) {
  const T r = clamp(roughness, T(0), T(1));
  return max(r * r, ggx_min_alpha<T>());
}

// The GGX normal distribution D(m) for a unit microfacet normal m: alpha^2 / (pi (x^2 + y^2 + alpha^2 z^2)^2),
// the usual alpha^2 / (pi cos^4 (alpha^2 + tan^2)^2) multiplied out so that it has no tangent to overflow.
// Zero below the surface. Normalised so that the integral of D(m) cos(theta_m) over the hemisphere is 1.
template <class T>
PT_HD inline T ggx_d(T alpha, const Vec3<T>& m) {
  if (!(m.z > T(0))) return T(0);
  const T a2 = alpha * alpha;
  const T t = m.x * m.x + m.y * m.y + a2 * m.z * m.z;
  return a2 / (pi<T>() * t * t);
}

// sqrt(z^2 + alpha^2 (x^2 + y^2)) for a unit direction w, which is |z| (1 + 2 Lambda(w)): the Smith terms written with
// it need no division by the cosine, which is zero at the horizon.
template <class T>
PT_HD inline T ggx_smith_root(T alpha, const Vec3<T>& w) {
  return sqrt(max(T(0), w.z * w.z + alpha * alpha * (w.x * w.x + w.y * w.y)));
}

// Smith's Lambda for GGX: (-1 + sqrt(1 + alpha^2 tan^2(theta))) / 2. (Tests and documentation; the BSDF uses the
// root above.)
template <class T>
PT_HD inline T ggx_lambda(T alpha, const Vec3<T>& w) {
  return (ggx_smith_root(alpha, w) / abs(w.z) - T(1)) * constant<T>(0.5);
}

// Smith's masking G1(w) = 1 / (1 + Lambda(w)) = 2 |z| / (|z| + root).
template <class T>
PT_HD inline T ggx_g1(T alpha, const Vec3<T>& w) {
  const T z = abs(w.z);
  const T denominator = z + ggx_smith_root(alpha, w);
  return denominator > T(0) ? constant<T>(2) * z / denominator : T(0);
}

// The height-correlated masking-shadowing G2(wo, wi) = 1 / (1 + Lambda(wo) + Lambda(wi)) (Heitz 2014): a point hidden
// from one direction is likelier hidden from the other, so it is larger than G1(wo) G1(wi).
template <class T>
PT_HD inline T ggx_g2(T alpha, const Vec3<T>& wo, const Vec3<T>& wi) {
  const T zo = abs(wo.z), zi = abs(wi.z);
  const T denominator = zi * ggx_smith_root(alpha, wo) + zo * ggx_smith_root(alpha, wi);
  return denominator > T(0) ? constant<T>(2) * zo * zi / denominator : T(0);
}

// A microfacet normal from the distribution of normals visible from wo (wo.z > 0), D_wo(m) = G1(wo) max(0, wo.m) D(m)
// / wo.z, by the spherical-cap construction of Dupuy and Benyoub 2023. In the space where the surface has alpha = 1
// (x and y divided by alpha) the microsurface is a hemisphere, and its normals visible from v (wo in that space) are
// v + c, normalised, for c uniform on the cap of the unit sphere above z = -v.z. Mapped back by multiplying x and y
// by alpha (normals transform by the inverse transpose). No rejection: every (u1, u2) gives a normal.
template <class T>
PT_HD inline Vec3<T> ggx_sample_visible_normal(T alpha, const Vec3<T>& wo, T u1, T u2) {
  const Vec3<T> v = normalize(Vec3<T>{alpha * wo.x, alpha * wo.y, wo.z});
  T c, s;
  cos_sin_turns(u1, c, s);
  const T z = (T(1) - u2) * (T(1) + v.z) - v.z;
  const T r = sqrt(max(T(0), T(1) - z * z));
  const Vec3<T> h{r * c + v.x, r * s + v.y, z + v.z};
  const Vec3<T> m{alpha * h.x, alpha * h.y, max(h.z, T(0))};
  const T len2 = length_squared(m);
  // h is zero only when the cap point is -v, which u2 < 1 excludes up to rounding; the normal itself stands in.
  return len2 > T(0) ? m / sqrt(len2) : Vec3<T>{T(0), T(0), T(1)};
}

// The density, in solid angle of wi, of reflecting wo about a visible normal: D_wo(m) / (4 wo.m) with m the half
// vector (4 wo.m is the Jacobian of the reflection, dwi = 4 (wo.m) dm), which simplifies to G1(wo) D(m) / (4 wo.z)
// = D(m) / (2 (wo.z + root(wo))). Defined for every wi, below the horizon too (where a reflected sample may land):
// it integrates to one over the whole sphere. Given D(m) and root(wo):
template <class T>
PT_HD inline T ggx_reflection_pdf_of(T d, T wo_z, T root_o) {
  return d / (constant<T>(2) * (wo_z + root_o));
}

// The same for any wi, from alpha.
template <class T>
PT_HD inline T ggx_reflection_pdf(T alpha, const Vec3<T>& wo, const Vec3<T>& wi) {
  const Vec3<T> sum = wo + wi;
  const T len2 = length_squared(sum);
  if (!(wo.z > T(0)) || !(len2 > T(0))) return T(0);
  const Vec3<T> m = sum / sqrt(len2);
  if (!(dot(wo, m) > T(0))) return T(0);
  return ggx_reflection_pdf_of(ggx_d(alpha, m), wo.z, ggx_smith_root(alpha, wo));
}

// Schlick's Fresnel with a colour F0: F0 + (1 - F0) (1 - cos)^5.
template <class T>
PT_HD inline Color<T> schlick_fresnel(const Color<T>& f0, T cosine) {
  const T m = T(1) - clamp(cosine, T(0), T(1));
  const T m2 = m * m;
  const T m5 = m2 * m2 * m;
  return f0 + (Color<T>::splat(T(1)) - f0) * m5;
}

// g(mu) = 1 - (1 - mu)^5: with it, Schlick's 1 - F(mu) = (1 - F0) g(mu).
template <class T>
PT_HD inline T schlick_complement_shape(T cosine) {
  const T m = T(1) - clamp(cosine, T(0), T(1));
  const T m2 = m * m;
  return T(1) - m2 * m2 * m;
}

// The glTF 2.0 metallic-roughness material at one point (textures already applied).
template <class T>
struct MetallicRoughnessParams {
  Color<T> base_color;
  T metallic;
  T roughness;  // perceptual: alpha = roughness^2
};

// f(wo, wi) |cos(wi)| and the pdf (solid angle) with which sample_metallic_roughness draws wi given wo.
template <class T>
struct BsdfEval {
  Color<T> f_cos;
  T pdf;
};

// A sampled direction, its weight f |cos| / pdf, and the pdf. `valid` is false where nothing was sampled (wo below
// the surface, a reflection below the horizon, a black material): the path ends there.
template <class T>
struct BsdfSample {
  Vec3<T> wi;
  Color<T> weight;
  T pdf;
  bool valid;
};

// What the two lobes need, worked out once per shading point and wo: glTF appendix B's
//   F0 = mix(0.04, base, metallic) (a dielectric of index 1.5 reflects 4% at normal incidence; a metal its colour),
//   c_diff = base (1 - metallic) (metals have no diffuse part),
// and the probability of sampling the specular lobe. Each lobe is picked in proportion to its albedo from wo, as
// far as it is known in closed form: the specular lobe reflects about F(wo.z) (exact for a smooth surface, a little
// less for rough ones), the diffuse lobe exactly c_diff (1 - F(wo.z)) (see evaluate_metallic_roughness). Then
// f |cos| / pdf stays close to the sum of the two albedos whichever lobe drew the direction (the pdf is the mixture of
// both), rather than one lobe's albedo over a small probability. The probability depends on wo only, so the mixture
// pdf is the same for sampling and for evaluation (NEE, MIS).
template <class T>
struct MetallicRoughnessLobes {
  Color<T> f0;
  Color<T> diffuse_through;  // c_diff (1 - F0): the diffuse colour less what the coating reflects at normal incidence
  T alpha;
  T specular_probability;
  bool black;  // neither lobe reflects anything: nothing to sample
};

template <class T>
PT_HD inline T color_mean(const Color<T>& c) {
  return (c.x + c.y + c.z) * constant<T>(1.0 / 3.0);
}

template <class T>
PT_HD inline MetallicRoughnessLobes<T> metallic_roughness_lobes(const MetallicRoughnessParams<T>& params, const Vec3<T>& wo) {
  MetallicRoughnessLobes<T> lobes;
  const T metallic = clamp(params.metallic, T(0), T(1));
  lobes.f0 = lerp(Color<T>::splat(constant<T>(0.04)), params.base_color, metallic);
  lobes.diffuse_through = params.base_color * (T(1) - metallic) * (Color<T>::splat(T(1)) - lobes.f0);
  lobes.alpha = ggx_alpha(params.roughness);
  const T specular = color_mean(schlick_fresnel(lobes.f0, wo.z));
  const T diffuse = color_mean(lobes.diffuse_through) * schlick_complement_shape(wo.z);
  const T total = specular + diffuse;
  lobes.black = !(total > T(0));
  lobes.specular_probability = lobes.black ? T(1) : specular / total;
  return lobes;
}

// The BSDF: a GGX specular lobe F D G2 / (4 |wo.z| |wi.z|) with F Schlick's at wo.h (h the half vector), over a
// diffuse lobe (21 / (20 pi)) c_diff (1 - F0) g(wo.z) g(wi.z), g(mu) = 1 - (1 - mu)^5. Reflection only: both
// directions above the surface (z > 0), else zero.
// The diffuse lobe differs from glTF appendix B's c_diff (1 - F(wo.h)) / pi, which is not energy conserving: at grazing
// wo the specular lobe reflects F(wo.z), near 1, while for most wi the half vector is far from grazing, so the diffuse
// part still reflects nearly c_diff, and a white dielectric returned up to 1.8 times the light it received. Here the
// diffuse lobe takes the light the coating lets through on the way in, 1 - F(wo.z) = (1 - F0) g(wo.z), and, for
// reciprocity, the same factor on the way out, normalised so that it integrates to exactly c_diff (1 - F(wo.z)):
// the integral of g(mu) mu over the hemisphere is pi (1 - 2/42) = pi 20/21. With a specular albedo of at most about
// F(wo.z), the total stays at or below one (tests/test_microfacet.cpp measures it), and the diffuse albedo is known
// in closed form for the lobe choice. At normal incidence on both sides the two forms agree within 1%.
// Symmetric in wo and wi (reciprocal): F depends on wo.h = wi.h, and D, G2 and the diffuse factor on both alike. The
// specular part times |wi.z| is written as F D wi.z / (2 (root_o wi.z + root_i wo.z)), with no division by a cosine.
template <class T>
PT_HD inline BsdfEval<T> evaluate_metallic_roughness(const MetallicRoughnessLobes<T>& lobes, const Vec3<T>& wo, const Vec3<T>& wi) {
  BsdfEval<T> out{Color<T>{}, T(0)};
  if (!(wo.z > T(0)) || !(wi.z > T(0)) || lobes.black) return out;
  const Vec3<T> h = normalize(wo + wi);
  const Color<T> fresnel = schlick_fresnel(lobes.f0, dot(wo, h));
  const T d = ggx_d(lobes.alpha, h);
  const T root_o = ggx_smith_root(lobes.alpha, wo), root_i = ggx_smith_root(lobes.alpha, wi);
  const T specular = d * wi.z / (constant<T>(2) * (root_o * wi.z + root_i * wo.z));
  const T cosine_over_pi = wi.z * constant<T>(1.0 / 3.14159265358979323846);
  const T diffuse = constant<T>(21.0 / 20.0) * schlick_complement_shape(wo.z) * schlick_complement_shape(wi.z) * cosine_over_pi;
  out.f_cos = fresnel * specular + lobes.diffuse_through * diffuse;
  const T specular_pdf = ggx_reflection_pdf_of(d, wo.z, root_o);
  out.pdf = lobes.specular_probability * specular_pdf + (T(1) - lobes.specular_probability) * cosine_over_pi;
  return out;
}

template <class T>
PT_HD inline BsdfEval<T> evaluate_metallic_roughness(const MetallicRoughnessParams<T>& params, const Vec3<T>& wo, const Vec3<T>& wi) {
  return evaluate_metallic_roughness(metallic_roughness_lobes(params, wo), wo, wi);
}

// Draws wi given wo: the specular lobe (a visible normal, wo reflected about it) with probability
// specular_probability, chosen by u_lobe, else the diffuse lobe (cosine-weighted); (u1, u2) place the direction.
// The weight divides by the mixture pdf of both lobes (one-sample MIS over the lobes), so it does not depend on
// which lobe drew the direction, and sample and evaluate agree exactly.
template <class T>
PT_HD inline BsdfSample<T> sample_metallic_roughness(const MetallicRoughnessLobes<T>& lobes, const Vec3<T>& wo, T u_lobe, T u1, T u2) {
  BsdfSample<T> out{Vec3<T>{}, Color<T>{}, T(0), false};
  if (!(wo.z > T(0)) || lobes.black) return out;
  Vec3<T> wi;
  if (u_lobe < lobes.specular_probability) {
    const Vec3<T> m = ggx_sample_visible_normal(lobes.alpha, wo, u1, u2);
    wi = constant<T>(2) * dot(wo, m) * m - wo;
  } else {
    // Cosine-weighted: a uniform point of the unit disk lifted onto the hemisphere.
    const T r = sqrt(u1);
    T c, s;
    cos_sin_turns(u2, c, s);
    wi = Vec3<T>{r * c, r * s, sqrt(max(T(0), T(1) - u1))};
  }
  const T len2 = length_squared(wi);
  if (!(wi.z > T(0)) || !(len2 > T(0))) return out;
  wi = wi / sqrt(len2);
  const BsdfEval<T> e = evaluate_metallic_roughness(lobes, wo, wi);
  if (!(e.pdf > T(0))) return out;
  out.wi = wi;
  out.pdf = e.pdf;
  out.weight = e.f_cos / e.pdf;
  out.valid = true;
  return out;
}

template <class T>
PT_HD inline BsdfSample<T> sample_metallic_roughness(const MetallicRoughnessParams<T>& params, const Vec3<T>& wo, T u_lobe, T u1, T u2) {
  return sample_metallic_roughness(metallic_roughness_lobes(params, wo), wo, u_lobe, u1, u2);
}

}  // namespace pt
