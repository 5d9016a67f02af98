// Next-event estimation: a light picked by power, a direction sampled towards it, the density of that direction
// per unit solid angle, and the weights of multiple importance sampling that join it with the scattered direction.
// One density function (light_pdf) serves both the shadow ray and the emission a scattered ray meets, so the two
// strategies agree on every direction by construction.
#pragma once

#include "kernel/scene_view.hpp"

namespace pt {

// A direction towards a light: the entry picked, and for a mesh the triangle the direction aims at.
template <class T>
struct LightSample {
  Vec3<T> direction;
  T distance;  // to the point on the light (largest<T>() for the background)
  u32 entry;
  u32 triangle;
};

// The power heuristic (exponent 2) for one sample of each strategy: the weight of the strategy with density `pdf`
// when the other has `other`. Written with the ratio, so fixed-point formats do not square a large density.
// With exact products (fixed point) both are one quotient of exact squares, pdf^2 / (pdf^2 + other^2) and
// pdf / (pdf^2 + other^2): the ratio's square saturated wherever one density was 180 times the other (Q16.16).
template <class T>
PT_HD inline T mis_weight(T pdf, T other) {
  if (!(pdf > T(0))) return T(0);
  if constexpr (ScalarTraits<T>::kExactProducts) {
    using S = ScalarTraits<T>;
    return S::exact_quotient(S::exact(pdf) * S::exact(pdf), S::exact(pdf) * S::exact(pdf) + S::exact(other) * S::exact(other));
  } else {
    const T ratio = other / pdf;
    return T(1) / (T(1) + ratio * ratio);
  }
}

// mis_weight(pdf, other) / pdf, the factor a light sample is counted with, without dividing twice.
template <class T>
PT_HD inline T mis_weight_over_pdf(T pdf, T other) {
  if constexpr (ScalarTraits<T>::kExactProducts) {
    using S = ScalarTraits<T>;
    return S::exact_quotient(S::exact(pdf) * S::exact(T(1)), S::exact(pdf) * S::exact(pdf) + S::exact(other) * S::exact(other));
  } else {
    return T(1) / (pdf + other * (other / pdf));
  }
}

// Picks an entry of the alias table: a uniform index, then the entry or its alias.
template <class T>
PT_HD inline u32 choose_light(const LightData<T>& lights, const BounceRandom& random) {
  const u32 index = static_cast<u32>((static_cast<u64>(random.stream->bits(random.bounce, kDimLightChoice)) * lights.count) >> 32);
  const LightEntry<T>& entry = lights.entries[index];
  return random.template uniform<T>(kDimLightAlias) < entry.threshold ? index : entry.alias;
}

// The triangle of an emitting mesh whose cumulative distribution first exceeds u (a binary search), as an index into
// MeshData::triangles.
template <class T>
PT_HD inline u32 choose_mesh_triangle(const LightData<T>& lights, const MeshRecord& mesh, u32 cdf_start, T u) {
  u32 lo = 0, hi = mesh.triangle_count;  // the answer lies in [lo, hi)
  while (hi - lo > 1) {
    const u32 mid = lo + (hi - lo) / 2;
    if (lights.triangle_cdf[cdf_start + mid] <= u) lo = mid;
    else hi = mid;
  }
  // Skip triangles of zero probability (those that do not emit) that the search may stop on.
  while (lo + 1 < mesh.triangle_count && !(lights.triangle_cdf[cdf_start + lo + 1] > lights.triangle_cdf[cdf_start + lo])) ++lo;
  return mesh.first_triangle + lo;
}

// A mesh triangle's vertices in the world.
template <class T>
PT_HD inline void world_triangle(const MeshData<T>& meshes, const MeshInstance<T>& instance, u32 triangle, Vec3<T> (&p)[3]) {
  const MeshRecord& mesh = meshes.meshes[instance.mesh];
  const MeshTriangle& tri = meshes.triangles[triangle];
  for (int k = 0; k < 3; ++k) {
    p[k] = meshes.positions[mesh.first_vertex + tri.vertex[k]];
    if (instance.transform != kNoTransform) p[k] = meshes.transforms[instance.transform].to_world.point(p[k]);
  }
}

// A unit vector making angle acos(cos_theta) with the unit axis w, at azimuth `turn` (in turns) about it.
template <class T>
PT_HD inline Vec3<T> direction_about(const Vec3<T>& w, T cos_theta, T turn) {
  const T sin_theta = sqrt(max(T(0), T(1) - cos_theta * cos_theta));
  T c, sn;
  cos_sin_turns(turn, c, sn);
  return frame_from_normal(w).to_world(Vec3<T>{sin_theta * c, sin_theta * sn, cos_theta});
}

// 1 - cos(theta_max) of the cone a sphere of squared radius r2 fills, seen from squared distance d2 > r2; from the
// sine, so a small, far sphere keeps its digits.
template <class T>
PT_HD inline T sphere_cone_width(T r2, T d2) {
  const T sin2 = r2 / d2;
  return sin2 / (T(1) + sqrt(max(T(0), T(1) - sin2)));
}

// A direction from `from` towards a point of the chosen light (pass its entry), or false where none can be had.
// Spheres seen from outside are sampled uniformly over the cone they fill; every other shape uniformly over its
// area (a mesh: a triangle by its share of the mesh's power, then a point on it).
template <class T>
PT_HD inline bool sample_light(const SceneView<T>& scene, u32 entry, const Vec3<T>& from, T time, const BounceRandom& random, LightSample<T>& out) {
  const LightEntry<T>& light = scene.lights.entries[entry];
  out.entry = entry;
  out.triangle = 0;
  T u1, u2;
  random.uniform_pair(kDimLightPoint, u1, u2);
  if (light.primitive == kNoLight) {
    out.direction = background_sample(scene.background, u1, u2).direction;
    out.distance = largest<T>();
    return true;
  }
  const Primitive<T>& primitive = scene.primitives[light.primitive];
  Vec3<T> target;
  auto sphere = [&](const Vec3<T>& center, T radius) {
    const Vec3<T> to_center = center - from;
    if constexpr (ScalarTraits<T>::kExactProducts) {
      // Fixed point: the distance, not its square (beyond the range for a light 200 units away in Q16.16), and the
      // sine of the cone's half-angle, r / d.
      using S = ScalarTraits<T>;
      const T d = length(to_center);
      if (d > radius) {
        const T sine = radius / d;
        out.direction = direction_about(to_center / d, T(1) - u1 * sphere_cone_width(sine * sine, T(1)), u2);
        T near, far;
        out.distance = sphere_roots(center, radius, Ray<T>{from, out.direction, time}, near, far) && near > T(0)
                           ? near
                           : S::exact_sqrt(S::exact(d - radius) * S::exact(d + radius));
        return true;
      }
    } else {
      const T d2 = length_squared(to_center);
      const T r2 = radius * radius;
      if (d2 > r2) {
        const T width = sphere_cone_width(r2, d2);
        out.direction = direction_about(to_center / sqrt(d2), T(1) - u1 * width, u2);
        // Where the direction enters the sphere; the tangent's length bounds it where rounding misses the sphere.
        T near, far;
        out.distance = sphere_roots(center, radius, Ray<T>{from, out.direction, time}, near, far) && near > T(0) ? near : sqrt(d2 - r2);
        return true;
      }
    }
    target = center + radius * uniform_unit_vector(u1, u2);
    return false;
  };
  if (const auto* s = std::get_if<Sphere<T>>(&primitive.shape)) {
    if (sphere(s->center, s->radius)) return true;
  } else if (const auto* m = std::get_if<MovingSphere<T>>(&primitive.shape)) {
    if (sphere(moving_sphere_center(*m, time), m->radius)) return true;
  } else if (const auto* q = std::get_if<Quad<T>>(&primitive.shape)) {
    Vec3<T> eu, ev;
    quad_edges(*q, eu, ev);
    target = q->corner + u1 * eu + u2 * ev;
  } else if (const auto* t = std::get_if<Triangle<T>>(&primitive.shape)) {
    const T root = sqrt(u1);  // uniform over the triangle: barycentrics (1 - root, root u2)
    target = t->p0 + (root * (T(1) - u2)) * t->edge1 + (root * u2) * t->edge2;
  } else if (const auto* instance = std::get_if<MeshInstance<T>>(&primitive.shape)) {
    const MeshRecord& mesh = scene.meshes.meshes[instance->mesh];
    out.triangle = choose_mesh_triangle(scene.lights, mesh, light.first_cdf, random.template uniform<T>(kDimLightTriangle));
    Vec3<T> p[3];
    world_triangle(scene.meshes, *instance, out.triangle, p);
    const T root = sqrt(u1);
    target = p[0] + (root * (T(1) - u2)) * (p[1] - p[0]) + (root * u2) * (p[2] - p[0]);
  } else {
    return false;
  }
  const Vec3<T> to_target = target - from;
  out.distance = length(to_target);  // not its square, which fixed point may not hold
  if (!(out.distance > T(0))) return false;
  out.direction = to_target / out.distance;
  return true;
}

// The density per unit solid angle with which sample_light, from the ray's origin, gives the ray's (unit) direction,
// where the ray meets the light of `entry` at `hit`, described by `at`.
template <class T>
PT_HD inline T light_pdf(const SceneView<T>& scene, u32 entry, const Ray<T>& ray, const Hit<T>& hit, const SurfacePoint<T>& at) {
  const LightEntry<T>& light = scene.lights.entries[entry];
  const Vec3<T>& from = ray.origin;
  const Vec3<T>& direction = ray.direction;
  const T t = hit.t;
  const Primitive<T>& primitive = scene.primitives[light.primitive];
  // An area density turned into one per solid angle: t^2 / |cos| at the light.
  const T cosine = abs(dot(at.geometric_normal, direction));
  // The area as two factors, so that fixed point need not hold the area itself (a 300 x 265 light is beyond
  // Q16.16) nor t^2: there pmf t t / (cos a1 a2) is one quotient of exact products (kernel/shapes.hpp).
  [[maybe_unused]] auto per_area2 = [&](T a1, T a2) {
    if constexpr (ScalarTraits<T>::kExactProducts) {
      using S = ScalarTraits<T>;
      return S::exact_quotient(S::exact(light.pmf) * S::exact(t) * S::exact(t), S::exact(cosine) * S::exact(a1) * S::exact(a2));
    } else {
      return light.pmf * (t * t) / (cosine * (a1 * a2));
    }
  };
  auto per_area = [&](T area) {
    if constexpr (ScalarTraits<T>::kExactProducts) return per_area2(area, T(1));
    else return light.pmf * (t * t) / (cosine * area);
  };
  auto sphere = [&](const Vec3<T>& center, T radius) {
    if constexpr (ScalarTraits<T>::kExactProducts) {
      const T d = length(center - from);
      if (d > radius) {
        const T sine = radius / d;
        return light.pmf / (constant<T>(2) * pi<T>() * sphere_cone_width(sine * sine, T(1)));
      }
      return per_area2(constant<T>(4) * pi<T>() * radius, radius);
    } else {
      const T d2 = length_squared(center - from);
      const T r2 = radius * radius;
      if (d2 > r2) return light.pmf / (constant<T>(2) * pi<T>() * sphere_cone_width(r2, d2));
      return per_area(constant<T>(4) * pi<T>() * r2);
    }
  };
  if (const auto* s = std::get_if<Sphere<T>>(&primitive.shape)) return sphere(s->center, s->radius);
  if (const auto* m = std::get_if<MovingSphere<T>>(&primitive.shape)) return sphere(moving_sphere_center(*m, ray.time), m->radius);
  if (const auto* q = std::get_if<Quad<T>>(&primitive.shape)) {
    // |u x v| = u_extent (v_extent / normal.(du x dv)) (quad_area).
    if constexpr (ScalarTraits<T>::kExactProducts) return per_area2(q->u_extent, abs(q->v_extent / dot(q->normal, cross(q->du, q->dv))));
    else return per_area(quad_area(*q));
  }
  if (const auto* tri = std::get_if<Triangle<T>>(&primitive.shape)) return per_area(triangle_area(tri->edge1, tri->edge2));
  if (const auto* instance = std::get_if<MeshInstance<T>>(&primitive.shape)) {
    const MeshRecord& mesh = scene.meshes.meshes[instance->mesh];
    const u32 start = light.first_cdf + (hit.triangle - mesh.first_triangle);
    const T share = scene.lights.triangle_cdf[start + 1] - scene.lights.triangle_cdf[start];
    Vec3<T> p[3];
    world_triangle(scene.meshes, *instance, hit.triangle, p);
    return share * per_area(triangle_area(p[1] - p[0], p[2] - p[0]));
  }
  return T(0);
}

}  // namespace pt
