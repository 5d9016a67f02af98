// Shapes: ray intersection (distance only, cheap, called many times per ray) and the surface description
// (normal, texture coordinates; called once for the closest hit).
#pragma once

#include <variant>

#include "kernel/material.hpp"

namespace pt {

template <class T>
struct Sphere {
  Vec3<T> center;
  T radius;
};

// A sphere whose centre moves linearly: centre(time) = center0 + velocity * (time - time0).
template <class T>
struct MovingSphere {
  Vec3<T> center0;
  T radius;
  Vec3<T> velocity;
  T time0;
};

// Vertices p0, p0 + edge1, p0 + edge2; `attributes` indexes per-vertex normals and uvs, or is -1.
template <class T>
struct Triangle {
  Vec3<T> p0, edge1, edge2;
  i32 attributes;
};

template <class T>
struct TriangleAttributes {
  Vec3<T> normal[3];
  T u[3], v[3];
  u32 has_normals, has_uvs;
};

// The parallelogram corner + a u + b v for a, b in [0, 1], stored as its plane's unit normal and the dual edge
// vectors (u* with u*.u = 1, u*.v = 0, and v* likewise), each times an extent: du = u_extent u*, dv = v_extent v*,
// so that a = du.(p - corner) / u_extent and b = dv.(p - corner) / v_extent. Floating point stores extents of 1
// (du and dv are the dual edges, sizes of 1 / edge length: no division per test), and so does every format without
// exact products (ScalarTraits::kExactProducts: the tests below assume it); fixed point with them, a power of two near
// the edge's length (ScalarTraits::quad_extent), so that du and dv have sizes near 1 and keep every fraction bit
// (1/555, a Cornell wall's, has 7 significant bits in Q16.16), and dividing by the extent is a shift. No stored
// value has the size of 1/area, and a hit costs two dot products instead of two cross products.
template <class T>
struct Quad {
  Vec3<T> corner, normal, du, dv;
  T u_extent, v_extent;
};

template <class T>
PT_HD inline Quad<T> make_quad(const Vec3<T>& corner, const Vec3<T>& u, const Vec3<T>& v) {
  const Vec3<T> n = cross(u, v);
  const T area_squared = length_squared(n);
  return Quad<T>{corner, n / sqrt(area_squared), cross(v, n) / area_squared, cross(n, u) / area_squared, T(1), T(1)};
}

// A quad's area |u x v|, from its dual vectors: u* x v* = normal / |u x v|, and du x dv = u_extent v_extent u* x v*.
template <class T>
PT_HD inline T quad_area(const Quad<T>& q) {
  return abs(q.u_extent * (q.v_extent / dot(q.normal, cross(q.du, q.dv))));
}

// A triangle's area from two of its edges.
template <class T>
PT_HD inline T triangle_area(const Vec3<T>& edge1, const Vec3<T>& edge2) {
  return length(cross(edge1, edge2)) / constant<T>(2);
}

// The edges u and v back from the dual vectors (for bounds): u = |u x v| v* x normal, v = |u x v| normal x u*,
// which with D = normal.(du x dv) = u_extent v_extent / |u x v| is u = (u_extent / D) dv x normal and
// v = (v_extent / D) normal x du.
template <class T>
PT_HD inline void quad_edges(const Quad<T>& q, Vec3<T>& u, Vec3<T>& v) {
  const T d = dot(q.normal, cross(q.du, q.dv));
  u = (q.u_extent / d) * cross(q.dv, q.normal);
  v = (q.v_extent / d) * cross(q.normal, q.du);
}

// A quad in another scalar type, from one in double with extents of 1 (make_quad's): du and dv times the type's
// extents for the edges' lengths (host code for tests; flatten_scene converts through its range checks instead).
template <class T>
inline Quad<T> quad_in(const Quad<double>& q) {
  Vec3<double> u, v;
  quad_edges(q, u, v);
  const double eu = ScalarTraits<T>::quad_extent(length(u)), ev = ScalarTraits<T>::quad_extent(length(v));
  auto to = [](const Vec3<double>& a) { return Vec3<T>{static_cast<T>(a.x), static_cast<T>(a.y), static_cast<T>(a.z)}; };
  return Quad<T>{to(q.corner), to(q.normal), to(q.du * eu), to(q.dv * ev), static_cast<T>(eu), static_cast<T>(ev)};
}

// A constant-density medium inside a convex boundary made of `boundary_count` geometric primitives stored from
// `first_boundary` in the scene's boundary array. neg_inv_density = -1 / density.
template <class T>
struct ConstantMedium {
  u32 first_boundary, boundary_count;
  T neg_inv_density;
};

// ---- Triangle meshes ----
// A mesh's vertices and triangles lie in arrays shared by all meshes (MeshData): positions, and where the mesh has
// them, normals and texture coordinates, indexed per mesh from the mesh's first entries. A mesh has its own BVH
// (built once however often it is placed); the scene's BVH holds instances, each placing a mesh by an affine map,
// or with none where the mesh's vertices are stored in world space already (a mesh placed once).
template <class T>
struct BvhNode;
template <class T>
struct WideBvhNode;
struct CompressedWideNode;  // kernel/compressed_bvh.hpp

// Vertex indices within its mesh, and its material.
struct MeshTriangle {
  u32 vertex[3];
  u32 material;
};

template <class T>
struct MeshUv {
  T u, v;
};

// A vertex's tangent as a model file gives it (glTF's TANGENT): its direction (along increasing u) and the sign of
// the bitangent, sign * normal x direction. Kept only for meshes whose material has a normal map.
template <class T>
struct MeshTangent {
  Vec3<T> direction;
  T sign;
};

inline constexpr u32 kNoAttributes = 0xffffffffu;

struct MeshRecord {
  u32 first_vertex;
  u32 first_normal;  // kNoAttributes where the mesh has no normals
  u32 first_uv;      // kNoAttributes where it has no texture coordinates
  u32 root;          // its BVH's root in MeshData::nodes, and the same tree's in wide_nodes
  u32 wide_root;
  u32 first_triangle, triangle_count;  // its triangles in MeshData::triangles
  u32 first_tangent;                   // kNoAttributes where it has no vertex tangents (they are derived from the uvs where needed)
};

// An affine map as the rows of its 3x4 matrix.
template <class T>
struct AffineRows {
  Vec3<T> row[3];
  Vec3<T> translation;
  PT_HD Vec3<T> vector(const Vec3<T>& v) const { return Vec3<T>{dot(row[0], v), dot(row[1], v), dot(row[2], v)}; }
  PT_HD Vec3<T> point(const Vec3<T>& p) const { return vector(p) + translation; }
  // |M| v: bounds how much the map can grow errors of size v.
  PT_HD Vec3<T> abs_vector(const Vec3<T>& v) const { return Vec3<T>{dot(vabs(row[0]), v), dot(vabs(row[1]), v), dot(vabs(row[2]), v)}; }
};

// The world-to-mesh map rays are taken into, the mesh-to-world map hits are brought back by, and the rows of the
// inverse transpose that carries normals (times the sign of the determinant, so orientation is kept).
template <class T>
struct InstanceTransform {
  AffineRows<T> to_mesh, to_world;
  Vec3<T> normal_rows[3];
  PT_HD Vec3<T> normal(const Vec3<T>& n) const { return Vec3<T>{dot(normal_rows[0], n), dot(normal_rows[1], n), dot(normal_rows[2], n)}; }
};

inline constexpr u32 kNoTransform = 0xffffffffu;
// An instance's Primitive::material where each triangle keeps its own.
inline constexpr u32 kMeshMaterials = 0xffffffffu;

template <class T>
struct MeshInstance {
  u32 mesh;
  u32 transform;
};  // transform: into MeshData::transforms, or kNoTransform

template <class T>
struct MeshData {
  const Vec3<T>* positions;
  const Vec3<T>* normals;
  const MeshUv<T>* uvs;
  const MeshTriangle* triangles;  // in BVH order per mesh; leaves index them directly
  const MeshRecord* meshes;
  const InstanceTransform<T>* transforms;
  const BvhNode<T>* nodes;
  const WideBvhNode<T>* wide_nodes;
  const CompressedWideNode* compressed_nodes;  // the wide nodes compressed where a backend walks them, at the same indices; else null
  const MeshTangent<T>* tangents;
};

template <class T>
using Shape = std::variant<Sphere<T>, MovingSphere<T>, Triangle<T>, Quad<T>, ConstantMedium<T>, MeshInstance<T>>;

template <class T>
struct Primitive {
  Shape<T> shape;
  u32 material;
};

// The closest hit found so far: distance, two surface parameters (barycentrics, quad coordinates), which primitive,
// and for a mesh instance which of the mesh triangles (an index into MeshData::triangles).
template <class T>
struct Hit {
  T t;
  T b1, b2;
  u32 primitive;
  u32 triangle;
};

// What intersecting a medium needs besides the ray: its boundary and a random number for the free-flight distance.
// A shadow ray gives `optical_depth` instead: media do not stop it, they add density x the length of the ray inside
// them (up to the closest hit so far) to it, and the caller weights by the transmittance exp(-optical_depth).
// A shadow ray may also give `blocked_before`: a hit nearer than that on any primitive but `light_primitive` (the
// light it aims at) blocks it whatever else lies nearer, so the walk stops at the first such hit (0: the closest hit
// is searched for).
template <class T>
struct IntersectContext {
  const Primitive<T>* boundaries;
  const SampleRandom* random;
  u32 bounce;
  T* optical_depth = nullptr;
  T blocked_before = T(0);
  u32 light_primitive = ~0u;
};

// ---- Exact products (fixed point of up to 32 bits, ScalarTraits::kExactProducts) ----
// Products of two values kept with 2F fraction bits, of three with 3F, in the traits' Exact integers: dot and cross
// products are exact, nothing squared overflows, and a test rounds once per result (a quotient or a root).
template <class T>
struct ExactVec3 {
  typename ScalarTraits<T>::Exact x, y, z;
};

template <class T>
PT_HD inline typename ScalarTraits<T>::Exact exact_dot(const Vec3<T>& a, const Vec3<T>& b) {
  using S = ScalarTraits<T>;
  return S::exact(a.x) * S::exact(b.x) + S::exact(a.y) * S::exact(b.y) + S::exact(a.z) * S::exact(b.z);
}

template <class T>
PT_HD inline typename ScalarTraits<T>::Exact exact_dot(const Vec3<T>& a, const ExactVec3<T>& b) {
  using S = ScalarTraits<T>;
  return S::exact(a.x) * b.x + S::exact(a.y) * b.y + S::exact(a.z) * b.z;
}

template <class T>
PT_HD inline ExactVec3<T> exact_cross(const Vec3<T>& a, const Vec3<T>& b) {
  using S = ScalarTraits<T>;
  return ExactVec3<T>{S::exact(a.y) * S::exact(b.z) - S::exact(a.z) * S::exact(b.y), S::exact(a.z) * S::exact(b.x) - S::exact(a.x) * S::exact(b.z),
                      S::exact(a.x) * S::exact(b.y) - S::exact(a.y) * S::exact(b.x)};
}

// The two distances at which the ray's line crosses the sphere, nearest first; false where it misses. With a unit
// direction the quadratic is t^2 + 2 b t + c; the discriminant is formed from the perpendicular distance to the
// centre, which stays accurate for large spheres seen from close by.
// With exact products the direction need not be unit: with a = d.d, b = oc.d and oc x d exact (2F fraction bits),
// the quadratic a t^2 + 2 b t + c has the discriminant a r^2 - |oc x d|^2 (Lagrange's identity), exact (4F), its
// root rounded to nearest once and kept with 2F, and each crossing (-b -+ root) / a one quotient: the crossings of
// the line through the rounded origin along the rounded direction, within a step, whatever the radius (a sphere of
// radius 1000 in Q16.16 without scaling the scene; nothing squared is ever rounded to the format).
template <class T>
PT_HD inline bool sphere_roots(const Vec3<T>& center, T radius, const Ray<T>& ray, T& near, T& far) {
  if constexpr (ScalarTraits<T>::kExactProducts) {
    using S = ScalarTraits<T>;
    const Vec3<T> oc = ray.origin - center;
    const auto a = exact_dot(ray.direction, ray.direction);
    const auto b = exact_dot(oc, ray.direction);
    const ExactVec3<T> across = exact_cross(oc, ray.direction);
    const auto discriminant = S::exact(radius) * S::exact(radius) * a - (across.x * across.x + across.y * across.y + across.z * across.z);
    if (discriminant < 0) return false;
    const auto root = S::exact_root(discriminant);
    near = S::exact_quotient(-b - root, a);
    far = S::exact_quotient(-b + root, a);
    return true;
  }
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

// Möller-Trumbore. With exact products (fixed point): p = d x e2 and q = (o - p0) x e1 exact (2F fraction bits),
// det = e1.p, b1 = (o - p0).p, b2 = d.q and t = e2.q exact (3F); the inside test compares these exactly (sign of
// det folded in), and b1, b2 and t are each one quotient, truncated. Nothing overflows however large the scene or
// small the triangle (det of a 0.01-unit triangle is 1e-4, 7 steps of Q16.16, if rounded).
template <class T>
PT_HD inline bool intersect_triangle(const Triangle<T>& tri, const Ray<T>& ray, T t_min, T t_max, Hit<T>& hit) {
  if constexpr (ScalarTraits<T>::kExactProducts) {
    using S = ScalarTraits<T>;
    const ExactVec3<T> pvec = exact_cross(ray.direction, tri.edge2);
    auto det = exact_dot(tri.edge1, pvec);
    if (det == 0) return false;
    const Vec3<T> tvec = ray.origin - tri.p0;
    auto b1 = exact_dot(tvec, pvec);
    const ExactVec3<T> qvec = exact_cross(tvec, tri.edge1);
    auto b2 = exact_dot(ray.direction, qvec);
    auto t = exact_dot(tri.edge2, qvec);
    if (det < 0) det = -det, b1 = -b1, b2 = -b2, t = -t;
    if (!(b1 >= 0 && b2 >= 0 && b1 + b2 <= det)) return false;
    const T distance = S::exact_quotient(t, det);
    if (!(distance > t_min && distance < t_max)) return false;
    hit.t = distance;
    hit.b1 = S::exact_fraction(b1, det);
    hit.b2 = S::exact_fraction(b2, det);
    return true;
  }
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

// With exact products (fixed point): t = n.(corner - o) / n.d, both dot products exact, one quotient (truncated);
// planar = o + t d - corner rounded per operation; du.planar and dv.planar exact (2F fraction bits) and compared
// with [0, extent] exactly; the coordinates a and b are those divided by the extents (truncated: a power of two,
// a shift).
// kOntoQuad: where the ray meets the quad's plane outside the quad, its coordinates are clamped onto the quad's
// edges instead of missing (quad_light_reached).
template <class T, bool kOntoQuad = false>
PT_HD inline bool intersect_quad(const Quad<T>& q, const Ray<T>& ray, T t_min, T t_max, Hit<T>& hit) {
  if constexpr (ScalarTraits<T>::kExactProducts) {
    using S = ScalarTraits<T>;
    const auto denominator = exact_dot(q.normal, ray.direction);
    if (denominator == 0) return false;
    const T t = S::exact_quotient(exact_dot(q.normal, q.corner - ray.origin), denominator);
    if (!(t > t_min && t < t_max)) return false;
    const Vec3<T> planar = ray.at(t) - q.corner;
    auto a = exact_dot(q.du, planar), b = exact_dot(q.dv, planar);
    const auto one = S::exact(T(1));
    const auto a_max = S::exact(q.u_extent) * one, b_max = S::exact(q.v_extent) * one;
    if constexpr (kOntoQuad) {
      a = a < 0 ? 0 : (a > a_max ? a_max : a);
      b = b < 0 ? 0 : (b > b_max ? b_max : b);
    }
    if (!(a >= 0 && a <= a_max && b >= 0 && b <= b_max)) return false;
    hit.t = t;
    hit.b1 = S::exact_quotient_by_extent(a, q.u_extent);
    hit.b2 = S::exact_quotient_by_extent(b, q.v_extent);
    return true;
  }
  const T denominator = dot(q.normal, ray.direction);
  if (denominator == T(0)) return false;
  const T t = dot(q.normal, q.corner - ray.origin) / denominator;
  if (!(t > t_min && t < t_max)) return false;
  const Vec3<T> planar = ray.at(t) - q.corner;
  T a = dot(q.du, planar);
  T b = dot(q.dv, planar);
  if constexpr (kOntoQuad) {
    a = clamp(a, T(0), T(1));
    b = clamp(b, T(0), T(1));
  }
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
    PT_HD bool operator()(const MeshInstance<T>&) const { return false; }  // walked by the BVH code (intersect_instance)
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

// The free-flight distance a ray draws in a constant medium, exponentially distributed: from the ray's random number
// for the medium (its index) at this bounce, so it depends on neither the walk nor the geometry (the rtl backend draws
// it before the ray enters its engine). 1 - u lies in (0, 1]: the logarithm is finite.
template <class T>
PT_HD inline T medium_free_flight(const ConstantMedium<T>& medium, u32 primitive_index, const SampleRandom& random, u32 bounce) {
  return medium.neg_inv_density * log(T(1) - random.template uniform<T>(bounce, kDimMediumBase + primitive_index));
}

// What a medium does to a ray whose line is inside it from `first` to `last`: the stretch within (t_min, t_max) and
// ahead of the origin; a shadow ray (optical_depth given) adds density x its length there and is never stopped; another
// scatters at the free-flight distance `free_flight()` (drawn only where the stretch is not empty) if it falls within.
template <class T, class FreeFlight>
PT_HD inline bool medium_event(T first, T last, T t_min, T t_max, T neg_inv_density, T* optical_depth, const FreeFlight& free_flight,
                               Hit<T>& hit) {
  T entry = max(first, t_min);
  const T exit = min(last, t_max);
  if (!(entry < exit)) return false;
  entry = max(entry, T(0));
  if (optical_depth) {
    if (entry < exit) *optical_depth += (entry - exit) / neg_inv_density;
    return false;
  }
  const T distance = free_flight();
  if (distance > exit - entry) return false;
  hit.t = entry + distance;
  hit.b1 = T(0);
  hit.b2 = T(0);
  return true;
}

// A ray crossing a medium scatters inside it after an exponentially distributed free flight. The boundary is convex,
// so the line is inside it between its first and its last crossing (at an edge or a corner several faces give the
// same distance): no tolerance separates the way in from the way out, whatever the scene's scale.
template <class T>
PT_HD inline bool intersect_medium(const ConstantMedium<T>& medium, u32 primitive_index, const IntersectContext<T>& context, const Ray<T>& ray,
                                   T t_min, T t_max, Hit<T>& hit) {
  T first = largest<T>(), last = -largest<T>();
  for (u32 i = 0; i < medium.boundary_count; ++i) widen_to_crossings(context.boundaries[medium.first_boundary + i].shape, ray, first, last);
  return medium_event(first, last, t_min, t_max, medium.neg_inv_density, context.optical_depth,
                      [&] { return medium_free_flight(medium, primitive_index, *context.random, context.bounce); }, hit);
}

template <class T>
PT_HD inline bool intersect_primitive(const Primitive<T>& primitive, u32 index, const IntersectContext<T>& context, const Ray<T>& ray, T t_min,
                                      T t_max, Hit<T>& hit) {
  hit.triangle = 0;  // only a mesh's hits name a triangle
  if (const auto* medium = std::get_if<ConstantMedium<T>>(&primitive.shape)) return intersect_medium(*medium, index, context, ray, t_min, t_max, hit);
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

// The magnitude of the coordinates a hit point's error bound grows with. With exact products (fixed point, kernel
// traits) a new test of a plane finds the side of the plane the ray starts on exactly, and the re-projected or
// interpolated point lies within a few steps of the plane whatever the coordinates' size: the bound of quads and
// triangles is kSpawnRoundings steps, absolute. So is a sphere's: its test finds the line's crossings exactly but for
// one quotient (sphere_roots), and the point re-projected onto it lies within a few steps. (When the test assumed a
// unit direction, whose length is 1 only to a step, the distance across the ray carried a step per unit of the
// radius, and the bound grew with it: 0.12 units off seed-default's ground, radius 1000, in Q16.16 at scale 1.)
template <class T>
PT_HD inline Vec3<T> spawn_magnitude(const Vec3<T>& magnitude) {
  if constexpr (ScalarTraits<T>::kExactProducts)
    return Vec3<T>{};
  else
    return magnitude;
}

template <class T>
PT_HD inline void set_spawn_offset(SurfacePoint<T>& at, const Vec3<T>& unit_normal, const Vec3<T>& error) {
  at.geometric_normal = unit_normal;
  at.offset = dot(vabs(unit_normal), error);
}

// The tangent frame of a surface point (SurfacePoint::tangent) from the directions in which u and v grow, dp/du and
// dp/dv (either may be of any length), and the surface's outward unit shading normal: dp/du made perpendicular to
// the normal (Gram-Schmidt) and normalised, and the handedness, on which side of normal x tangent dp/dv lies (as
// MikkTSpace defines it). Both turned on a back face. Left zero where dp/du is zero, along the normal, or not finite.
template <class T>
PT_HD inline void set_tangent_frame(SurfacePoint<T>& at, const Vec3<T>& outward, const Vec3<T>& dpdu, const Vec3<T>& dpdv) {
  const Vec3<T> along = dpdu - dot(dpdu, outward) * outward;
  const T along_length = length(along);  // not its square, which fixed point may not hold
  if (!(along_length > T(0)) || !is_finite(along_length)) return;
  const Vec3<T> tangent = along / along_length;
  const T handedness = dot(cross(outward, tangent), dpdv) < T(0) ? T(-1) : T(1);
  at.tangent = at.front_face ? tangent : -tangent;
  at.handedness = at.front_face ? handedness : -handedness;
}

// A triangle's dp/du and dp/dv from its edges and the uv differences along them: p - p0 = a e1 + b e2 and
// (u, v) - (u0, v0) = a (du1, dv1) + b (du2, dv2), solved for dp/du and dp/dv. Both are returned times det =
// du1 dv2 - du2 dv1 and its sign (|det| times the derivatives): only their directions are used, and no division
// by a det near zero can overflow. False where det is zero (the uvs are collinear or equal: no frame).
template <class T>
PT_HD inline bool triangle_uv_derivatives(const Vec3<T>& edge1, const Vec3<T>& edge2, const T* us, const T* vs, Vec3<T>& dpdu, Vec3<T>& dpdv) {
  const T du1 = us[1] - us[0], du2 = us[2] - us[0];
  const T dv1 = vs[1] - vs[0], dv2 = vs[2] - vs[0];
  const T det = du1 * dv2 - du2 * dv1;
  if (!(det != T(0))) return false;
  const T sign = det < T(0) ? T(-1) : T(1);
  dpdu = sign * (dv2 * edge1 - dv1 * edge2);
  dpdv = sign * (du1 * edge2 - du2 * edge1);
  return true;
}

// Full description of the closest hit. With needs_uv false the texture coordinates of spheres are left at 0
// (the material's textures do not read them); those of triangles and quads cost nothing and are always set. The
// tangent frame is worked out only with needs_tangent (a normal map reads it: material_needs_tangent).
// The material a hit is shaded with: the primitive's, or for a mesh instance without one, the triangle's.
template <class T>
PT_HD inline u32 material_of_hit(const Primitive<T>& primitive, const MeshData<T>& meshes, const Hit<T>& hit) {
  return primitive.material != kMeshMaterials ? primitive.material : meshes.triangles[hit.triangle].material;
}

// A triangle's surface at a hit, from its first vertex and edges: the point, the unit geometric normal, the bound on
// the point's error, and the shading normal and texture coordinates (interpolated where the vertices have them, the
// geometric normal and the barycentrics where not).
template <class T>
struct TriangleSurface {
  Vec3<T> p, geometric, error, shading;
  T u, v;
  Vec3<T> dpdu, dpdv;  // where asked for and known (else zero): the directions of growing u and v, any length
};

template <class T>
PT_HD inline TriangleSurface<T> triangle_surface(const Vec3<T>& p0, const Vec3<T>& edge1, const Vec3<T>& edge2, const Hit<T>& hit,
                                                 const Vec3<T>* normals, const T* us, const T* vs, bool needs_tangent = false,
                                                 const MeshTangent<T>* tangents = nullptr) {
  TriangleSurface<T> s;
  T twice_area;
  if constexpr (ScalarTraits<T>::kExactProducts) {
    // From the exact cross product: edges of 0.01 have one below a step of Q16.16, whose normal was 0 / 0.
    const ExactVec3<T> area_normal = exact_cross(edge1, edge2);
    ScalarTraits<T>::exact_unit(area_normal.x, area_normal.y, area_normal.z, s.geometric.x, s.geometric.y, s.geometric.z, twice_area);
  } else {
    const Vec3<T> area_normal = cross(edge1, edge2);
    twice_area = length(area_normal);
    s.geometric = area_normal / twice_area;
  }
  // From the barycentrics the point lies on the triangle's plane up to the rounding of the interpolation. A new
  // test measures the distance to the plane through cross products of the edges, whose rounding, relative to
  // that distance, grows as 1 / sin of the corner's angle, |e1| |e2| / |e1 x e2|.
  const Vec3<T> along1 = hit.b1 * edge1, along2 = hit.b2 * edge2;
  s.p = p0 + along1 + along2;
  const T roundings = constant<T>(kSpawnRoundings);
  if constexpr (ScalarTraits<T>::kExactProducts) {
    // The new test's plane distance is exact: no term for the edges' cross products.
    s.error = rounding_error(spawn_magnitude(vabs(p0) + vabs(along1) + vabs(along2)), roundings);
  } else {
    const T skew = length(edge1) * length(edge2) / twice_area;
    s.error = rounding_error(vabs(p0) + vabs(along1) + vabs(along2), roundings) + rounding_error(vabs(edge1) + vabs(edge2), roundings * skew);
  }
  const T b0 = T(1) - hit.b1 - hit.b2;
  s.shading = s.geometric;
  s.u = hit.b1;
  s.v = hit.b2;
  if (normals) {
    const Vec3<T> interpolated = b0 * normals[0] + hit.b1 * normals[1] + hit.b2 * normals[2];
    const T len2 = length_squared(interpolated);
    if (len2 > T(0)) s.shading = interpolated / sqrt(len2);
    // Keep the shading normal on the geometric side so the normal still tells front from back.
    if (dot(s.shading, s.geometric) < T(0)) s.shading = -s.shading;
  }
  if (us) {
    s.u = b0 * us[0] + hit.b1 * us[1] + hit.b2 * us[2];
    s.v = b0 * vs[0] + hit.b1 * vs[1] + hit.b2 * vs[2];
  }
  if (needs_tangent) {
    if (tangents) {
      // The file's tangents, interpolated; the bitangent's sign from the vertices' (the same at the three in any
      // file that MikkTSpace or glTF exporters wrote).
      s.dpdu = b0 * tangents[0].direction + hit.b1 * tangents[1].direction + hit.b2 * tangents[2].direction;
      const T sign = b0 * tangents[0].sign + hit.b1 * tangents[1].sign + hit.b2 * tangents[2].sign;
      s.dpdv = (sign < T(0) ? T(-1) : T(1)) * cross(s.shading, s.dpdu);
    } else if (us && !triangle_uv_derivatives(edge1, edge2, us, vs, s.dpdu, s.dpdv)) {
      s.dpdu = s.dpdv = Vec3<T>{};
    }
  }
  return s;
}

template <class T>
PT_HD inline SurfacePoint<T> describe_hit(const Primitive<T>& primitive, const TriangleAttributes<T>* triangle_attributes, const MeshData<T>& meshes,
                                          const Ray<T>& ray, const Hit<T>& hit, bool needs_uv = true, bool needs_tangent = false) {
  struct Describe {
    const TriangleAttributes<T>* attributes;
    const MeshData<T>& meshes;
    const Ray<T>& ray;
    const Hit<T>& hit;
    SurfacePoint<T>& at;
    bool needs_uv, needs_tangent;

    PT_HD void sphere(const Vec3<T>& center, T radius) const {
      // Re-projected onto the sphere, the point's error is that of the centre and the radius, however long the ray.
      // A new test from there rounds the squared radius and distances (floating point): an error of the radius's size
      // (fixed point with exact products: a step, spawn_magnitude). The normal is
      // the same direction divided by the radius (unit to within the hit point's error), so that the shading, which
      // waits for it, does not wait for the square root.
      const Vec3<T> from_center = at.p - center;
      Vec3<T> outward;
      if constexpr (ScalarTraits<T>::kExactProducts) {
        // Each coordinate one quotient of exact products, (p - c) r / |p - c|: radius / |p - c| rounded to the
        // format would carry a step of relative error into a radius of 1000. The normal likewise, (p - c) / |p - c|:
        // (p - c) / r is unit only to the point's error over the radius (1e-4 for a radius of 0.2 in Q16.16), and
        // directions reflected about it as far from unit, which a sphere's test turns into distance errors.
        using S = ScalarTraits<T>;
        const auto distance = S::exact(length(from_center)) * S::exact(T(1));
        auto along = [&](T component, T size) { return S::exact_quotient(S::exact(component) * S::exact(size), distance); };
        outward = Vec3<T>{along(from_center.x, T(1)), along(from_center.y, T(1)), along(from_center.z, T(1))};
        at.p = center + Vec3<T>{along(from_center.x, radius), along(from_center.y, radius), along(from_center.z, radius)};
      } else {
        outward = from_center / radius;
        at.p = center + from_center * (radius / length(from_center));
      }
      set_spawn_offset(at, outward, rounding_error(spawn_magnitude(vabs(center) + Vec3<T>::splat(radius)), constant<T>(kSpawnRoundings)));
      set_face_normal(at, ray, outward);
      if (needs_uv) sphere_uv(outward, at.u, at.v);
      // u grows as atan2(z, x) falls (sphere_uv), v towards +y: dp/du is along (z, 0, -x), and dp/dv along
      // outward x dp/du. No frame at the poles.
      if (needs_tangent) {
        const Vec3<T> dpdu{outward.z, T(0), -outward.x};
        set_tangent_frame(at, outward, dpdu, cross(outward, dpdu));
      }
    }
    PT_HD void operator()(const Sphere<T>& s) const { sphere(s.center, s.radius); }
    PT_HD void operator()(const MovingSphere<T>& s) const { sphere(moving_sphere_center(s, ray.time), s.radius); }
    PT_HD void operator()(const Triangle<T>& tri) const {
      Vec3<T> normals[3];
      T us[3], vs[3];
      const TriangleAttributes<T>* a = tri.attributes >= 0 ? &attributes[tri.attributes] : nullptr;
      if (a && a->has_normals)
        for (int k = 0; k < 3; ++k) normals[k] = a->normal[k];
      if (a && a->has_uvs)
        for (int k = 0; k < 3; ++k) us[k] = a->u[k], vs[k] = a->v[k];
      const TriangleSurface<T> s = triangle_surface(tri.p0, tri.edge1, tri.edge2, hit, a && a->has_normals ? normals : nullptr,
                                                    a && a->has_uvs ? us : nullptr, vs, needs_tangent);
      set_triangle_point(s, s.geometric, s.shading);
    }
    PT_HD void operator()(const MeshInstance<T>& instance) const {
      const MeshRecord& mesh = meshes.meshes[instance.mesh];
      const MeshTriangle& tri = meshes.triangles[hit.triangle];
      const Vec3<T>& p0 = meshes.positions[mesh.first_vertex + tri.vertex[0]];
      Vec3<T> normals[3];
      T us[3], vs[3];
      MeshTangent<T> tangents[3];
      const bool vertex_tangents = needs_tangent && mesh.first_tangent != kNoAttributes;
      for (int k = 0; k < 3; ++k) {
        if (vertex_tangents) tangents[k] = meshes.tangents[mesh.first_tangent + tri.vertex[k]];
        if (mesh.first_normal != kNoAttributes) normals[k] = meshes.normals[mesh.first_normal + tri.vertex[k]];
        if (mesh.first_uv != kNoAttributes) {
          const MeshUv<T>& uv = meshes.uvs[mesh.first_uv + tri.vertex[k]];
          us[k] = uv.u;
          vs[k] = uv.v;
        }
      }
      TriangleSurface<T> s =
          triangle_surface(p0, meshes.positions[mesh.first_vertex + tri.vertex[1]] - p0, meshes.positions[mesh.first_vertex + tri.vertex[2]] - p0,
                           hit, mesh.first_normal != kNoAttributes ? normals : nullptr, mesh.first_uv != kNoAttributes ? us : nullptr, vs,
                           needs_tangent, vertex_tangents ? tangents : nullptr);
      if (instance.transform == kNoTransform) return set_triangle_point(s, s.geometric, s.shading);
      // Brought to the world: the point's error bound grows by the map's absolute rows, plus the rounding of the map
      // itself, counted twice: once here and once where a new ray is taken back into the mesh's space.
      const InstanceTransform<T>& xf = meshes.transforms[instance.transform];
      const Vec3<T> p = xf.to_world.point(s.p);
      s.error = xf.to_world.abs_vector(s.error) +
                rounding_error(xf.to_world.abs_vector(vabs(s.p)) + vabs(xf.to_world.translation), constant<T>(2 * kSpawnRoundings));
      s.p = p;
      const Vec3<T> geometric = normalize(xf.normal(s.geometric));
      Vec3<T> shading = geometric;
      if (mesh.first_normal != kNoAttributes) {
        const Vec3<T> turned = xf.normal(s.shading);
        const T len2 = length_squared(turned);
        if (len2 > T(0)) shading = turned / sqrt(len2);
        if (dot(shading, geometric) < T(0)) shading = -shading;
      }
      // dp/du and dp/dv are vectors along the surface: they go by the map itself.
      s.dpdu = xf.to_world.vector(s.dpdu);
      s.dpdv = xf.to_world.vector(s.dpdv);
      set_triangle_point(s, geometric, shading);
    }
    PT_HD void set_triangle_point(const TriangleSurface<T>& s, const Vec3<T>& geometric, const Vec3<T>& shading) const {
      at.p = s.p;
      set_spawn_offset(at, geometric, s.error);
      at.front_face = dot(ray.direction, geometric) < T(0);
      at.u = s.u;
      at.v = s.v;
      at.normal = at.front_face ? shading : -shading;
      if (needs_tangent) set_tangent_frame(at, shading, s.dpdu, s.dpdv);
    }
    PT_HD void operator()(const Quad<T>& q) const {
      // Re-projected onto the quad's plane, the point's error no longer grows with the ray's length; a new test
      // rounds the distance from the corner.
      at.p = at.p - dot(q.normal, at.p - q.corner) * q.normal;
      set_spawn_offset(at, q.normal, rounding_error(spawn_magnitude(vabs(at.p) + vabs(at.p - q.corner)), constant<T>(kSpawnRoundings)));
      set_face_normal(at, ray, q.normal);
      at.u = hit.b1;
      at.v = hit.b2;
      // u and v grow along the quad's edges: u = |u x v| dv x normal, v = |u x v| normal x du (quad_edges).
      if (needs_tangent) set_tangent_frame(at, q.normal, cross(q.dv, q.normal), cross(q.normal, q.du));
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
  at.material = material_of_hit(primitive, meshes, hit);
  visit(Describe{triangle_attributes, meshes, ray, hit, at, needs_uv, needs_tangent}, primitive.shape);
  return at;
}

}  // namespace pt
