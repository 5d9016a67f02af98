// Robust ray spawning: a ray leaving a surface never meets that surface again, whatever the direction (grazing
// included), the number format, and where and at what size the shape is placed.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "kernel/fixed_point.hpp"
#include "test_support.hpp"

namespace pt {
namespace {

using test::TestRandom;

// Where a shape of unit size is placed: every length multiplied by `scale`, then moved by `offset`.
struct Placement {
  std::string name;
  double scale;
  Vec3d offset;
  Vec3d place(const Vec3d& p) const { return p * scale + offset; }
};

std::vector<Placement> placements_for(bool narrow) {
  // A fixed format holds a limited range: narrow formats are tested near the origin at moderate sizes.
  if (narrow) return {{"unit", 1, {0.3, -0.2, 0.1}}, {"scaled 8", 8, {0, 0, 0}}, {"moved 100", 1, {100, -60, 40}}};
  return {{"unit", 1, {0.3, -0.2, 0.1}},
          {"moved 1e4", 1, {1e4, -7e3, 3e3}},
          {"scaled 1e3", 1e3, {0, 0, 0}},
          {"scaled 1e-3", 1e-3, {0, 0, 0}},
          {"moved 1e4 and scaled 1e3", 1e3, {1e4, 2e4, -1e4}}};
}

// The unit-size shapes, each with the exact outward normal at a point of it, in double.
struct ShapeCase {
  std::string name;
  Shape<double> shape;
};

Shape<double> placed(const Shape<double>& shape, const Placement& where) {
  if (const auto* s = std::get_if<Sphere<double>>(&shape)) return Sphere<double>{where.place(s->center), s->radius * where.scale};
  if (const auto* s = std::get_if<MovingSphere<double>>(&shape))
    return MovingSphere<double>{where.place(s->center0), s->radius * where.scale, s->velocity * where.scale, s->time0};
  if (const auto* t = std::get_if<Triangle<double>>(&shape))
    return Triangle<double>{where.place(t->p0), t->edge1 * where.scale, t->edge2 * where.scale, -1};
  const Quad<double>& q = std::get<Quad<double>>(shape);
  Vec3d u, v;
  quad_edges(q, u, v);
  return make_quad(where.place(q.corner), u * where.scale, v * where.scale);
}

template <class T>
Shape<T> converted(const Shape<double>& shape) {
  if (const auto* s = std::get_if<Sphere<double>>(&shape)) return Sphere<T>{test::to<T>(s->center), static_cast<T>(s->radius)};
  if (const auto* s = std::get_if<MovingSphere<double>>(&shape))
    return MovingSphere<T>{test::to<T>(s->center0), static_cast<T>(s->radius), test::to<T>(s->velocity), static_cast<T>(s->time0)};
  if (const auto* t = std::get_if<Triangle<double>>(&shape)) return Triangle<T>{test::to<T>(t->p0), test::to<T>(t->edge1), test::to<T>(t->edge2), -1};
  const Quad<double>& q = std::get<Quad<double>>(shape);
  return quad_in<T>(q);
}

template <class T>
Vec3d as_double(const Vec3<T>& v) {
  return {static_cast<double>(v.x), static_cast<double>(v.y), static_cast<double>(v.z)};
}

// The shape as the scalar type holds it, back in double: the surface the kernels test is that one, not the shape
// before rounding (in float at 1e4 from the origin the two differ by 1e-3).
template <class T>
Shape<double> as_double(const Shape<T>& shape) {
  if (const auto* s = std::get_if<Sphere<T>>(&shape)) return Sphere<double>{as_double(s->center), static_cast<double>(s->radius)};
  if (const auto* s = std::get_if<MovingSphere<T>>(&shape))
    return MovingSphere<double>{as_double(s->center0), static_cast<double>(s->radius), as_double(s->velocity), static_cast<double>(s->time0)};
  if (const auto* t = std::get_if<Triangle<T>>(&shape)) return Triangle<double>{as_double(t->p0), as_double(t->edge1), as_double(t->edge2), -1};
  const Quad<T>& q = std::get<Quad<T>>(shape);
  // Back to extents of 1: the dual edges themselves.
  const double eu = static_cast<double>(q.u_extent), ev = static_cast<double>(q.v_extent);
  return Quad<double>{as_double(q.corner), as_double(q.normal), as_double(q.du) / eu, as_double(q.dv) / ev, 1, 1};
}

std::vector<ShapeCase> unit_shapes() {
  // Tilted so that no face lies along an axis (the hardest case: every coordinate of a hit point is rounded).
  const RigidTransform tilt = RigidTransform::from_euler_degrees({23, -37, 11}, {0, 0, 0});
  return {{"sphere", Sphere<double>{{0.1, 0.2, -0.3}, 0.7}},
          {"moving sphere", MovingSphere<double>{{0.1, 0.2, -0.3}, 0.7, {0.3, -0.2, 0.1}, 0}},
          {"triangle", Triangle<double>{tilt.apply_point({-0.6, -0.4, 0.2}), tilt.apply_vector({1.3, 0.1, 0}), tilt.apply_vector({0.2, 0.9, 0}), -1}},
          {"sliver triangle",
           Triangle<double>{tilt.apply_point({-0.6, -0.4, 0.2}), tilt.apply_vector({1.5, 0.02, 0}), tilt.apply_vector({1.4, 0.05, 0}), -1}},
          {"quad", make_quad(tilt.apply_point({-0.5, -0.5, 0}), tilt.apply_vector({1.2, 0, 0}), tilt.apply_vector({0.3, 0.9, 0}))}};
}

// A random point of the shape (double) and the outward normal there.
void random_surface_point(const Shape<double>& shape, double time, TestRandom& rng, Vec3d& point, Vec3d& normal) {
  if (const auto* s = std::get_if<Sphere<double>>(&shape)) {
    normal = rng.unit_vector();
    point = s->center + s->radius * normal;
  } else if (const auto* s = std::get_if<MovingSphere<double>>(&shape)) {
    normal = rng.unit_vector();
    point = moving_sphere_center(*s, time) + s->radius * normal;
  } else if (const auto* t = std::get_if<Triangle<double>>(&shape)) {
    double a = rng.uniform(0.02, 0.98), b = rng.uniform(0.02, 0.98);
    if (a + b > 0.98) {
      a = 0.98 - a;
      b = 0.98 - b;
    }
    point = t->p0 + a * t->edge1 + b * t->edge2;
    normal = normalize(cross(t->edge1, t->edge2));
  } else {
    const Quad<double>& q = std::get<Quad<double>>(shape);
    Vec3d u, v;
    quad_edges(q, u, v);
    point = q.corner + rng.uniform(0.02, 0.98) * u + rng.uniform(0.02, 0.98) * v;
    normal = q.normal;
  }
}

// Shoots rays at random points of the shape from both sides, and from every hit sends a ray to a random side at
// angles down to 1e-7 from the surface; counts how often that ray meets the surface it left. A sphere left inwards
// is met again on its far side, and that is a correct hit as long as it lies beyond the chord's first half.
template <class T>
void expect_no_self_intersection(bool narrow) {
  TestRandom rng(20261201);
  for (const ShapeCase& unit : unit_shapes()) {
    for (const Placement& where : placements_for(narrow)) {
      const Shape<T> shape = converted<T>(placed(unit.shape, where));
      const Shape<double> exact = as_double(shape);
      int spawned = 0, met_again = 0;
      std::string first_failure;
      for (int trial = 0; trial < 4000; ++trial) {
        const double time = rng.uniform();
        Vec3d point, normal;
        random_surface_point(exact, time, rng, point, normal);
        // Arrive from either side; inside a sphere, from close by.
        const bool sphere = std::holds_alternative<Sphere<double>>(exact) || std::holds_alternative<MovingSphere<double>>(exact);
        const bool from_inside = rng.uniform() < 0.5;
        Vec3d incoming = normalize(rng.unit_vector() - 1.5 * normal);  // towards the surface from the outside
        if (from_inside) incoming = -incoming;
        const double back = (sphere && from_inside ? 0.05 : 3.0) * where.scale;
        const Ray<T> ray{test::to<T>(point - back * incoming), test::to<T>(incoming), static_cast<T>(time)};
        Hit<T> hit{};
        if (!intersect_geometry(shape, ray, T(0), largest<T>(), hit)) continue;
        const SurfacePoint<T> at = describe_hit(Primitive<T>{shape, 0}, static_cast<const TriangleAttributes<T>*>(nullptr), MeshData<T>{}, ray, hit);
        // Directions are drawn about the normal the kernel computed, as a material draws them: which side a ray
        // within the normal's own rounding of the tangent plane goes to is the kernel's call, not the test's.
        normal = normalize(as_double(at.geometric_normal));
        const double radius = std::holds_alternative<Sphere<double>>(exact) ? std::get<Sphere<double>>(exact).radius
                              : sphere                                      ? std::get<MovingSphere<double>>(exact).radius
                                                                            : 0.0;
        // A direction nearly in the tangent plane, on a random side: angle from the surface log-uniform in [1e-7, 1].
        Vec3d tangent = cross(normal, rng.unit_vector());
        if (length(tangent) < 1e-3) continue;
        tangent = normalize(tangent);
        const double elevation = std::pow(10.0, rng.uniform(-7, 0));
        const double side = rng.uniform() < 0.5 ? 1.0 : -1.0;
        const Vec3d leaving = normalize(tangent + side * elevation * normal);
        const Ray<T> next = spawn_ray(at, test::to<T>(leaving), static_cast<T>(time));
        ++spawned;
        Hit<T> again{};
        if (!intersect_geometry(shape, next, T(0), largest<T>(), again)) continue;
        // Into a sphere, the ray starts at least `offset` inside it and meets it again only where it leaves it, at
        // least sqrt(2 r offset) away even when it goes along the surface. A hit nearer than half that is the
        // surface it left. Which way the ray goes is that of its direction as the type holds it: within the
        // direction's rounding of the tangent plane (2^-17 in Q16.16, more than the smallest elevations drawn) a
        // ray drawn outwards may be sent inwards, and then meets the far side.
        const bool went_in = dot(as_double(next.direction), as_double(at.geometric_normal)) < 0;
        if (sphere && went_in && static_cast<double>(again.t) > 0.5 * std::sqrt(2 * radius * static_cast<double>(at.offset))) continue;
        if (met_again++ == 0)
          first_failure = "t = " + std::to_string(static_cast<double>(again.t)) + " at elevation " + std::to_string(elevation) +
                          (side > 0 ? " outwards" : " inwards");
      }
      EXPECT_GT(spawned, 1000) << unit.name << ", " << where.name;
      EXPECT_EQ(met_again, 0) << unit.name << ", " << where.name << ": " << met_again << " of " << spawned
                              << " spawned rays met the surface they left; first: " << first_failure;
    }
  }
}

template <class T>
class RaySpawning : public ::testing::Test {};
using FloatingTypes = ::testing::Types<float, double>;
TYPED_TEST_SUITE(RaySpawning, FloatingTypes);

TYPED_TEST(RaySpawning, RaysLeavingASurfaceNeverMeetItAgainAtAnyScaleOrPosition) { expect_no_self_intersection<TypeParam>(false); }

TEST(RaySpawningInFixedPoint, RaysLeavingASurfaceNeverMeetItAgainInQ32_32) { expect_no_self_intersection<Fixed<32, 32>>(true); }

// Q16.16 keeps products exact in its intersection tests, and its offset is a few steps whatever the coordinates.
TEST(RaySpawningInFixedPoint, RaysLeavingASurfaceNeverMeetItAgainInQ16_16) { expect_no_self_intersection<Fixed<16, 16>>(true); }

// The offset is the least that clears the rounding error: it shrinks with the scene and stays a tiny fraction of it.
TEST(RaySpawning, OffsetIsRelativeToTheSceneSize) {
  for (double scale : {1e-3, 1.0, 1e3}) {
    const Shape<float> sphere = Sphere<float>{test::to<float>(Vec3d{0, 0, 0} * scale), static_cast<float>(scale)};
    const Ray<float> ray{test::to<float>(Vec3d{0.2, 0.1, 5} * scale), test::to<float>(normalize(Vec3d{-0.04, -0.02, -1})), 0};
    Hit<float> hit{};
    ASSERT_TRUE(intersect_geometry(sphere, ray, 0.0f, largest<float>(), hit));
    const SurfacePoint<float> at =
        describe_hit(Primitive<float>{sphere, 0}, static_cast<const TriangleAttributes<float>*>(nullptr), MeshData<float>{}, ray, hit);
    const double offset = at.offset;
    EXPECT_GT(offset, 1e-7 * scale);
    EXPECT_LT(offset, 1e-5 * scale);
  }
}

}  // namespace
}  // namespace pt
