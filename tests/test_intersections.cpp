// Checks ray-shape intersection and hit description (distance, normal, front face, texture coordinates) in float and double.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <type_traits>
#include <utility>
#include <vector>

#include "kernel/fixed_point.hpp"
#include "test_support.hpp"

namespace pt {
namespace {

using test::to;

template <class T>
double tolerance() {
  return std::is_same_v<T, float> ? 2e-5 : 1e-12;
}

template <class T>
Ray<T> make_ray(const Vec3d& origin, const Vec3d& direction, double time = 0) {
  return Ray<T>{to<T>(origin), to<T>(normalize(direction)), static_cast<T>(time)};
}

template <class T>
Quad<T> make_test_quad(const Vec3d& corner, const Vec3d& u, const Vec3d& v) {
  // Made in double and converted, as flatten_scene does (|u x v|^2 may exceed a fixed format).
  return quad_in<T>(make_quad(corner, u, v));
}

template <class T>
void expect_vec_near(const Vec3<T>& actual, const Vec3d& expected, double tol) {
  EXPECT_NEAR(static_cast<double>(actual.x), expected.x, tol);
  EXPECT_NEAR(static_cast<double>(actual.y), expected.y, tol);
  EXPECT_NEAR(static_cast<double>(actual.z), expected.z, tol);
}

// Intersects a purely geometric shape and, on a hit, describes it (no triangle attributes).
template <class T>
bool hit_shape(const Shape<T>& shape, const Ray<T>& ray, double t_min, double t_max, Hit<T>& hit, SurfacePoint<T>& at,
               const TriangleAttributes<T>* attributes = nullptr) {
  if (!intersect_geometry(shape, ray, static_cast<T>(t_min), static_cast<T>(t_max), hit)) return false;
  at = describe_hit(Primitive<T>{shape, 7}, attributes, MeshData<T>{}, ray, hit);
  return true;
}

template <class T>
class SphereIntersection : public ::testing::Test {};
template <class T>
class MovingSphereIntersection : public ::testing::Test {};
template <class T>
class TriangleIntersection : public ::testing::Test {};
template <class T>
class QuadIntersection : public ::testing::Test {};
template <class T>
class MediumIntersection : public ::testing::Test {};

using ScalarTypes = ::testing::Types<float, double>;
TYPED_TEST_SUITE(SphereIntersection, ScalarTypes);
TYPED_TEST_SUITE(MovingSphereIntersection, ScalarTypes);
TYPED_TEST_SUITE(TriangleIntersection, ScalarTypes);
TYPED_TEST_SUITE(QuadIntersection, ScalarTypes);
TYPED_TEST_SUITE(MediumIntersection, ScalarTypes);

// ---- sphere ----

TYPED_TEST(SphereIntersection, HeadOnHitGivesDistanceOutwardNormalAndFrontFace) {
  using T = TypeParam;
  const Shape<T> sphere = Sphere<T>{to<T>({0, 0, -5}), T(1)};
  Hit<T> hit;
  SurfacePoint<T> at;
  ASSERT_TRUE(hit_shape(sphere, make_ray<T>({0, 0, 0}, {0, 0, -1}), 0.001, 1e30, hit, at));
  EXPECT_NEAR(hit.t, 4.0, tolerance<T>());
  expect_vec_near(at.p, {0, 0, -4}, tolerance<T>());
  expect_vec_near(at.normal, {0, 0, 1}, tolerance<T>());
  EXPECT_TRUE(at.front_face);
  EXPECT_EQ(at.material, 7u);
  // Texture coordinates: u = 1 - (atan2(z, x) + pi) / 2pi, v = (asin(y) + pi/2) / pi at the unit normal.
  EXPECT_NEAR(at.u, 0.25, tolerance<T>());
  EXPECT_NEAR(at.v, 0.5, tolerance<T>());
}

TYPED_TEST(SphereIntersection, OffCentreHitHasNormalAlongRadius) {
  using T = TypeParam;
  const Shape<T> sphere = Sphere<T>{to<T>({0, 0, -5}), T(1)};
  Hit<T> hit;
  SurfacePoint<T> at;
  ASSERT_TRUE(hit_shape(sphere, make_ray<T>({0.6, 0, 0}, {0, 0, -1}), 0.001, 1e30, hit, at));
  EXPECT_NEAR(hit.t, 4.2, 10 * tolerance<T>());
  expect_vec_near(at.normal, {0.6, 0, 0.8}, 10 * tolerance<T>());
  EXPECT_TRUE(at.front_face);
  EXPECT_NEAR(length(at.normal), 1.0, tolerance<T>());
}

TYPED_TEST(SphereIntersection, RaysPassingBesideOrPointingAwayMiss) {
  using T = TypeParam;
  const Shape<T> sphere = Sphere<T>{to<T>({0, 0, -5}), T(1)};
  Hit<T> hit;
  SurfacePoint<T> at;
  EXPECT_FALSE(hit_shape(sphere, make_ray<T>({0, 0, 0}, {0, 1, 0}), 0.001, 1e30, hit, at));
  EXPECT_FALSE(hit_shape(sphere, make_ray<T>({1.01, 0, 0}, {0, 0, -1}), 0.001, 1e30, hit, at));
  EXPECT_FALSE(hit_shape(sphere, make_ray<T>({0, 0, 0}, {0, 0, 1}), 0.001, 1e30, hit, at));  // sphere behind the origin
}

TYPED_TEST(SphereIntersection, DistanceLimitsAreRespected) {
  using T = TypeParam;
  const Shape<T> sphere = Sphere<T>{to<T>({0, 0, -5}), T(1)};
  const Ray<T> ray = make_ray<T>({0, 0, 0}, {0, 0, -1});
  Hit<T> hit;
  SurfacePoint<T> at;
  EXPECT_FALSE(hit_shape(sphere, ray, 0.001, 4.0, hit, at));  // t_max is exclusive and before the sphere
  ASSERT_TRUE(hit_shape(sphere, ray, 0.001, 4.01, hit, at));
  EXPECT_NEAR(hit.t, 4.0, tolerance<T>());
  // t_min beyond the near side: the far side is hit from inside.
  ASSERT_TRUE(hit_shape(sphere, ray, 4.5, 1e30, hit, at));
  EXPECT_NEAR(hit.t, 6.0, tolerance<T>());
  EXPECT_FALSE(at.front_face);
  expect_vec_near(at.normal, {0, 0, 1}, tolerance<T>());     // faces against the ray
  EXPECT_FALSE(hit_shape(sphere, ray, 6.0, 1e30, hit, at));  // t_min is exclusive too
  EXPECT_FALSE(hit_shape(sphere, ray, 4.5, 5.5, hit, at));   // both roots outside (t_min, t_max)
}

TYPED_TEST(SphereIntersection, OriginInsideHitsFarSideFromBehind) {
  using T = TypeParam;
  const Vec3d center{1, 2, 3};
  const Shape<T> sphere = Sphere<T>{to<T>(center), T(2)};
  const Vec3d origin = center + Vec3d{0.5, 0, 0};
  const Vec3d direction = Vec3d{1, 2, 2} / 3.0;
  Hit<T> hit;
  SurfacePoint<T> at;
  ASSERT_TRUE(hit_shape(sphere, make_ray<T>(origin, direction), 0.001, 1e30, hit, at));
  // |o + t d - c| = r with o - c = (0.5, 0, 0): t = -b + sqrt(b^2 - (0.25 - 4)), b = 0.5 / 3.
  const double b = 0.5 / 3;
  const double expected_t = -b + std::sqrt(b * b + 3.75);
  EXPECT_NEAR(hit.t, expected_t, 10 * tolerance<T>());
  EXPECT_FALSE(at.front_face);
  const Vec3d outward = (origin + expected_t * direction - center) / 2.0;
  expect_vec_near(at.normal, -outward, 10 * tolerance<T>());
  EXPECT_LT(dot(to<T>(direction), at.normal), T(0));
}

TYPED_TEST(SphereIntersection, TangentRaysGiveAConsistentFiniteAnswer) {
  using T = TypeParam;
  const Shape<T> sphere = Sphere<T>{to<T>({0, 0, -5}), T(1)};
  Hit<T> hit;
  SurfacePoint<T> at;
  // Exactly tangent: a hit (discriminant 0) at the touching point, or no hit; never a non-finite value.
  const Ray<T> tangent = make_ray<T>({1, 0, 0}, {0, 0, -1});
  const bool first = hit_shape(sphere, tangent, 0.001, 1e30, hit, at);
  const T first_t = hit.t;
  EXPECT_EQ(first, hit_shape(sphere, tangent, 0.001, 1e30, hit, at));
  if (first) {
    EXPECT_EQ(first_t, hit.t);
    EXPECT_NEAR(hit.t, 5.0, tolerance<T>());
    EXPECT_TRUE(is_finite(at.normal));
    EXPECT_NEAR(std::abs(static_cast<double>(at.normal.x)), 1.0, tolerance<T>());
  }
  // Sweeping across the silhouette: hits inside, misses outside, distances stay close to the tangent point.
  int hits = 0, misses = 0;
  for (int i = -50; i <= 50; ++i) {
    const double offset = 1.0 + i * 1e-5;
    Hit<T> h;
    SurfacePoint<T> s;
    const bool found = hit_shape(sphere, make_ray<T>({offset, 0, 0}, {0, 0, -1}), 0.001, 1e30, h, s);
    if (i <= -5) {
      EXPECT_TRUE(found) << "offset " << offset;
    }
    if (i >= 5) {
      EXPECT_FALSE(found) << "offset " << offset;
    }
    if (found) {
      ++hits;
      EXPECT_TRUE(is_finite(h.t));
      // The near root: 5 minus half the chord.
      EXPECT_NEAR(h.t, 5.0 - std::sqrt(std::max(0.0, 1.0 - offset * offset)), 1e-4) << "offset " << offset;
      EXPECT_TRUE(is_finite(s.normal));
    } else {
      ++misses;
    }
  }
  EXPECT_GT(hits, 40);
  EXPECT_GT(misses, 40);
}

// ---- moving sphere ----

TYPED_TEST(MovingSphereIntersection, CentreFollowsRayTime) {
  using T = TypeParam;
  // Centre (0, 0, -5) at time 0, moving by (0, 2, 0) per unit time.
  const Shape<T> sphere = MovingSphere<T>{to<T>({0, 0, -5}), T(1), to<T>({0, 2, 0}), T(0)};
  Hit<T> hit;
  SurfacePoint<T> at;
  ASSERT_TRUE(hit_shape(sphere, make_ray<T>({0, 0, 0}, {0, 0, -1}, 0.0), 0.001, 1e30, hit, at));
  EXPECT_NEAR(hit.t, 4.0, tolerance<T>());
  expect_vec_near(at.normal, {0, 0, 1}, tolerance<T>());
  EXPECT_TRUE(at.front_face);
  // At time 1 the centre is at (0, 2, -5): the same ray passes below it.
  EXPECT_FALSE(hit_shape(sphere, make_ray<T>({0, 0, 0}, {0, 0, -1}, 1.0), 0.001, 1e30, hit, at));
  // A ray aimed at the time-1 centre hits at distance sqrt(29) - 1, with the normal pointing back at the origin.
  const Vec3d toward{0, 2, -5};
  ASSERT_TRUE(hit_shape(sphere, make_ray<T>({0, 0, 0}, toward, 1.0), 0.001, 1e30, hit, at));
  EXPECT_NEAR(hit.t, std::sqrt(29.0) - 1, 10 * tolerance<T>());
  expect_vec_near(at.normal, -normalize(toward), 10 * tolerance<T>());
  EXPECT_TRUE(at.front_face);
  // Halfway: centre (0, 1, -5).
  ASSERT_TRUE(hit_shape(sphere, make_ray<T>({0, 1, 0}, {0, 0, -1}, 0.5), 0.001, 1e30, hit, at));
  EXPECT_NEAR(hit.t, 4.0, tolerance<T>());
  expect_vec_near(at.normal, {0, 0, 1}, tolerance<T>());
}

TYPED_TEST(MovingSphereIntersection, TimeIsMeasuredFromTime0) {
  using T = TypeParam;
  // Centre (0, 0, -5) at time 0.5, so (0, -1, -5) at time 0 and (0, 1, -5) at time 1.
  const Shape<T> sphere = MovingSphere<T>{to<T>({0, 0, -5}), T(0.5), to<T>({0, 2, 0}), T(0.5)};
  Hit<T> hit;
  SurfacePoint<T> at;
  ASSERT_TRUE(hit_shape(sphere, make_ray<T>({0, -1, 0}, {0, 0, -1}, 0.0), 0.001, 1e30, hit, at));
  EXPECT_NEAR(hit.t, 4.5, tolerance<T>());
  EXPECT_FALSE(hit_shape(sphere, make_ray<T>({0, 0, 0}, {0, 0, -1}, 0.0), 0.001, 1e30, hit, at));
  ASSERT_TRUE(hit_shape(sphere, make_ray<T>({0, 1, 0}, {0, 0, -1}, 1.0), 0.001, 1e30, hit, at));
  EXPECT_NEAR(hit.t, 4.5, tolerance<T>());
}

// ---- triangle ----

// Vertices (-1, -1, -3), (1, -1, -3), (-1, 1, -3); geometric normal +z. A ray along -z through (x, y) hits at
// t = 3 with barycentrics b1 = (x + 1) / 2, b2 = (y + 1) / 2.
template <class T>
Triangle<T> test_triangle(i32 attributes = -1) {
  return Triangle<T>{to<T>({-1, -1, -3}), to<T>({2, 0, 0}), to<T>({0, 2, 0}), attributes};
}

TYPED_TEST(TriangleIntersection, HitGivesBarycentricUvsAndGeometricNormal) {
  using T = TypeParam;
  const Shape<T> tri = test_triangle<T>();
  Hit<T> hit;
  SurfacePoint<T> at;
  ASSERT_TRUE(hit_shape(tri, make_ray<T>({-0.5, -0.25, 0}, {0, 0, -1}), 0.001, 1e30, hit, at));
  EXPECT_NEAR(hit.t, 3.0, tolerance<T>());
  EXPECT_NEAR(hit.b1, 0.25, tolerance<T>());
  EXPECT_NEAR(hit.b2, 0.375, tolerance<T>());
  EXPECT_NEAR(at.u, 0.25, tolerance<T>());
  EXPECT_NEAR(at.v, 0.375, tolerance<T>());
  expect_vec_near(at.p, {-0.5, -0.25, -3}, tolerance<T>());
  expect_vec_near(at.normal, {0, 0, 1}, tolerance<T>());
  EXPECT_TRUE(at.front_face);
}

TYPED_TEST(TriangleIntersection, BackSideHitHasFrontFaceFalseAndNormalAgainstRay) {
  using T = TypeParam;
  const Shape<T> tri = test_triangle<T>();
  Hit<T> hit;
  SurfacePoint<T> at;
  ASSERT_TRUE(hit_shape(tri, make_ray<T>({-0.5, -0.25, -6}, {0, 0, 1}), 0.001, 1e30, hit, at));
  EXPECT_NEAR(hit.t, 3.0, tolerance<T>());
  EXPECT_FALSE(at.front_face);
  expect_vec_near(at.normal, {0, 0, -1}, tolerance<T>());
}

TYPED_TEST(TriangleIntersection, RaysOutsideTheEdgesMiss) {
  using T = TypeParam;
  const Shape<T> tri = test_triangle<T>();
  Hit<T> hit;
  SurfacePoint<T> at;
  EXPECT_FALSE(hit_shape(tri, make_ray<T>({0.1, 0.1, 0}, {0, 0, -1}), 0.001, 1e30, hit, at));   // beyond the hypotenuse
  EXPECT_FALSE(hit_shape(tri, make_ray<T>({-1.001, 0, 0}, {0, 0, -1}), 0.001, 1e30, hit, at));  // left of the left edge
  EXPECT_FALSE(hit_shape(tri, make_ray<T>({0, -1.001, 0}, {0, 0, -1}), 0.001, 1e30, hit, at));  // below the bottom edge
  EXPECT_FALSE(hit_shape(tri, make_ray<T>({-0.5, -0.5, 0}, {0, 0, 1}), 0.001, 1e30, hit, at));  // triangle behind the origin
}

TYPED_TEST(TriangleIntersection, RaysThroughEdgesAndVerticesHit) {
  using T = TypeParam;
  const Shape<T> tri = test_triangle<T>();
  Hit<T> hit;
  SurfacePoint<T> at;
  ASSERT_TRUE(hit_shape(tri, make_ray<T>({0, -1, 0}, {0, 0, -1}), 0.001, 1e30, hit, at));  // bottom edge: b2 = 0
  EXPECT_EQ(hit.b2, T(0));
  EXPECT_NEAR(hit.b1, 0.5, tolerance<T>());
  ASSERT_TRUE(hit_shape(tri, make_ray<T>({-1, -1, 0}, {0, 0, -1}), 0.001, 1e30, hit, at));  // vertex p0
  EXPECT_EQ(hit.b1, T(0));
  EXPECT_EQ(hit.b2, T(0));
}

TYPED_TEST(TriangleIntersection, RayInThePlaneMissesAndGrazingRayHitsAccurately) {
  using T = TypeParam;
  const Shape<T> tri = test_triangle<T>();
  Hit<T> hit;
  SurfacePoint<T> at;
  // Travelling inside the triangle's plane, across it and along its bottom edge: zero determinant, no hit.
  EXPECT_FALSE(hit_shape(tri, make_ray<T>({-2, -0.5, -3}, {1, 0, 0}), 0.001, 1e30, hit, at));
  EXPECT_FALSE(hit_shape(tri, make_ray<T>({-2, -1, -3}, {1, 0, 0}), 0.001, 1e30, hit, at));
  // Almost in the plane: crosses it at (0, -0.5, -3) after a distance of about 2.
  const Vec3d origin{-2, -0.5, -3 + 1e-3}, direction{2, 0, -1e-3};
  ASSERT_TRUE(hit_shape(tri, make_ray<T>(origin, direction), 0.001, 1e30, hit, at));
  EXPECT_NEAR(hit.t, length(direction), 1e-3);
  EXPECT_NEAR(hit.b1, 0.5, 1e-3);
  EXPECT_NEAR(hit.b2, 0.25, 1e-3);
  EXPECT_TRUE(at.front_face);  // it comes from the +z side
}

TYPED_TEST(TriangleIntersection, DistanceLimitsAreRespected) {
  using T = TypeParam;
  const Shape<T> tri = test_triangle<T>();
  const Ray<T> ray = make_ray<T>({-0.5, -0.5, 0}, {0, 0, -1});
  Hit<T> hit;
  SurfacePoint<T> at;
  EXPECT_FALSE(hit_shape(tri, ray, 0.001, 3.0, hit, at));
  EXPECT_TRUE(hit_shape(tri, ray, 0.001, 3.01, hit, at));
  EXPECT_FALSE(hit_shape(tri, ray, 3.0, 1e30, hit, at));
  EXPECT_TRUE(hit_shape(tri, ray, 2.99, 1e30, hit, at));
}

TYPED_TEST(TriangleIntersection, PerVertexUvsAndNormalsAreInterpolated) {
  using T = TypeParam;
  const Vec3d n0{0, 0, 1}, n1 = normalize(Vec3d{1, 0, 1}), n2 = normalize(Vec3d{0, 1, 1});
  TriangleAttributes<T> attributes{};
  attributes.normal[0] = to<T>(n0);
  attributes.normal[1] = to<T>(n1);
  attributes.normal[2] = to<T>(n2);
  const double us[3] = {0.1, 0.9, 0.5}, vs[3] = {0.2, 0.3, 0.95};
  for (int i = 0; i < 3; ++i) {
    attributes.u[i] = static_cast<T>(us[i]);
    attributes.v[i] = static_cast<T>(vs[i]);
  }
  attributes.has_normals = 1;
  attributes.has_uvs = 1;
  const Shape<T> tri = test_triangle<T>(0);
  Hit<T> hit;
  SurfacePoint<T> at;
  ASSERT_TRUE(hit_shape(tri, make_ray<T>({-0.5, -0.25, 0}, {0, 0, -1}), 0.001, 1e30, hit, at, &attributes));
  const double b1 = 0.25, b2 = 0.375, b0 = 1 - b1 - b2;
  EXPECT_NEAR(at.u, b0 * us[0] + b1 * us[1] + b2 * us[2], tolerance<T>());
  EXPECT_NEAR(at.v, b0 * vs[0] + b1 * vs[1] + b2 * vs[2], tolerance<T>());
  expect_vec_near(at.normal, normalize(b0 * n0 + b1 * n1 + b2 * n2), tolerance<T>());
  EXPECT_TRUE(at.front_face);

  // From behind: the same shading normal, turned to face the ray.
  ASSERT_TRUE(hit_shape(tri, make_ray<T>({-0.5, -0.25, -6}, {0, 0, 1}), 0.001, 1e30, hit, at, &attributes));
  EXPECT_FALSE(at.front_face);
  expect_vec_near(at.normal, -normalize(b0 * n0 + b1 * n1 + b2 * n2), tolerance<T>());

  // Only uvs: the geometric normal. Only normals: barycentric uvs.
  attributes.has_normals = 0;
  ASSERT_TRUE(hit_shape(tri, make_ray<T>({-0.5, -0.25, 0}, {0, 0, -1}), 0.001, 1e30, hit, at, &attributes));
  expect_vec_near(at.normal, {0, 0, 1}, tolerance<T>());
  EXPECT_NEAR(at.u, b0 * us[0] + b1 * us[1] + b2 * us[2], tolerance<T>());
  attributes.has_normals = 1;
  attributes.has_uvs = 0;
  ASSERT_TRUE(hit_shape(tri, make_ray<T>({-0.5, -0.25, 0}, {0, 0, -1}), 0.001, 1e30, hit, at, &attributes));
  EXPECT_NEAR(at.u, b1, tolerance<T>());
  EXPECT_NEAR(at.v, b2, tolerance<T>());
}

TYPED_TEST(TriangleIntersection, ShadingNormalStaysOnTheGeometricSide) {
  using T = TypeParam;
  // Vertex normals all pointing to -z, against the geometric normal +z: the shading normal is turned over, so the
  // normal still tells front from back.
  TriangleAttributes<T> attributes{};
  for (int i = 0; i < 3; ++i) attributes.normal[i] = to<T>(normalize(Vec3d{0.1 * i, 0, -1}));
  attributes.has_normals = 1;
  const Shape<T> tri = test_triangle<T>(0);
  Hit<T> hit;
  SurfacePoint<T> at;
  const Ray<T> front = make_ray<T>({-0.5, -0.25, 0}, {0, 0, -1});
  ASSERT_TRUE(hit_shape(tri, front, 0.001, 1e30, hit, at, &attributes));
  EXPECT_TRUE(at.front_face);
  EXPECT_GT(at.normal.z, T(0));
  EXPECT_LT(dot(front.direction, at.normal), T(0));
  const Ray<T> back = make_ray<T>({-0.5, -0.25, -6}, {0, 0, 1});
  ASSERT_TRUE(hit_shape(tri, back, 0.001, 1e30, hit, at, &attributes));
  EXPECT_FALSE(at.front_face);
  EXPECT_LT(dot(back.direction, at.normal), T(0));
}

// ---- quad ----

TYPED_TEST(QuadIntersection, HitGivesQuadCoordinatesAndNormal) {
  using T = TypeParam;
  const Shape<T> quad = make_test_quad<T>({-1, -1, -3}, {2, 0, 0}, {0, 2, 0});
  Hit<T> hit;
  SurfacePoint<T> at;
  ASSERT_TRUE(hit_shape(quad, make_ray<T>({0.5, -0.5, 0}, {0, 0, -1}), 0.001, 1e30, hit, at));
  EXPECT_NEAR(hit.t, 3.0, tolerance<T>());
  EXPECT_NEAR(at.u, 0.75, tolerance<T>());
  EXPECT_NEAR(at.v, 0.25, tolerance<T>());
  expect_vec_near(at.normal, {0, 0, 1}, tolerance<T>());
  EXPECT_TRUE(at.front_face);
  // Back side.
  ASSERT_TRUE(hit_shape(quad, make_ray<T>({0.5, -0.5, -5}, {0, 0, 1}), 0.001, 1e30, hit, at));
  EXPECT_NEAR(hit.t, 2.0, tolerance<T>());
  EXPECT_FALSE(at.front_face);
  expect_vec_near(at.normal, {0, 0, -1}, tolerance<T>());
  // Corners are inside.
  ASSERT_TRUE(hit_shape(quad, make_ray<T>({1, 1, 0}, {0, 0, -1}), 0.001, 1e30, hit, at));
  EXPECT_NEAR(at.u, 1.0, tolerance<T>());
  EXPECT_NEAR(at.v, 1.0, tolerance<T>());
}

TYPED_TEST(QuadIntersection, SkewedQuadCoordinatesSolveCornerPlusAUPlusBV) {
  using T = TypeParam;
  const Vec3d corner{0.5, -1, 2}, u{2, 1, 0}, v{0.5, 0.5, 3};
  const Shape<T> quad = make_test_quad<T>(corner, u, v);
  const Vec3d target = corner + 0.3 * u + 0.8 * v;
  const Vec3d origin{4, 5, -1};
  Hit<T> hit;
  SurfacePoint<T> at;
  ASSERT_TRUE(hit_shape(quad, make_ray<T>(origin, target - origin), 0.001, 1e30, hit, at));
  EXPECT_NEAR(hit.t, length(target - origin), 1e3 * tolerance<T>());
  EXPECT_NEAR(at.u, 0.3, 1e3 * tolerance<T>());
  EXPECT_NEAR(at.v, 0.8, 1e3 * tolerance<T>());
  EXPECT_LT(dot(to<T>(normalize(target - origin)), at.normal), T(0));
}

TYPED_TEST(QuadIntersection, OutsideParallelAndOutOfRangeRaysMiss) {
  using T = TypeParam;
  const Shape<T> quad = make_test_quad<T>({-1, -1, -3}, {2, 0, 0}, {0, 2, 0});
  Hit<T> hit;
  SurfacePoint<T> at;
  EXPECT_FALSE(hit_shape(quad, make_ray<T>({1.001, 0, 0}, {0, 0, -1}), 0.001, 1e30, hit, at));
  EXPECT_FALSE(hit_shape(quad, make_ray<T>({0, -1.001, 0}, {0, 0, -1}), 0.001, 1e30, hit, at));
  EXPECT_FALSE(hit_shape(quad, make_ray<T>({-2, 0, -3}, {1, 0, 0}), 0.001, 1e30, hit, at));  // in the plane
  EXPECT_FALSE(hit_shape(quad, make_ray<T>({0, 0, 0}, {0, 0, -1}), 0.001, 3.0, hit, at));
  EXPECT_FALSE(hit_shape(quad, make_ray<T>({0, 0, 0}, {0, 0, -1}), 3.0, 1e30, hit, at));
  EXPECT_TRUE(hit_shape(quad, make_ray<T>({0, 0, 0}, {0, 0, -1}), 2.99, 3.01, hit, at));
}

// A Cornell-box wall (555 units square) seen from 800 units away in Q32.32: the quad stores its unit normal and
// dual edges (sizes 1 and 1/555), not (u x v) / |u x v|^2 (about 3e-6, of which Q32.32 keeps only 14 bits), so the
// hit distance and quad coordinates keep nearly the format's full precision.
TEST(QuadIntersectionInFixedPoint, LargeQuadHitIsPreciseInQ32_32) {
  using T = Fixed<32, 32>;
  const Vec3d corner{0, 0, 555}, u{555, 0, 0}, v{0, 555, 0};
  const Shape<T> quad = make_test_quad<T>(corner, u, v);
  test::TestRandom rng(2024);
  for (int i = 0; i < 200; ++i) {
    const double a = rng.uniform(), b = rng.uniform();
    const Vec3d target = corner + a * u + b * v;
    const Vec3d origin{278 + 200 * (rng.uniform() - 0.5), 273 + 200 * (rng.uniform() - 0.5), -800};
    Hit<T> hit;
    SurfacePoint<T> at;
    ASSERT_TRUE(hit_shape(quad, make_ray<T>(origin, target - origin), 0.001, 1e9, hit, at));
    // The direction is rounded to 2^-32, so the distance can be off by about t * 2^-32 per component.
    EXPECT_NEAR(static_cast<double>(hit.t), length(target - origin), 1e-6);
    // du = 1/555 keeps 2^-33 / (1/555), about 6e-8 relative, which bounds the coordinates' error.
    EXPECT_NEAR(static_cast<double>(at.u), a, 1e-7);
    EXPECT_NEAR(static_cast<double>(at.v), b, 1e-7);
  }
}

// ---- Fixed point of up to 32 bits: exact products (ScalarTraits::kExactProducts) ----
// Each test compares Q16.16 with double on the same, rounded, inputs (the shape and the ray as Q16.16 holds them),
// so what remains is the error of the test's own arithmetic: one rounding per result. The formulations these
// replace squared lengths and distances (the scene had to be scaled down to keep the squares in range) and stored
// a quad's dual edges as 1 / length; each case below failed with them.

using Q16 = Fixed<16, 16>;

Vec3d as_double(const Vec3<Q16>& v) { return {static_cast<double>(v.x), static_cast<double>(v.y), static_cast<double>(v.z)}; }
Ray<double> as_double(const Ray<Q16>& r) { return {as_double(r.origin), as_double(r.direction), static_cast<double>(r.time)}; }

// The crossings of the line through the rounded origin along the rounded direction (not unit: 1 to a step or so),
// in long double: a t^2 + 2 b t + c with the discriminant a r^2 - |oc x d|^2.
std::pair<long double, long double> line_crossings(const Vec3<Q16>& center, Q16 radius, const Ray<Q16>& ray) {
  auto ld = [](Q16 x) { return static_cast<long double>(static_cast<double>(x)); };
  const long double ox = ld(ray.origin.x - center.x), oy = ld(ray.origin.y - center.y), oz = ld(ray.origin.z - center.z);
  const long double dx = ld(ray.direction.x), dy = ld(ray.direction.y), dz = ld(ray.direction.z), r = ld(radius);
  const long double a = dx * dx + dy * dy + dz * dz, b = ox * dx + oy * dy + oz * dz;
  const long double cx = oy * dz - oz * dy, cy = oz * dx - ox * dz, cz = ox * dy - oy * dx;
  const long double root = std::sqrt(a * r * r - (cx * cx + cy * cy + cz * cz));
  return {(-b - root) / a, (-b + root) / a};
}

// seed-default's ground (radius 1000, centre 1000 below the origin) seen from its camera, at scale 1: r^2 = 1e6 is
// beyond Q16.16 (32768), which made every ray miss (or forced a scale of 1/32). The discriminant is now exact and
// rounded once, by its root.
TEST(SphereIntersectionInFixedPoint, LargeSphereIsHitPreciselyWithoutScalingInQ16_16) {
  const Vec3d center{0, -1000, 0};
  const double radius = 1000;
  test::TestRandom rng(19);
  const u64 saturations_before = fixed_saturations_this_thread();
  for (int i = 0; i < 500; ++i) {
    const Vec3d target{8 * (rng.uniform() - 0.5), 0, 8 * (rng.uniform() - 0.5)};
    const Ray<Q16> ray = make_ray<Q16>({13, 3, 3}, target - Vec3d{13, 3, 3});
    Hit<Q16> hit;
    ASSERT_TRUE(intersect_sphere(to<Q16>(center), Q16(radius), ray, Q16(0), largest<Q16>(), hit));
    Hit<double> reference;
    ASSERT_TRUE(intersect_sphere(center, radius, as_double(ray), 0.0, 1e30, reference));
    // The rounded ray's line (its direction unit only to a step or so) meets the ground here; the test's crossing
    // is one quotient of exact values (the next test bounds it by a step).
    EXPECT_NEAR(static_cast<double>(hit.t), static_cast<double>(line_crossings(to<Q16>(center), Q16(radius), ray).first), 1e-3);
  }
  EXPECT_EQ(fixed_saturations_this_thread(), saturations_before);
}

// The same ground, near and far: the crossings are those of the rounded ray's line to within a step (one quotient,
// truncated, and the discriminant's root rounded once), whatever the radius. When the test assumed a unit direction
// they were off by up to a few 1e-4 here (a step of the direction's length per unit of the radius).
TEST(SphereIntersectionInFixedPoint, CrossingsOfALargeSphereAreThoseOfTheRoundedLineInQ16_16) {
  const Vec3<Q16> center = to<Q16>(Vec3d{0, -1000, 0});
  const Q16 radius(1000);
  test::TestRandom rng(31);
  double largest_error = 0;
  for (int i = 0; i < 500; ++i) {
    const Vec3d target{8 * (rng.uniform() - 0.5), 0, 8 * (rng.uniform() - 0.5)};
    const Ray<Q16> ray = make_ray<Q16>({13, 3, 3}, target - Vec3d{13, 3, 3});
    Q16 near, far;
    ASSERT_TRUE(sphere_roots(center, radius, ray, near, far));
    const auto [expected_near, expected_far] = line_crossings(center, radius, ray);
    largest_error = std::max({largest_error, std::abs(static_cast<double>(near) - static_cast<double>(expected_near)),
                              std::abs(static_cast<double>(far) - static_cast<double>(expected_far))});
  }
  EXPECT_LT(largest_error, 2.0 / 65536);
}

// A Cornell wall (555 units square) from 800 units away in Q16.16 at scale 1: du = 1/555 keeps 7 significant bits
// in Q16.16 (the edges moved by up to 4 units); stored times its extent (512), it keeps 16, and the coordinates are
// exact sums of products rounded once.
TEST(QuadIntersectionInFixedPoint, CornellWallCoordinatesArePreciseInQ16_16) {
  const Vec3d corner{0, 0, 555}, u{555, 0, 0}, v{0, 555, 0};
  const Quad<Q16> quad = make_test_quad<Q16>(corner, u, v);
  const Quad<double> reference_quad = make_quad(corner, u, v);
  test::TestRandom rng(2024);
  const u64 saturations_before = fixed_saturations_this_thread();
  int edges = 0;
  for (int i = 0; i < 500; ++i) {
    // Half of the targets within 1 % of an edge, where an error in the coordinates turns hits into misses.
    double a = rng.uniform(), b = rng.uniform();
    if (i % 2) a = a < 0.5 ? 0.01 * a : 1 - 0.01 * (1 - a), ++edges;
    const Vec3d origin{278 + 200 * (rng.uniform() - 0.5), 273 + 200 * (rng.uniform() - 0.5), -800};
    const Ray<Q16> ray = make_ray<Q16>(origin, corner + a * u + b * v - origin);
    Hit<double> reference{};
    const bool expected = intersect_quad(reference_quad, as_double(ray), 0.0, 1e30, reference);
    Hit<Q16> hit{};
    const bool found = intersect_quad(quad, ray, Q16(0), largest<Q16>(), hit);
    // Where the rounded ray meets the plane, in double (rounding the direction moves it by up to 1e-5 units per
    // unit of distance); within a step of an edge either answer is right.
    const Ray<double> r = as_double(ray);
    const double t = dot(reference_quad.normal, reference_quad.corner - r.origin) / dot(reference_quad.normal, r.direction);
    const Vec3d planar = r.at(t) - reference_quad.corner;
    const double ra = dot(reference_quad.du, planar), rb = dot(reference_quad.dv, planar);
    if (std::min({std::abs(ra), std::abs(1 - ra), std::abs(rb), std::abs(1 - rb)}) > 1e-4) {
      ASSERT_EQ(found, expected) << "a " << ra << " b " << rb;
    }
    if (!found || !expected) continue;
    // t (about 1400) is one quotient, truncated; the coordinates carry planar's rounding (a step per component,
    // over 555) and du's (2^-17 relative).
    EXPECT_NEAR(static_cast<double>(hit.t), reference.t, 1e-3);
    EXPECT_NEAR(static_cast<double>(hit.b1), reference.b1, 1e-4);
    EXPECT_NEAR(static_cast<double>(hit.b2), reference.b2, 1e-4);
  }
  EXPECT_GT(edges, 200);
  EXPECT_EQ(fixed_saturations_this_thread(), saturations_before);
}

// Triangles of very different sizes in Q16.16 at scale 1: one of edge 0.02 seen from 4 units (det = 4e-4, 26 steps
// if rounded: the barycentrics were off by a few per cent), and one of edge 555 seen from 1400 (det = 3e5, beyond
// Q16.16: it saturated). With exact products the barycentrics and t are each one quotient.
TEST(TriangleIntersectionInFixedPoint, SmallAndLargeTrianglesAreHitPreciselyInQ16_16) {
  struct Case {
    Vec3d p0, e1, e2, origin;
  };
  const Case cases[] = {{{0.1, 0.2, -4}, {0.02, 0, 0}, {0.004, 0.018, 0.003}, {0, 0, 0}},
                        {{0, 0, 555}, {555, 0, 0}, {100, 555, -50}, {278, 273, -800}}};
  test::TestRandom rng(7);
  const u64 saturations_before = fixed_saturations_this_thread();
  for (const Case& c : cases) {
    const Triangle<Q16> tri{to<Q16>(c.p0), to<Q16>(c.e1), to<Q16>(c.e2), -1};
    const Triangle<double> reference_tri{as_double(tri.p0), as_double(tri.edge1), as_double(tri.edge2), -1};
    for (int i = 0; i < 500; ++i) {
      double b1 = rng.uniform(), b2 = rng.uniform();
      if (b1 + b2 > 1) b1 = 1 - b1, b2 = 1 - b2;
      const Ray<Q16> ray = make_ray<Q16>(c.origin, c.p0 + b1 * c.e1 + b2 * c.e2 - c.origin);
      Hit<double> reference{};
      const bool expected = intersect_triangle(reference_tri, as_double(ray), 0.0, 1e30, reference);
      Hit<Q16> hit{};
      const bool found = intersect_triangle(tri, ray, Q16(0), largest<Q16>(), hit);
      // The rounded ray's barycentrics in double (Moller-Trumbore without the inside test); within a step of an
      // edge either answer is right.
      const Ray<double> r = as_double(ray);
      const Vec3d pvec = cross(r.direction, reference_tri.edge2), tvec = r.origin - reference_tri.p0;
      const double det = dot(reference_tri.edge1, pvec);
      const double rb1 = dot(tvec, pvec) / det, rb2 = dot(r.direction, cross(tvec, reference_tri.edge1)) / det;
      if (std::min({std::abs(rb1), std::abs(rb2), std::abs(1 - rb1 - rb2)}) > 1e-4) {
        ASSERT_EQ(found, expected) << "b1 " << rb1 << " b2 " << rb2;
      }
      if (!found || !expected) continue;
      EXPECT_NEAR(static_cast<double>(hit.t), reference.t, 1e-4);
      EXPECT_NEAR(static_cast<double>(hit.b1), reference.b1, 1e-4);
      EXPECT_NEAR(static_cast<double>(hit.b2), reference.b2, 1e-4);
    }
  }
  EXPECT_EQ(fixed_saturations_this_thread(), saturations_before);
}

// The hit on seed-default's ground described in Q16.16 at scale 1: re-projecting the point onto the sphere divides
// by |p - centre|, about 1000, whose square overflowed; the length is now a root of exact squares.
TEST(SphereIntersectionInFixedPoint, HitOnALargeSphereIsDescribedPreciselyInQ16_16) {
  const Vec3d center{0, -1000, 0};
  const Shape<Q16> ground = Sphere<Q16>{to<Q16>(center), Q16(1000)};
  test::TestRandom rng(23);
  const u64 saturations_before = fixed_saturations_this_thread();
  for (int i = 0; i < 200; ++i) {
    const Vec3d target{8 * (rng.uniform() - 0.5), 0, 8 * (rng.uniform() - 0.5)};
    Hit<Q16> hit;
    SurfacePoint<Q16> at;
    ASSERT_TRUE(hit_shape(ground, make_ray<Q16>({13, 3, 3}, target - Vec3d{13, 3, 3}), 0, 1e4, hit, at));
    // On the sphere to within a few steps (each coordinate is one quotient; radius / |p - c| rounded to the format
    // put it 0.015 off), and the normal unit to within a few steps.
    EXPECT_NEAR(length(as_double(at.p) - center), 1000, 1e-3);
    EXPECT_NEAR(length(as_double(at.normal)), 1, 1e-4);
    // A ray leaving it starts a few steps off (kSpawnRoundings steps): a new test of the ground is exact but for a
    // step (0.12 units when the test assumed a unit direction, more than the small spheres resting on the ground).
    EXPECT_LT(static_cast<double>(at.offset), 16.0 / 65536);
  }
  EXPECT_EQ(fixed_saturations_this_thread(), saturations_before);
}

// A triangle of edges 0.004 in Q16.16 (after scaling, the tiny scene's knot has such): their cross product, 1.6e-5,
// is about a step, whose square rounds to 0, and the normal was 0 / 0. From the exact cross product it is unit and
// points the right way.
TEST(TriangleIntersectionInFixedPoint, SmallTriangleHasAUnitNormalInQ16_16) {
  const Vec3d p0{0.5, 0.25, -2}, e1{0.004, 0.0005, 0}, e2{0.001, 0.004, 0.0005};
  const Triangle<Q16> tri{to<Q16>(p0), to<Q16>(e1), to<Q16>(e2), -1};
  const Vec3d expected = normalize(cross(as_double(tri.edge1), as_double(tri.edge2)));
  const u64 saturations_before = fixed_saturations_this_thread();
  Hit<Q16> hit{};
  hit.b1 = Q16(0.25);
  hit.b2 = Q16(0.25);
  const TriangleSurface<Q16> surface = triangle_surface<Q16>(tri.p0, tri.edge1, tri.edge2, hit, nullptr, nullptr, nullptr);
  expect_vec_near(surface.geometric, expected, 1e-4);
  EXPECT_EQ(fixed_saturations_this_thread(), saturations_before);
}

// ---- constant medium ----

template <class T>
struct MediumFixture {
  std::vector<Primitive<T>> boundaries;
  Primitive<T> medium;
};

// A medium of the given density inside the unit sphere centred at (0, 0, -5).
template <class T>
MediumFixture<T> sphere_medium(double density) {
  MediumFixture<T> f;
  f.boundaries.push_back(Primitive<T>{Sphere<T>{to<T>({0, 0, -5}), T(1)}, 0});
  f.medium = Primitive<T>{ConstantMedium<T>{0, 1, static_cast<T>(-1.0 / density)}, 0};
  return f;
}

template <class T>
bool hit_medium(const MediumFixture<T>& f, u32 stream, const Ray<T>& ray, double t_min, double t_max, Hit<T>& hit, u32 index = 0) {
  const SampleRandom random = SampleRandom::make(99, stream, 0);
  const IntersectContext<T> context{f.boundaries.data(), &random, 0};
  return intersect_primitive(f.medium, index, context, ray, static_cast<T>(t_min), static_cast<T>(t_max), hit);
}

TYPED_TEST(MediumIntersection, GeometricQueryNeverHitsAMedium) {
  using T = TypeParam;
  const MediumFixture<T> f = sphere_medium<T>(1e6);
  Hit<T> hit;
  EXPECT_FALSE(intersect_geometry(f.medium.shape, make_ray<T>({0, 0, 0}, {0, 0, -1}), T(0.001), T(1e30), hit));
  EXPECT_TRUE(hit_medium(f, 0, make_ray<T>({0, 0, 0}, {0, 0, -1}), 0.001, 1e30, hit));
}

TYPED_TEST(MediumIntersection, DenseMediumScattersRightAtTheBoundary) {
  using T = TypeParam;
  const MediumFixture<T> f = sphere_medium<T>(1e6);
  for (u32 stream = 0; stream < 100; ++stream) {
    Hit<T> hit;
    ASSERT_TRUE(hit_medium(f, stream, make_ray<T>({0, 0, 0}, {0, 0, -1}), 0.001, 1e30, hit));
    EXPECT_GE(hit.t, T(4) - T(1e-5));
    EXPECT_LT(hit.t, T(4.001));
  }
  // Missing the boundary, or a boundary entirely outside (t_min, t_max): no scattering.
  Hit<T> hit;
  EXPECT_FALSE(hit_medium(f, 0, make_ray<T>({0, 0, 0}, {0, 1, 0}), 0.001, 1e30, hit));
  EXPECT_FALSE(hit_medium(f, 0, make_ray<T>({0, 0, 0}, {0, 0, -1}), 0.001, 3.5, hit));
  EXPECT_FALSE(hit_medium(f, 0, make_ray<T>({0, 0, 0}, {0, 0, -1}), 6.5, 1e30, hit));
  EXPECT_FALSE(hit_medium(f, 0, make_ray<T>({0, 0, 0}, {0, 0, 1}), 0.001, 1e30, hit));
}

TYPED_TEST(MediumIntersection, OriginInsideScattersJustAheadOfTheOrigin) {
  using T = TypeParam;
  const MediumFixture<T> f = sphere_medium<T>(1e6);
  Hit<T> hit;
  ASSERT_TRUE(hit_medium(f, 3, make_ray<T>({0, 0.2, -5}, {0, 0, -1}), 0.001, 1e30, hit));
  EXPECT_GE(hit.t, T(0.001));
  EXPECT_LT(hit.t, T(0.0011));
  const SurfacePoint<T> at =
      describe_hit(f.medium, static_cast<const TriangleAttributes<T>*>(nullptr), MeshData<T>{}, make_ray<T>({0, 0.2, -5}, {0, 0, -1}), hit);
  EXPECT_TRUE(at.front_face);
  EXPECT_NEAR(length(at.normal), 1.0, tolerance<T>());
  expect_vec_near(at.p, {0, 0.2, -5 - static_cast<double>(hit.t)}, tolerance<T>());
}

TYPED_TEST(MediumIntersection, ScatteringProbabilityFollowsBeerLambert) {
  using T = TypeParam;
  // Density 0.5 over a chord of length 2: scatters with probability 1 - e^-1; given that, the distance into the
  // medium has the truncated exponential mean 1/0.5 - 2 / (e - 1).
  const MediumFixture<T> f = sphere_medium<T>(0.5);
  const int n = 20000;
  int hits = 0;
  double distance_sum = 0;
  for (int i = 0; i < n; ++i) {
    Hit<T> hit;
    if (!hit_medium(f, static_cast<u32>(i), make_ray<T>({0, 0, 0}, {0, 0, -1}), 0.001, 1e30, hit)) continue;
    ++hits;
    ASSERT_GE(hit.t, T(4) - T(1e-5));
    ASSERT_LE(hit.t, T(6) + T(1e-5));
    distance_sum += static_cast<double>(hit.t) - 4.0;
  }
  const double p = 1 - std::exp(-1.0);
  const double fraction = static_cast<double>(hits) / n;
  EXPECT_NEAR(fraction, p, 5 * std::sqrt(p * (1 - p) / n));
  const double expected_mean = 2.0 - 2.0 / (std::exp(1.0) - 1.0);
  EXPECT_NEAR(distance_sum / hits, expected_mean, 5 * 0.6 / std::sqrt(static_cast<double>(hits)));
}

TYPED_TEST(MediumIntersection, BoxBoundaryMediumScattersAtTheBox) {
  using T = TypeParam;
  MediumFixture<T> f;
  // The six faces of the box [-1, 1]^2 x [-6, -4].
  const Vec3d a{-1, -1, -6}, b{1, 1, -4};
  const Vec3d dx{2, 0, 0}, dy{0, 2, 0}, dz{0, 0, 2};
  f.boundaries = {Primitive<T>{make_test_quad<T>({a.x, a.y, b.z}, dx, dy), 0},  Primitive<T>{make_test_quad<T>({b.x, a.y, b.z}, -dz, dy), 0},
                  Primitive<T>{make_test_quad<T>({b.x, a.y, a.z}, -dx, dy), 0}, Primitive<T>{make_test_quad<T>(a, dz, dy), 0},
                  Primitive<T>{make_test_quad<T>({a.x, b.y, b.z}, dx, -dz), 0}, Primitive<T>{make_test_quad<T>(a, dz, dx), 0}};
  f.medium = Primitive<T>{ConstantMedium<T>{0, 6, static_cast<T>(-1e-6)}, 0};
  Hit<T> hit;
  ASSERT_TRUE(hit_medium(f, 1, make_ray<T>({0.3, 0.2, 0}, {0, 0, -1}), 0.001, 1e30, hit));
  EXPECT_NEAR(hit.t, 4.0, 1e-4);
  ASSERT_TRUE(hit_medium(f, 1, make_ray<T>({5, 0.2, -5}, {-1, 0, 0}), 0.001, 1e30, hit));
  EXPECT_NEAR(hit.t, 4.0, 1e-4);
  EXPECT_FALSE(hit_medium(f, 1, make_ray<T>({1.5, 0.2, 0}, {0, 0, -1}), 0.001, 1e30, hit));
}

TYPED_TEST(MediumIntersection, FreeFlightDrawDependsOnThePrimitiveIndex) {
  using T = TypeParam;
  const MediumFixture<T> f = sphere_medium<T>(0.5);
  const Ray<T> ray = make_ray<T>({0, 0, 0}, {0, 0, -1});
  int differ = 0, both = 0;
  for (u32 stream = 0; stream < 200; ++stream) {
    Hit<T> a, b, again;
    const bool hit_a = hit_medium(f, stream, ray, 0.001, 1e30, a, 0);
    const bool hit_b = hit_medium(f, stream, ray, 0.001, 1e30, b, 1);
    // The same index and stream give the same draw.
    ASSERT_EQ(hit_a, hit_medium(f, stream, ray, 0.001, 1e30, again, 0));
    if (hit_a) {
      ASSERT_EQ(a.t, again.t);
    }
    if (hit_a && hit_b) {
      ++both;
      if (a.t != b.t) ++differ;
    }
  }
  ASSERT_GT(both, 50);
  EXPECT_EQ(differ, both);
}

}  // namespace
}  // namespace pt
