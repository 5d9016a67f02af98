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
  T pdf;       // the density per unit solid angle where sampling knows it (by solid angle: a cone, a rectangle, the
               // background), else 0; as the format carries it (light_density)
  T brightest; // the largest channel of the radiance it can bring (the background's own, a shape's brightest), 0
               // where not known
  u32 entry;
  u32 triangle;
};

// Light densities as the format carries them. Floating point, and fixed point with at least as many integer bits as
// fraction bits, carry the density per unit solid angle; fixed point with more fraction bits (Q12.20, Q10.22, Q8.24)
// carries its reciprocal, the solid angle per unit of probability. The density of a small or far light, or of one
// seen edge-on, grows without bound (beyond Q8.24's 128 for a sphere of radius 0.15 seen from 3 units), where it was
// clamped and its samples over-weighted; its reciprocal shrinks towards 0 in steps of 2^-F, fine where F is large.
// Multiple importance sampling needs only its ratio to the scattering density. Either way 0 means none: light
// sampling cannot give the direction (or, carried as a reciprocal, its density is beyond 2^F).
template <class T>
inline constexpr bool kReciprocalLightDensity = ScalarTraits<T>::kReciprocalLightDensity;

// The light density numerator / denominator, given as exact values with the same fraction bits (fixed point with
// exact products), as the format carries it: one quotient either way.
template <class T, class Exact>
PT_HD inline T exact_light_density(Exact numerator, Exact denominator) {
  using S = ScalarTraits<T>;
  return kReciprocalLightDensity<T> ? S::exact_quotient(denominator, numerator) : S::exact_quotient(numerator, denominator);
}

// The light density numerator / denominator as the format carries it.
template <class T>
PT_HD inline T light_density(T numerator, T denominator) {
  if constexpr (kReciprocalLightDensity<T>)
    return exact_light_density<T>(ScalarTraits<T>::exact(numerator), ScalarTraits<T>::exact(denominator));
  else
    return numerator / denominator;
}

// The scattering density times a light's reciprocal density, s r, rounded once: the ratio of the two strategies'
// densities, from which both power-heuristic weights follow where the format carries reciprocals.
template <class T>
PT_HD inline T scatter_to_light_ratio(T scatter_pdf, T reciprocal_light) {
  using S = ScalarTraits<T>;
  return S::round_exact(S::exact(scatter_pdf) * S::exact(reciprocal_light));
}

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

// The weight of light that a scattered direction (density `scatter_pdf` > 0) found, against the density `light`
// (as the format carries it, 0: none) with which light sampling could have found it.
template <class T>
PT_HD inline T scattered_light_weight(T scatter_pdf, T light) {
  if constexpr (kReciprocalLightDensity<T>) {
    // (s r)^2 / ((s r)^2 + 1) for the reciprocal r: s r rounded once (where it exceeds the range the weight is 1 to
    // within 2^-2(I-1)), then one quotient of exact squares.
    if (!(light > T(0))) return T(1);
    using S = ScalarTraits<T>;
    const T ratio = scatter_to_light_ratio(scatter_pdf, light);
    return S::exact_quotient(S::exact(ratio) * S::exact(ratio), S::exact(ratio) * S::exact(ratio) + S::exact(T(1)) * S::exact(T(1)));
  } else {
    return mis_weight(scatter_pdf, light);
  }
}

// The factor a light sample of density `light` (as the format carries it, > 0) is counted with: its power-heuristic
// weight against the scattering density `scatter_pdf`, over its density.
template <class T>
PT_HD inline T light_sample_weight(T light, T scatter_pdf) {
  if constexpr (kReciprocalLightDensity<T>) {
    // r / (1 + (s r)^2) for the reciprocal r: s r rounded once, then one quotient.
    using S = ScalarTraits<T>;
    const T ratio = scatter_to_light_ratio(scatter_pdf, light);
    return S::exact_quotient(S::exact(light) * S::exact(T(1)), S::exact(T(1)) * S::exact(T(1)) + S::exact(ratio) * S::exact(ratio));
  } else {
    return mis_weight_over_pdf(light, scatter_pdf);
  }
}

// The density of a background direction, pmf times the background's own density, as the format carries it.
template <class T>
PT_HD inline T background_light_density(T pmf, T background_pdf) {
  if constexpr (kReciprocalLightDensity<T>) {
    using S = ScalarTraits<T>;
    return exact_light_density<T>(S::exact(pmf) * S::exact(background_pdf), S::exact(T(1)) * S::exact(T(1)));
  } else {
    return pmf * background_pdf;
  }
}

