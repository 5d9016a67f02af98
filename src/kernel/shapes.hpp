// Shapes: ray intersection (distance only, cheap, called many times per ray) and the surface description
// (normal, texture coordinates; called once for the closest hit).
#pragma once

#include <variant>

#include "kernel/material.hpp"

namespace pt {

template <class T> struct Sphere { Vec3<T> center; T radius; };

// A sphere whose centre moves linearly: centre(time) = center0 + velocity * (time - time0).
template <class T> struct MovingSphere { Vec3<T> center0; T radius; Vec3<T> velocity; T time0; };

// Vertices p0, p0 + edge1, p0 + edge2; `attributes` indexes per-vertex normals and uvs, or is -1.
template <class T> struct Triangle { Vec3<T> p0, edge1, edge2; i32 attributes; };

template <class T>
struct TriangleAttributes {
  Vec3<T> normal[3];
  T u[3], v[3];
  u32 has_normals, has_uvs;
};

// The parallelogram corner + a u + b v for a, b in [0, 1], stored as its plane's unit normal and the dual edge
// vectors du, dv (du.u = dv.v = 1, du.v = dv.u = 0), so that a = du.(p - corner) and b = dv.(p - corner).
// Every stored value has the size of a length or of its reciprocal, never of 1/area, so narrow number formats
// keep it precise, and a hit costs two dot products instead of two cross products.
template <class T> struct Quad { Vec3<T> corner, normal, du, dv; };

template <class T>
PT_HD inline Quad<T> make_quad(const Vec3<T>& corner, const Vec3<T>& u, const Vec3<T>& v) {
  const Vec3<T> n = cross(u, v);
  const T area_squared = length_squared(n);
  return Quad<T>{corner, n / sqrt(area_squared), cross(v, n) / area_squared, cross(n, u) / area_squared};
}

// The edges u and v back from the dual vectors (for bounds): du x dv = normal / |u x v|, u = |u x v| dv x normal,
// v = |u x v| normal x du.
template <class T>
PT_HD inline void quad_edges(const Quad<T>& q, Vec3<T>& u, Vec3<T>& v) {
  const T area = T(1) / dot(q.normal, cross(q.du, q.dv));
  u = area * cross(q.dv, q.normal);
  v = area * cross(q.normal, q.du);
}

// A constant-density medium inside a convex boundary made of `boundary_count` geometric primitives stored from
// `first_boundary` in the scene's boundary array. neg_inv_density = -1 / density.
template <class T> struct ConstantMedium { u32 first_boundary, boundary_count; T neg_inv_density; };

template <class T>
using Shape = std::variant<Sphere<T>, MovingSphere<T>, Triangle<T>, Quad<T>, ConstantMedium<T>>;

template <class T>
struct Primitive {
  Shape<T> shape;
  u32 material;
};

// The closest hit found so far: distance, two surface parameters (barycentrics, quad coordinates) and which primitive.
template <class T>
struct Hit {
  T t;
  T b1, b2;
  u32 primitive;
};

// What intersecting a medium needs besides the ray: its boundary and a random number for the free-flight distance.
template <class T>
struct IntersectContext {
  const Primitive<T>* boundaries;
  const SampleRandom* random;
  u32 bounce;
};

// The two distances at which the ray's line crosses the sphere, nearest first; false where it misses. With a unit
// direction the quadratic is t^2 + 2 b t + c; the discriminant is formed from the perpendicular distance to the
// centre, which stays accurate for large spheres seen from close by.
template <class T>
PT_HD inline bool sphere_roots(const Vec3<T>& center, T radius, const Ray<T>& ray, T& near, T& far) {
  const Vec3<T> oc = ray.origin - center;
  const T b = dot(oc, ray.direction);
  const Vec3<T> perpendicular = oc - b * ray.direction;
  const T discriminant = radius * radius - length_squared(perpendicular);
  if (discriminant < T(0)) return false;
  const T root = sqrt(discriminant);
  near = -b - root;
  far = -b + root;
  return true;
}

template <class T>
PT_HD inline bool intersect_sphere(const Vec3<T>& center, T radius, const Ray<T>& ray, T t_min, T t_max, Hit<T>& hit) {
  T near, far;
  if (!sphere_roots(center, radius, ray, near, far)) return false;
  T t = near;
  if (!(t > t_min && t < t_max)) {
    t = far;
    if (!(t > t_min && t < t_max)) return false;
  }
  hit.t = t;
  hit.b1 = T(0);
  hit.b2 = T(0);
  return true;
}

template <class T>
PT_HD inline Vec3<T> moving_sphere_center(const MovingSphere<T>& s, T time) {
  return s.center0 + (time - s.time0) * s.velocity;
}

// Möller-Trumbore.
template <class T>
PT_HD inline bool intersect_triangle(const Triangle<T>& tri, const Ray<T>& ray, T t_min, T t_max, Hit<T>& hit) {
  const Vec3<T> pvec = cross(ray.direction, tri.edge2);
  const T det = dot(tri.edge1, pvec);
  if (det == T(0)) return false;
  const T inv_det = T(1) / det;
  const Vec3<T> tvec = ray.origin - tri.p0;
  const T b1 = dot(tvec, pvec) * inv_det;
  if (!(b1 >= T(0) && b1 <= T(1))) return false;
  const Vec3<T> qvec = cross(tvec, tri.edge1);
  const T b2 = dot(ray.direction, qvec) * inv_det;
  if (!(b2 >= T(0) && b1 + b2 <= T(1))) return false;
  const T t = dot(tri.edge2, qvec) * inv_det;
  if (!(t > t_min && t < t_max)) return false;
  hit.t = t;
  hit.b1 = b1;
  hit.b2 = b2;
  return true;
}

template <class T>
PT_HD inline bool intersect_quad(const Quad<T>& q, const Ray<T>& ray, T t_min, T t_max, Hit<T>& hit) {
  const T denominator = dot(q.normal, ray.direction);
  if (denominator == T(0)) return false;
  const T t = dot(q.normal, q.corner - ray.origin) / denominator;
  if (!(t > t_min && t < t_max)) return false;
  const Vec3<T> planar = ray.at(t) - q.corner;
  const T a = dot(q.du, planar);
  const T b = dot(q.dv, planar);
  if (!(a >= T(0) && a <= T(1) && b >= T(0) && b <= T(1))) return false;
  hit.t = t;
  hit.b1 = a;
  hit.b2 = b;
  return true;
}

// Closest intersection with a purely geometric primitive. Media are not geometric (they never nest), so a
// medium here never intersects.
template <class T>
PT_HD inline bool intersect_geometry(const Shape<T>& shape, const Ray<T>& ray, T t_min, T t_max, Hit<T>& hit) {
  struct Intersect {
    const Ray<T>& ray;
    T t_min, t_max;
    Hit<T>& hit;
    PT_HD bool operator()(const Sphere<T>& s) const { return intersect_sphere(s.center, s.radius, ray, t_min, t_max, hit); }
    PT_HD bool operator()(const MovingSphere<T>& s) const {
      return intersect_sphere(moving_sphere_center(s, ray.time), s.radius, ray, t_min, t_max, hit);
    }
    PT_HD bool operator()(const Triangle<T>& tri) const { return intersect_triangle(tri, ray, t_min, t_max, hit); }
    PT_HD bool operator()(const Quad<T>& q) const { return intersect_quad(q, ray, t_min, t_max, hit); }
    PT_HD bool operator()(const ConstantMedium<T>&) const { return false; }
  };
  return visit(Intersect{ray, t_min, t_max, hit}, shape);
}

// Widens [first, last] to take in every distance, anywhere along the ray's line, at which the line crosses one piece
// of a medium's boundary (a sphere twice, a face once).
template <class T>
PT_HD inline void widen_to_crossings(const Shape<T>& piece, const Ray<T>& ray, T& first, T& last) {
  if (const auto* s = std::get_if<Sphere<T>>(&piece)) {
    T near, far;
    if (sphere_roots(s->center, s->radius, ray, near, far)) {
      first = min(first, near);
      last = max(last, far);
    }
    return;
  }
  Hit<T> hit{};
  if (intersect_geometry(piece, ray, -largest<T>(), largest<T>(), hit)) {
    first = min(first, hit.t);
    last = max(last, hit.t);
  }
}

// A ray crossing a medium scatters inside it after an exponentially distributed free flight. The boundary is convex,
// so the line is inside it between its first and its last crossing (at an edge or a corner several faces give the
// same distance): no tolerance separates the way in from the way out, whatever the scene's scale.
template <class T>
PT_HD inline bool intersect_medium(const ConstantMedium<T>& medium, u32 primitive_index, const IntersectContext<T>& context,
                                   const Ray<T>& ray, T t_min, T t_max, Hit<T>& hit) {
  T entry = largest<T>(), exit = -largest<T>();
  for (u32 i = 0; i < medium.boundary_count; ++i) widen_to_crossings(context.boundaries[medium.first_boundary + i].shape, ray, entry, exit);
  entry = max(entry, t_min);
  exit = min(exit, t_max);
  if (!(entry < exit)) return false;
  entry = max(entry, T(0));
  const T u = context.random->template uniform<T>(context.bounce, kDimMediumBase + primitive_index);
  const T distance = medium.neg_inv_density * log(T(1) - u);  // 1 - u lies in (0, 1]: the logarithm is finite
  if (distance > exit - entry) return false;
  hit.t = entry + distance;
  hit.b1 = T(0);
  hit.b2 = T(0);
  return true;
}

template <class T>
PT_HD inline bool intersect_primitive(const Primitive<T>& primitive, u32 index, const IntersectContext<T>& context,
                                      const Ray<T>& ray, T t_min, T t_max, Hit<T>& hit) {
  if (const auto* medium = std::get_if<ConstantMedium<T>>(&primitive.shape))
    return intersect_medium(*medium, index, context, ray, t_min, t_max, hit);
  return intersect_geometry(primitive.shape, ray, t_min, t_max, hit);
}

// Sphere texture coordinates from the outward unit normal.
template <class T>
PT_HD inline void sphere_uv(const Vec3<T>& n, T& u, T& v) {
  u = T(1) - (atan2(n.z, n.x) + pi<T>()) / (constant<T>(2) * pi<T>());
  v = (asin(clamp(n.y, T(-1), T(1))) + pi<T>() / constant<T>(2)) / pi<T>();
}

template <class T>
PT_HD inline void set_face_normal(SurfacePoint<T>& at, const Ray<T>& ray, const Vec3<T>& outward) {
  at.front_face = dot(ray.direction, outward) < T(0);
  at.normal = at.front_face ? outward : -outward;
}

// Robust ray spawning. A hit point computed in the scalar type lies off the exact surface by its rounding error, and
// a ray leaving it may meet the same surface again a tiny distance away (self-intersection: missing light, worst at
// grazing angles and far from the origin, where float's steps are coarse). Instead of ignoring hits closer than a
// fixed distance, each shape bounds, component by component, the error of its hit point plus that of a new test of
// the same surface from there, and describe_hit turns the bound into an offset along the geometric normal (pbrt's
// approach); spawn_ray starts the next ray that far off the surface, on the side it goes to, where the surface can
// no longer be met. The bounds are relative to the size of the coordinates involved (absolute, in steps, for fixed
// point), so a scene renders the same picture at any scale and position. The largest is a grazing new test of a
// sphere: its discriminant r^2 - |perp|^2 rounds by about 8 u r^2 (u the unit roundoff), 4 u r as a distance, on top
// of the re-projected point's u (|c| + 2 r); kSpawnRoundings = 8 covers both. (RaySpawning's grazing rays get
// through with 2 and never with 4.) A larger factor only moves rays farther off surfaces, where they start inside
// whatever touches the surface (a small sphere resting on a large one).
inline constexpr double kSpawnRoundings = 8;

template <class T>
PT_HD inline void set_spawn_offset(SurfacePoint<T>& at, const Vec3<T>& unit_normal, const Vec3<T>& error) {
  at.geometric_normal = unit_normal;
  at.offset = dot(vabs(unit_normal), error);
}

// Full description of the closest hit. With needs_uv false the texture coordinates of spheres are left at 0
// (the material's textures do not read them); those of triangles and quads cost nothing and are always set.
template <class T>
PT_HD inline SurfacePoint<T> describe_hit(const Primitive<T>& primitive, const TriangleAttributes<T>* triangle_attributes,
                                          const Ray<T>& ray, const Hit<T>& hit, bool needs_uv = true) {
  struct Describe {
    const TriangleAttributes<T>* attributes;
    const Ray<T>& ray;
    const Hit<T>& hit;
    SurfacePoint<T>& at;
    bool needs_uv;

    PT_HD void sphere(const Vec3<T>& center, T radius) const {
      // Re-projected onto the sphere, the point's error is that of the centre and the radius, however long the ray.
      // A new test from there rounds the squared radius and distances: an error of the radius's size. The normal is
      // the same direction divided by the radius (unit to within the hit point's error), so that the shading, which
      // waits for it, does not wait for the square root.
      const Vec3<T> from_center = at.p - center;
      const Vec3<T> outward = from_center / radius;
      at.p = center + from_center * (radius / length(from_center));
      set_spawn_offset(at, outward, rounding_error(vabs(center) + Vec3<T>::splat(radius), constant<T>(kSpawnRoundings)));
      set_face_normal(at, ray, outward);
      if (needs_uv) sphere_uv(outward, at.u, at.v);
    }
    PT_HD void operator()(const Sphere<T>& s) const { sphere(s.center, s.radius); }
    PT_HD void operator()(const MovingSphere<T>& s) const { sphere(moving_sphere_center(s, ray.time), s.radius); }
    PT_HD void operator()(const Triangle<T>& tri) const {
      const Vec3<T> area_normal = cross(tri.edge1, tri.edge2);
      const T twice_area = length(area_normal);
      const Vec3<T> geometric = area_normal / twice_area;
      // From the barycentrics the point lies on the triangle's plane up to the rounding of the interpolation. A new
      // test measures the distance to the plane through cross products of the edges, whose rounding, relative to
      // that distance, grows as 1 / sin of the corner's angle, |e1| |e2| / |e1 x e2|.
      const Vec3<T> along1 = hit.b1 * tri.edge1, along2 = hit.b2 * tri.edge2;
      at.p = tri.p0 + along1 + along2;
      const T skew = length(tri.edge1) * length(tri.edge2) / twice_area;
      const T roundings = constant<T>(kSpawnRoundings);
      set_spawn_offset(at, geometric, rounding_error(vabs(tri.p0) + vabs(along1) + vabs(along2), roundings) +
                                          rounding_error(vabs(tri.edge1) + vabs(tri.edge2), roundings * skew));
      at.front_face = dot(ray.direction, geometric) < T(0);
      const T b0 = T(1) - hit.b1 - hit.b2;
      Vec3<T> shading = geometric;
      at.u = hit.b1;
      at.v = hit.b2;
      if (tri.attributes >= 0) {
        const TriangleAttributes<T>& a = attributes[tri.attributes];
        if (a.has_normals) {
          const Vec3<T> interpolated = b0 * a.normal[0] + hit.b1 * a.normal[1] + hit.b2 * a.normal[2];
          const T len2 = length_squared(interpolated);
          if (len2 > T(0)) shading = interpolated / sqrt(len2);
          // Keep the shading normal on the geometric side so the normal still tells front from back.
          if (dot(shading, geometric) < T(0)) shading = -shading;
        }
        if (a.has_uvs) {
          at.u = b0 * a.u[0] + hit.b1 * a.u[1] + hit.b2 * a.u[2];
          at.v = b0 * a.v[0] + hit.b1 * a.v[1] + hit.b2 * a.v[2];
        }
      }
      at.normal = at.front_face ? shading : -shading;
    }
    PT_HD void operator()(const Quad<T>& q) const {
      // Re-projected onto the quad's plane, the point's error no longer grows with the ray's length; a new test
      // rounds the distance from the corner.
      at.p = at.p - dot(q.normal, at.p - q.corner) * q.normal;
      set_spawn_offset(at, q.normal, rounding_error(vabs(at.p) + vabs(at.p - q.corner), constant<T>(kSpawnRoundings)));
      set_face_normal(at, ray, q.normal);
      at.u = hit.b1;
      at.v = hit.b2;
    }
    PT_HD void operator()(const ConstantMedium<T>&) const {
      // Scattering inside a medium has no surface: the phase function ignores normal and texture coordinates, and
      // the next ray starts at the point itself.
      at.normal = Vec3<T>{T(1), T(0), T(0)};
      at.geometric_normal = at.normal;
      at.offset = T(0);
      at.front_face = true;
      at.u = T(0);
      at.v = T(0);
    }
  };
  SurfacePoint<T> at{};
  at.p = ray.at(hit.t);
  at.material = primitive.material;
  visit(Describe{triangle_attributes, ray, hit, at, needs_uv}, primitive.shape);
  return at;
}

}  // namespace pt