// Picks an entry of the alias table: a uniform index, then the entry or its alias. A lone light needs no draw (both
// would give entry 0), which saves two of the few random numbers a light sample costs.
template <class T>
PT_HD inline u32 choose_light(const LightData<T>& lights, const BounceRandom& random) {
  if (lights.count == 1) return 0;
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
    if (lights.triangle_cdf[cdf_start + mid] <= u)
      lo = mid;
    else
      hi = mid;
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

// (a, b) / |(a, b)|, and |(a, b)|; false for (0, 0). Fixed-point formats divide by the larger magnitude first, so
// that no length is squared (it would overflow); floating point squares directly, with one division.
template <class T>
PT_HD inline bool unit_pair(T a, T b, T& ua, T& ub, T& length) {
  ua = T(0);
  ub = T(0);
  length = T(0);
  if constexpr (std::is_floating_point_v<T>) {
    length = sqrt(a * a + b * b);
    if (!(length > T(0))) return false;
    const T inverse = T(1) / length;
    ua = a * inverse;
    ub = b * inverse;
  } else {
    const T m = max(abs(a), abs(b));
    if (!(m > T(0))) return false;
    a = a / m;
    b = b / m;
    const T l = sqrt(a * a + b * b);
    ua = a / l;
    ub = b / l;
    length = m * l;
  }
  return true;
}

// A rectangle seen from a point as the spherical rectangle it fills (Urena, Fajardo and King, "An Area-Preserving
// Parametrization for Spherical Rectangles", 2013), so that light sampling can pick directions uniformly in solid
// angle: near a large light, area sampling's density falls as 1/distance^2 across the light and its samples vary
// by orders of magnitude, while directions spread evenly over the light's solid angle vary only with the cosine at
// the receiver. The frame: x and y along the edges, z the normal turned away from the point, so the rectangle lies
// at height z0 < 0 over [x0, x1] x [y0, y1]. b0, b1 and k are the constants of the parametrization.
template <class T>
struct SphericalRectangle {
  Vec3<T> x, y, z;
  T x0, x1, y0, y1, z0;
  T b0, b1, k;
  T solid_angle;
};

// The angle between unit vectors a and b as the unit complex number (cos, sin), from their dot product and the length
// of their cross product (accurate near 0 and pi, where an arc cosine is not). Angles add by multiplying these, so
// a sum of angles costs one arc tangent instead of one each.
template <class T>
struct Turn {
  T c, s;
};

template <class T>
PT_HD inline Turn<T> turn_between(const Vec3<T>& a, const Vec3<T>& b) {
  return Turn<T>{dot(a, b), length(cross(a, b))};
}

template <class T>
PT_HD inline Turn<T> operator*(const Turn<T>& a, const Turn<T>& b) {
  return Turn<T>{a.c * b.c - a.s * b.s, a.s * b.c + a.c * b.s};
}

// The angle of a turn in [0, 2 pi).
template <class T>
PT_HD inline T turn_angle(const Turn<T>& t) {
  const T angle = atan2(t.s, t.c);
  return angle < T(0) ? angle + constant<T>(2) * pi<T>() : angle;
}

// Below this solid angle, light sampling falls back to the area (the spherical rectangle's angles cancel to a few
// digits, and for a far light the two densities are the same anyway); the margin in rounding units keeps the
// cancellation small for fixed-point formats, whose angles carry an absolute error of a few steps. Above the
// largest, the point nearly touches the light's plane, where the parametrization divides by almost zero.
// (1024 units as two factors of 32: Q8.24 and Q10.22 cannot hold 1024, which saturated on every light sample.)
template <class T>
PT_HD inline T smallest_sampled_solid_angle() {
  return constant<T>(3e-4) + ScalarTraits<T>::rounding_unit() * constant<T>(32) * constant<T>(32);
}

// Quad q's frame (RectangleFrame), or one with lu = 0 where q is a parallelogram that is not a rectangle.
template <class T>
PT_HD inline RectangleFrame<T> rectangle_frame(const Quad<T>& q) {
  RectangleFrame<T> f{};
  Vec3<T> eu, ev;
  quad_edges(q, eu, ev);
  const T lu = length(eu), lv = length(ev);
  if (!(lu > T(0) && lv > T(0))) return f;
  // Floating point multiplies by the reciprocal (one division); fixed point divides, as 1 / length keeps few digits.
  if constexpr (std::is_floating_point_v<T>) {
    f.x = eu * (T(1) / lu);
    f.y = ev * (T(1) / lv);
  } else {
    f.x = eu / lu;
    f.y = ev / lv;
  }
  if (!(abs(dot(f.x, f.y)) <= constant<T>(1e-6))) return RectangleFrame<T>{};
  f.z = cross(f.x, f.y);
  f.lu = lu;
  f.lv = lv;
  return f;
}

// The spherical rectangle that a rectangle of frame `f` and corner `corner` (a quad's) fills seen from `from`, where
// its solid angle lies within the range sampled by it; false otherwise (light sampling then samples the quad by
// area). The same test decides in sample_light and light_pdf, so the density is always that of the sampling used.
template <class T>
PT_HD inline bool spherical_rectangle(const RectangleFrame<T>& f, const Vec3<T>& corner, const Vec3<T>& from, SphericalRectangle<T>& r) {
  if (!(f.lu > T(0))) return false;  // no rectangle
  const T lu = f.lu, lv = f.lv;
  r.x = f.x;
  r.y = f.y;
  r.z = f.z;
  const Vec3<T> d = corner - from;
  r.x0 = dot(d, r.x);
  r.y0 = dot(d, r.y);
  r.z0 = dot(d, r.z);
  if (r.z0 > T(0)) {
    r.z = -r.z;
    r.z0 = -r.z0;
  }
  if (!(r.z0 < T(0))) return false;  // the point lies in the light's plane
  r.x1 = r.x0 + lu;
  r.y1 = r.y0 + lv;
  // Unit normals of the planes through the point and each edge, (0, z0, -y0), (-z0, 0, x1), (0, -z0, y1) and
  // (z0, 0, -x0) normalised; the spherical rectangle's inner angles lie between consecutive ones.
  Vec3<T> n0{}, n1{}, n2{}, n3{};
  T unused;
  if (!unit_pair(r.z0, -r.y0, n0.y, n0.z, unused) || !unit_pair(-r.z0, r.x1, n1.x, n1.z, unused) || !unit_pair(-r.z0, r.y1, n2.y, n2.z, unused) ||
      !unit_pair(r.z0, -r.x0, n3.x, n3.z, unused))
    return false;
  // The inner angles g0..g3 sum to 2 pi + the solid angle; k = 2 pi - g2 - g3. Each lies in (0, pi), so g2 + g3
  // and the solid angle are read off their turns in [0, 2 pi) (two arc tangents for the four angles).
  const Turn<T> g23 = turn_between(-n2, n3) * turn_between(-n3, n0);
  r.b0 = n0.z;
  r.b1 = n2.z;
  r.k = constant<T>(2) * pi<T>() - turn_angle(g23);
  r.solid_angle = turn_angle(turn_between(-n0, n1) * turn_between(-n1, n2) * g23);
  return r.solid_angle > smallest_sampled_solid_angle<T>() && r.solid_angle < constant<T>(6.2);
}

// The point of the spherical rectangle at (u1, u2), as a unit direction from the point it is seen from and the
// distance to it: u1 sweeps the solid angle by equal shares along x, u2 along y, so the directions are uniform in
// solid angle. Written without squaring lengths (every square is of a ratio within [-1, 1] or of a sine).
template <class T>
PT_HD inline void sample_spherical_rectangle(const SphericalRectangle<T>& r, T u1, T u2, Vec3<T>& direction, T& distance) {
  // x: the angle au that takes the share u1 of the solid angle; cu is the cosine of the angle at which the plane
  // through the point and x = xu meets the x axis: cu = sign(f) / sqrt(f^2 + b0^2) with f = (cos au b0 - b1) / sin au,
  // written as a ratio of bounded terms.
  const T au = u1 * r.solid_angle + r.k;
  const T s = sin(au), c = cos(au);
  const T num = c * r.b0 - r.b1;
  const T den = sqrt(num * num + (r.b0 * s) * (r.b0 * s));
  T xu = num < T(0) ? r.x0 : r.x1;
  if (den > T(0)) {
    const T cu = clamp((num < T(0) ? -s : s) / den, constant<T>(-1), constant<T>(1));
    const T sine = sqrt(max(T(0), T(1) - cu * cu));
    xu = sine > T(0) ? -(cu * r.z0) / sine : (cu > T(0) ? r.x1 : r.x0);
  }
  xu = clamp(xu, r.x0, r.x1);
  // y: uniform in the sine of the elevation over [y0, y1] along the line x = xu, at distance dd from the point.
  T cx, sz, dd;  // dd = sqrt(xu^2 + z0^2)
  unit_pair(xu, r.z0, cx, sz, dd);
  T c0, h0, c1, h1, unused;
  unit_pair(dd, r.y0, c0, h0, unused);
  unit_pair(dd, r.y1, c1, h1, unused);
  const T hv = h0 + u2 * (h1 - h0);
  const T cv = sqrt(max(T(0), T(1) - hv * hv));
  const T yv = cv > T(0) ? clamp(hv * dd / cv, r.y0, r.y1) : (hv > T(0) ? r.y1 : r.y0);
  // The direction (xu, yv, z0) in the rectangle's frame, normalised without squaring lengths.
  Vec3<T> local{xu, yv, r.z0};
  if constexpr (std::is_floating_point_v<T>) {
    distance = length(local);
    local = local * (T(1) / distance);
  } else {
    const T m = max(max(abs(xu), abs(yv)), abs(r.z0));
    local = Vec3<T>{xu / m, yv / m, r.z0 / m};
    const T l = length(local);
    distance = m * l;
    local = Vec3<T>{local.x / l, local.y / l, local.z / l};
  }
  direction = r.x * local.x + r.y * local.y + r.z * local.z;
}

// The centre (at `time`) and radius of a sphere or moving sphere; false for every other shape.
template <class T>
PT_HD inline bool sphere_at(const Primitive<T>& primitive, T time, Vec3<T>& center, T& radius) {
  if (const auto* s = std::get_if<Sphere<T>>(&primitive.shape)) {
    center = s->center;
    radius = s->radius;
    return true;
  }
  if (const auto* m = std::get_if<MovingSphere<T>>(&primitive.shape)) {
    center = moving_sphere_center(*m, time);
    radius = m->radius;
    return true;
  }
  return false;
}

// The density per unit solid angle of directions drawn uniformly over a cone of width 1 - cos theta_max, for a
// light picked with probability pmf, as the format carries it.
template <class T>
PT_HD inline T cone_density(T pmf, T width) {
  return light_density(pmf, constant<T>(2) * pi<T>() * width);
}

// A direction from `from` towards a point of the chosen light (pass its entry), or false where none can be had.
// Spheres seen from outside are sampled uniformly over the cone they fill, rectangles uniformly over the solid angle
// they fill (where it is neither tiny nor nearly a half-space); every other shape uniformly over its area (a mesh: a
// triangle by its share of the mesh's power, then a point on it).
template <class T>
PT_HD inline bool sample_light(const SceneView<T>& scene, u32 entry, const Vec3<T>& from, T time, const BounceRandom& random, LightSample<T>& out) {
  const LightEntry<T>& light = scene.lights.entries[entry];
  out.entry = entry;
  out.triangle = 0;
  out.pdf = T(0);
  out.brightest = light.brightest;
  T u1, u2;
  random.uniform_pair(kDimLightPoint, u1, u2);
  if (light.primitive == kNoLight) {
    const BackgroundSample<T> sample = background_sample(scene.background, u1, u2);
    out.direction = sample.direction;
    out.distance = largest<T>();
    out.pdf = background_light_density(light.pmf, sample.pdf);
    out.brightest = max_component(sample.radiance);
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
        const T width = sphere_cone_width(sine * sine, T(1));
        out.direction = direction_about(to_center / d, T(1) - u1 * width, u2);
        out.pdf = cone_density(light.pmf, width);
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
        out.pdf = cone_density(light.pmf, width);
        // Where the direction enters the sphere; the tangent's length bounds it where rounding misses the sphere.
        T near, far;
        out.distance = sphere_roots(center, radius, Ray<T>{from, out.direction, time}, near, far) && near > T(0) ? near : sqrt(d2 - r2);
        return true;
      }
    }
    target = center + radius * uniform_unit_vector(u1, u2);
    return false;
  };
  Vec3<T> center;
  T radius;
  if (sphere_at(primitive, time, center, radius)) {
    if (sphere(center, radius)) return true;
  } else if (const auto* q = std::get_if<Quad<T>>(&primitive.shape)) {
    SphericalRectangle<T> rectangle;
    if (spherical_rectangle(scene.lights.rectangles[entry], q->corner, from, rectangle)) {
      sample_spherical_rectangle(rectangle, u1, u2, out.direction, out.distance);
      out.pdf = light_density(light.pmf, rectangle.solid_angle);
      return true;
    }
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

// What a light sample of `entry` can add at `from`, at most, per unit of the path's throughput, at a material whose
// f never exceeds 1 / pi (a lambertian surface of albedo at most 1, a medium's phase function): the light's
// brightest radiance over its density, pmf / (2 pi (1 - cos theta_max)), divided by pi, times the largest cosine
// with `normal` (where given: a surface) over the cone. Known before sampling only for spheres seen from outside;
// 0 for every other light; negative where the whole cone lies below the surface (the sample would bring nothing).
// Floating point only: the fixed-point formats would need the cone's width from the distance rather than its square
// (sample_light does both).
template <class T>
PT_HD inline T light_reach(const SceneView<T>& scene, u32 entry, const Vec3<T>& from, T time, const Vec3<T>* normal) {
  const LightEntry<T>& light = scene.lights.entries[entry];
  if (light.primitive == kNoLight || !(light.brightest > T(0))) return T(0);
  Vec3<T> center;
  T radius;
  if (!sphere_at(scene.primitives[light.primitive], time, center, radius)) return T(0);
  const Vec3<T> to_center = center - from;
  const T d2 = length_squared(to_center), r2 = radius * radius;
  if (!(d2 > r2)) return T(0);
  T largest_cosine = T(1);
  if (normal) {
    // The angle to the centre less the cone's half-angle: cos(a - t) = cos a cos t + sin a sin t <= cos a + sin t
    // where cos a >= 0, and cos a cos t + sin t where it is not.
    const T d = sqrt(d2), sine = radius / d;
    const T c = dot(*normal, to_center) / d;
    largest_cosine = min(T(1), (c < T(0) ? c * sqrt(max(T(0), T(1) - sine * sine)) : c) + sine);
    if (!(largest_cosine > T(0))) return T(-1);
  }
  return light.brightest * largest_cosine / (pi<T>() * cone_density(light.pmf, sphere_cone_width(r2, d2)));
}

// The density per unit solid angle with which sample_light, from the ray's origin, gives the ray's (unit) direction,
// where the ray meets the light of `entry` at `hit`, described by `at`; as the format carries it (light_density).
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
      return exact_light_density<T>(S::exact(light.pmf) * S::exact(t) * S::exact(t), S::exact(cosine) * S::exact(a1) * S::exact(a2));
    } else {
      return light.pmf * (t * t) / (cosine * (a1 * a2));
    }
  };
  auto per_area = [&](T area) {
    if constexpr (ScalarTraits<T>::kExactProducts)
      return per_area2(area, T(1));
    else
      return light.pmf * (t * t) / (cosine * area);
  };
  auto sphere = [&](const Vec3<T>& center, T radius) {
    if constexpr (ScalarTraits<T>::kExactProducts) {
      const T d = length(center - from);
      if (d > radius) {
        const T sine = radius / d;
        return cone_density(light.pmf, sphere_cone_width(sine * sine, T(1)));
      }
      return per_area2(constant<T>(4) * pi<T>() * radius, radius);
    } else {
      const T d2 = length_squared(center - from);
      const T r2 = radius * radius;
      if (d2 > r2) return cone_density(light.pmf, sphere_cone_width(r2, d2));
      return per_area(constant<T>(4) * pi<T>() * r2);
    }
  };
  Vec3<T> center;
  T radius;
  if (sphere_at(primitive, ray.time, center, radius)) return sphere(center, radius);
  if (const auto* q = std::get_if<Quad<T>>(&primitive.shape)) {
    SphericalRectangle<T> rectangle;
    if (spherical_rectangle(scene.lights.rectangles[entry], q->corner, from, rectangle)) return light_density(light.pmf, rectangle.solid_angle);
    // |u x v| = u_extent (v_extent / normal.(du x dv)) (quad_area).
    if constexpr (ScalarTraits<T>::kExactProducts)
      return per_area2(q->u_extent, abs(q->v_extent / dot(q->normal, cross(q->du, q->dv))));
    else
      return per_area(quad_area(*q));
  }
  if (const auto* tri = std::get_if<Triangle<T>>(&primitive.shape)) return per_area(triangle_area(tri->edge1, tri->edge2));
  if (const auto* instance = std::get_if<MeshInstance<T>>(&primitive.shape)) {
    const MeshRecord& mesh = scene.meshes.meshes[instance->mesh];
    const u32 start = light.first_cdf + (hit.triangle - mesh.first_triangle);
    const T share = scene.lights.triangle_cdf[start + 1] - scene.lights.triangle_cdf[start];
    Vec3<T> p[3];
    world_triangle(scene.meshes, *instance, hit.triangle, p);
    const T per_area_of_mesh = per_area(triangle_area(p[1] - p[0], p[2] - p[0]));
    // The triangle's share of the mesh's probability: a reciprocal is divided by it.
    if constexpr (kReciprocalLightDensity<T>)
      return ScalarTraits<T>::exact_quotient(ScalarTraits<T>::exact(per_area_of_mesh), ScalarTraits<T>::exact(share));
    else
      return share * per_area_of_mesh;
  }
  return T(0);
}

}  // namespace pt
