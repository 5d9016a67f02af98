// Checks that BVH traversal finds exactly the brute-force closest hit, and the BVH's structural invariants.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <type_traits>
#include <vector>

#include "backends/registry.hpp"
#include "film/film.hpp"
#include "flat/bvh_builder.hpp"
#include "flat/compressed_bvh_builder.hpp"
#include "kernel/fixed_point.hpp"
#include "loading/scene_loader.hpp"
#include "scene/mesh.hpp"
#include "test_support.hpp"

namespace pt {
namespace {

using test::TestRandom;

SceneDescription empty_scene() {
  SceneDescription scene = test::generated_scene({0, 0, 30});
  scene.camera.shutter_open = 0;
  scene.camera.shutter_close = 1;
  scene.textures.push_back(SolidTexture<double>{{0.5, 0.5, 0.5}});
  scene.materials.push_back(Lambertian<double>{0});  // material 0: surfaces
  scene.materials.push_back(Isotropic<double>{0});   // material 1: media
  return scene;
}

SceneObject object(const ObjectShape& shape, u32 material = 0, const RigidTransform& transform = {}) {
  SceneObject o;
  o.shape = shape;
  o.material = material;
  o.transform = transform;
  return o;
}

// A few thousand primitives of every kind in [-10, 10]^3, with sizes over two orders of magnitude, some
// primitives sharing one centroid, a huge ground sphere, rotated boxes and two media.
SceneDescription random_scene(u64 seed) {
  TestRandom rng(seed);
  SceneDescription scene = empty_scene();
  auto size = [&] { return 0.02 * std::pow(50.0, rng.uniform()); };  // 0.02 to 1, log-uniform
  for (int i = 0; i < 1200; ++i) scene.objects.push_back(object(Sphere<double>{rng.vec3(-10, 10), size()}));
  for (int i = 0; i < 300; ++i) {
    const Vec3d c0 = rng.vec3(-10, 10);
    const double time0 = i % 2 ? 0.0 : 0.25, time1 = i % 2 ? 1.0 : 0.75;  // some move beyond their time range
    scene.objects.push_back(object(MovingSphereSettings{c0, c0 + rng.vec3(-1.5, 1.5), size(), time0, time1}));
  }
  for (int i = 0; i < 900; ++i) {
    const Vec3d p = rng.vec3(-10, 10);
    const double s = size() * 2;
    TriangleSettings t;
    t.vertices = {p, p + s * rng.unit_vector(), p + s * rng.unit_vector()};
    if (i % 3 == 0) t.normals = std::array<Vec3d, 3>{rng.unit_vector(), rng.unit_vector(), rng.unit_vector()};
    if (i % 4 == 0) t.uvs = std::array<std::array<double, 2>, 3>{{{0, 0}, {1, 0}, {0, 1}}};
    scene.objects.push_back(object(t));
  }
  for (int i = 0; i < 600; ++i) {
    const double s = size() * 2;
    scene.objects.push_back(object(QuadSettings{rng.vec3(-10, 10), s * rng.unit_vector(), s * rng.unit_vector()}));
  }
  for (int i = 0; i < 40; ++i) {
    const Vec3d lo = rng.vec3(-10, 10);
    const Vec3d degrees = rng.vec3(-180, 180);  // drawn in a fixed order (function arguments have none)
    const RigidTransform xf = RigidTransform::from_euler_degrees(degrees, rng.vec3(-1, 1));
    scene.objects.push_back(object(BoxSettings{lo, lo + Vec3d{size(), size(), size()} * 2.0}, 0, xf));
  }
  // Concentric spheres: one centroid shared by more primitives than a leaf holds.
  for (int i = 0; i < 12; ++i) scene.objects.push_back(object(Sphere<double>{{1.5, -2.5, 3.5}, 0.1 + 0.05 * i}));
  // One primitive much larger than the rest, and one long sliver.
  scene.objects.push_back(object(Sphere<double>{{0, -1012, 0}, 1000}));
  TriangleSettings sliver;
  sliver.vertices = {Vec3d{-10, -3, 2}, Vec3d{10, 4, -2}, Vec3d{10, 4.01, -2}};
  scene.objects.push_back(object(sliver));
  // Two media: a sphere and a rotated box; thin enough that rays often pass through them.
  scene.objects.push_back(object(MediumSettings{Sphere<double>{{2, 1, -3}, 2.5}, RigidTransform{}, 0.3}, 1));
  scene.objects.push_back(
      object(MediumSettings{BoxSettings{{-3, -3, -3}, {3, 2, 1}}, RigidTransform::from_euler_degrees({10, 25, -5}, {0, 0, 0}), 0.2}, 1,
             RigidTransform::from_euler_degrees({0, 0, 0}, {-4, 3, 4})));
  // Meshes: one file placed three times (instances sharing one mesh, scaled, rotated, one mirrored), one placed once
  // (stored in world space).
  const u32 shared = add_mesh_file(scene, test::triangle_soup(rng, 400), "/objects");
  const u32 single = add_mesh_file(scene, test::triangle_soup(rng, 300), "/objects");
  test::place_mesh(scene, shared, {1, 1, 1}, {0, 0, 0}, {5, 5, 5});
  test::place_mesh(scene, shared, {2, 0.5, 1.5}, {30, -20, 75}, {-6, 2, -4});
  test::place_mesh(scene, shared, {-1.5, 1.5, 1.5}, {0, 90, 10}, {4, -6, 1});
  test::place_mesh(scene, single, {1.2, 0.8, 1}, {-40, 15, 5}, {-3, -5, 6});
  return scene;
}

// Random rays of several kinds: from inside the scene in any direction, from far away towards the scene, along the
// axes, and with one zero direction component (the BVH's reciprocal must cope).
template <class T>
std::vector<Ray<T>> random_rays(u64 seed, int count) {
  TestRandom rng(seed);
  std::vector<Ray<T>> rays;
  for (int i = 0; i < count; ++i) {
    Vec3d origin = rng.vec3(-12, 12), direction = rng.unit_vector();
    switch (i % 10) {
      case 0:
      case 1: {
        origin = 30.0 * rng.unit_vector();
        direction = normalize(rng.vec3(-10, 10) - origin);
        break;
      }
      case 2: {
        Vec3d axis{0, 0, 0};
        const int k = static_cast<int>(rng.below(3));
        (k == 0 ? axis.x : k == 1 ? axis.y : axis.z) = rng.uniform() < 0.5 ? -1 : 1;
        direction = axis;
        break;
      }
      case 3: {
        const int k = static_cast<int>(rng.below(3));
        (k == 0 ? direction.x : k == 1 ? direction.y : direction.z) = 0;
        direction = normalize(direction);
        break;
      }
      default: break;
    }
    rays.push_back(Ray<T>{test::to<T>(origin), test::to<T>(direction), static_cast<T>(rng.uniform())});
  }
  return rays;
}

template <class T>
struct Comparison {
  int rays = 0, hits = 0, mismatches = 0;
  std::vector<int> hits_by_shape = std::vector<int>(std::variant_size_v<Shape<T>>, 0);
  int world_space_mesh_hits = 0, instanced_mesh_hits = 0;  // meshes placed once, and more often (with a transform)
  std::string first_mismatch;
};

template <class T>
Comparison<T> compare_with_brute_force(const FlatScene<T>& flat, const std::vector<Ray<T>>& rays) {
  Comparison<T> result;
  const SceneView<T> view = flat.view();
  // The same view with the compressed trees, which the host then walks for the scene and for meshes alike.
  SceneView<T> compressed_view = view;
  std::vector<CompressedWideNode> compressed, mesh_compressed;
  if constexpr (std::is_same_v<T, float>) {
    compressed = compress_wide_bvh(flat.wide_nodes);
    mesh_compressed = compress_wide_bvh(flat.mesh_wide_nodes);
    compressed_view.compressed_nodes = compressed.data();
    compressed_view.meshes.compressed_nodes = mesh_compressed.data();
  }
  for (std::size_t i = 0; i < rays.size(); ++i) {
    const SampleRandom random = SampleRandom::make(7, static_cast<u32>(i), 0);
    const IntersectContext<T> context{view.boundaries, &random, 0};
    Hit<T> brute_hit{};
    const bool brute_found = closest_hit_brute_force(flat, rays[i], context, brute_hit);
    ++result.rays;
    // Every layout: the binary tree (walked on GPUs in double), the wide one (walked on CPUs) and, in float, the
    // compressed wide one (walked by CUDA).
    bool same = true;
    const char* layouts[] = {"binary", "wide", "compressed"};
    const int layout_count = std::is_same_v<T, float> ? 3 : 2;
    for (int layout = 0; layout < layout_count; ++layout) {
      Hit<T> bvh_hit{};
      bool bvh_found = false;
      if (layout == 0) bvh_found = closest_hit_binary(view, rays[i], context, bvh_hit);
      if (layout == 1) bvh_found = closest_hit_wide(view, rays[i], context, bvh_hit);
      if constexpr (std::is_same_v<T, float>)
        if (layout == 2) bvh_found = closest_hit_compressed(compressed_view, rays[i], context, bvh_hit);
      if (bvh_found == brute_found &&
          (!bvh_found || (bvh_hit.primitive == brute_hit.primitive && bvh_hit.t == brute_hit.t && bvh_hit.b1 == brute_hit.b1 &&
                          bvh_hit.b2 == brute_hit.b2 && bvh_hit.triangle == brute_hit.triangle)))
        continue;
      same = false;
      if (result.mismatches++ == 0)
        result.first_mismatch =
            "ray " + std::to_string(i) + ": " + layouts[layout] + " bvh " +
            (bvh_found ? std::to_string(bvh_hit.primitive) + " t=" + std::to_string(static_cast<double>(bvh_hit.t)) : "miss") + ", brute force " +
            (brute_found ? std::to_string(brute_hit.primitive) + " t=" + std::to_string(static_cast<double>(brute_hit.t)) : "miss");
    }
    if (!same) continue;
    if (brute_found) {
      ++result.hits;
      ++result.hits_by_shape[flat.primitives[brute_hit.primitive].shape.index()];
      if (const auto* instance = std::get_if<MeshInstance<T>>(&flat.primitives[brute_hit.primitive].shape))
        ++(instance->transform == kNoTransform ? result.world_space_mesh_hits : result.instanced_mesh_hits);
    }
  }
  return result;
}

template <class T>
class BvhMatchesBruteForce : public ::testing::Test {};
template <class T>
class BvhStructure : public ::testing::Test {};
using ScalarTypes = ::testing::Types<float, double>;
TYPED_TEST_SUITE(BvhMatchesBruteForce, ScalarTypes);
TYPED_TEST_SUITE(BvhStructure, ScalarTypes);

TYPED_TEST(BvhMatchesBruteForce, RandomSpheresTrianglesQuadsMovingSpheresAndMedia) {
  using T = TypeParam;
  const SceneDescription scene = random_scene(12345);
  RenderSettings settings;
  settings.width = 64;
  settings.height = 48;
  const FlatScene<T> flat = flatten_scene<T>(scene, settings);
  ASSERT_GT(flat.primitives.size(), 3000u);
  const Comparison<T> result = compare_with_brute_force(flat, random_rays<T>(777, 20000));
  EXPECT_EQ(result.mismatches, 0) << result.first_mismatch;
  // The comparison means something only if rays hit every kind of primitive.
  EXPECT_GT(result.hits, result.rays / 4);
  for (std::size_t kind = 0; kind < result.hits_by_shape.size(); ++kind) EXPECT_GT(result.hits_by_shape[kind], 20) << "shape kind " << kind;
  EXPECT_GT(result.world_space_mesh_hits, 20);
  EXPECT_GT(result.instanced_mesh_hits, 20);
  EXPECT_EQ(flat.instance_transforms.size(), 3u);
  EXPECT_EQ(flat.meshes.size(), 2u);
}

// A mesh whose coordinates are beyond float's range (a double scene may hold them up to 2^504) keeps double boxes
// for its BVH (float ones would be infinite).
TEST(BvhMatchesBruteForceInDouble, MeshBeyondFloatRange) {
  const double big = 0x1p140;  // float reaches 2^128
  TestRandom rng(99);
  SceneDescription scene = test::generated_scene({0, 2, 12});
  const u32 file = add_mesh_file(scene, test::triangle_soup(rng, 600), "/objects");
  test::place_mesh(scene, file, {big, big, big}, {10, 20, 30}, {0, 0, 0});
  const FlatScene<double> flat = test::flatten<double>(scene);
  ASSERT_EQ(flat.meshes.size(), 1u);
  ASSERT_GT(flat.mesh_nodes.size(), 100u);
  for (const BvhNode<double>& n : flat.mesh_nodes)
    ASSERT_TRUE(std::isfinite(n.lo.x) && std::isfinite(n.lo.y) && std::isfinite(n.lo.z) && std::isfinite(n.hi.x) && std::isfinite(n.hi.y) &&
                std::isfinite(n.hi.z));
  std::vector<Ray<double>> rays = random_rays<double>(31, 20000);
  for (Ray<double>& ray : rays) ray.origin = ray.origin * big;
  const Comparison<double> result = compare_with_brute_force(flat, rays);
  EXPECT_EQ(result.mismatches, 0) << result.first_mismatch;
  EXPECT_GT(result.world_space_mesh_hits, 200);
}

TYPED_TEST(BvhMatchesBruteForce, RaysStartingOnSurfaces) {
  using T = TypeParam;
  // Secondary rays start on a surface: shoot from hit points of the first rays (not moved off the surface, the
  // hardest case: any hit beyond zero counts, as in a render).
  const SceneDescription scene = random_scene(999);
  RenderSettings settings;
  settings.width = 16;
  settings.height = 16;
  const FlatScene<T> flat = flatten_scene<T>(scene, settings);
  const SceneView<T> view = flat.view();
  std::vector<Ray<T>> secondary;
  TestRandom rng(4242);
  for (const Ray<T>& ray : random_rays<T>(31, 6000)) {
    const SampleRandom random = SampleRandom::make(3, 0, 0);
    const IntersectContext<T> context{view.boundaries, &random, 0};
    Hit<T> hit;
    if (!closest_hit(view, ray, context, hit)) continue;
    secondary.push_back(Ray<T>{ray.at(hit.t), test::to<T>(rng.unit_vector()), ray.time});
  }
  ASSERT_GT(secondary.size(), 1000u);
  const Comparison<T> result = compare_with_brute_force(flat, secondary);
  EXPECT_EQ(result.mismatches, 0) << result.first_mismatch;
  EXPECT_GT(result.hits, result.rays / 4);
}

#if !defined(__CUDA_ARCH__) && (defined(__GNUC__) || defined(__clang__))
// The float box test in vector registers gives exactly the scalar loop's entry distances and mask, whether the
// children go in groups of four (SSE) or eight (AVX), so the host's instruction set never changes an image.
TEST(WideBoxTest, VectorGroupsOfFourAndEightMatchTheScalarLoop) {
  const FlatScene<float> flat = flatten_scene<float>(random_scene(2024), RenderSettings{});
  ASSERT_GT(flat.wide_nodes.size(), 100u);
  const std::vector<Ray<float>> rays = random_rays<float>(55, 2000);
  TestRandom rng(8);
  int entered_children = 0;
  for (std::size_t r = 0; r < rays.size(); ++r) {
    const Vec3<float> inv = slab_reciprocals(rays[r]);
    const Vec3<float> origin_term = slab_origin_terms(rays[r], inv);
    const PlaneRows rows{inv.x < 0 ? 3u : 0u, inv.y < 0 ? 4u : 1u, inv.z < 0 ? 5u : 2u,
                         inv.x < 0 ? 0u : 3u, inv.y < 0 ? 1u : 4u, inv.z < 0 ? 2u : 5u};
    const float closest = r % 2 ? largest<float>() : static_cast<float>(rng.uniform() * 30);
    for (std::size_t n = r % 7; n < flat.wide_nodes.size(); n += 7) {
      const WideBvhNode<float>& node = flat.wide_nodes[n];
      float scalar_entry[kWideBvhWidth], four_entry[kWideBvhWidth], eight_entry[kWideBvhWidth];
      const u32 scalar = wide_box_test<float>(node, rows, inv, origin_term, 0.001f, closest, scalar_entry);
      const u32 four = wide_box_test_in_groups<4>(node, rows, inv, origin_term, 0.001f, closest, four_entry);
      const u32 eight = wide_box_test_in_groups<8>(node, rows, inv, origin_term, 0.001f, closest, eight_entry);
      ASSERT_EQ(four, scalar) << "node " << n << ", ray " << r;
      ASSERT_EQ(eight, scalar) << "node " << n << ", ray " << r;
      for (u32 i = 0; i < kWideBvhWidth; ++i) {
        ASSERT_EQ(four_entry[i], scalar_entry[i]) << "node " << n << ", ray " << r << ", child " << i;
        ASSERT_EQ(eight_entry[i], scalar_entry[i]) << "node " << n << ", ray " << r << ", child " << i;
      }
      entered_children += __builtin_popcount(scalar & node.inner_mask) + __builtin_popcount(scalar & node.leaf_mask);
    }
  }
  EXPECT_GT(entered_children, 1000);  // the masks compared were not all empty
}
#endif

// Fixed point has no infinity: near-axis directions make 1 / d, and the slab distances, exceed the format. The slab
// test must then clamp them to "beyond the scene" (not subtract two saturated products to zero), so that axis-parallel
// rays still find exactly what brute force finds. Fewer rays than above: 128-bit divisions make brute force slow.
TEST(BvhMatchesBruteForceInFixedPoint, Q32_32WithAxisParallelRays) {
  using T = Fixed<32, 32>;
  RenderSettings settings;
  settings.width = 64;
  settings.height = 48;
  const FlatScene<T> flat = flatten_scene<T>(random_scene(12345), settings);
  const Comparison<T> result = compare_with_brute_force(flat, random_rays<T>(777, 800));
  EXPECT_EQ(result.mismatches, 0) << result.first_mismatch;
  EXPECT_GT(result.hits, result.rays / 4);
}

// In Q24.8 an axis-parallel ray's reciprocal direction is far out of range; traversal must still find the sphere
// straight ahead and count no saturation (clamped slab distances are an answer, not an overflow).
TEST(BvhMatchesBruteForceInFixedPoint, AxisParallelRayInQ24_8FindsTheSphereWithoutSaturating) {
  using T = Fixed<24, 8>;
  SceneDescription scene = empty_scene();
  for (int i = 0; i < 8; ++i) scene.objects.push_back(object(Sphere<double>{{2.0 * i - 7, 0.5 * i, -6}, 0.75}));
  const FlatScene<T> flat = flatten_scene<T>(scene, RenderSettings{});
  ASSERT_EQ(flat.scale, 1.0);
  const SceneView<T> view = flat.view();
  const SampleRandom random = SampleRandom::make(1, 0, 0);
  const IntersectContext<T> context{view.boundaries, &random, 0};
  const std::uint64_t before = fixed_saturations_this_thread();
  for (int i = 0; i < 8; ++i) {
    Hit<T> hit;
    const Ray<T> ray{test::to<T>({2.0 * i - 7, 0.5 * i, 0}), test::to<T>({0, 0, -1}), T(0)};
    ASSERT_TRUE(closest_hit(view, ray, context, hit)) << "sphere " << i;
    EXPECT_NEAR(static_cast<double>(hit.t), 5.25, 0.01);
    const Ray<T> sideways{test::to<T>({-10, 0.5 * i, -6}), test::to<T>({1, 0, 0}), T(0)};
    ASSERT_TRUE(closest_hit(view, sideways, context, hit)) << "row " << i;
  }
  EXPECT_EQ(fixed_saturations_this_thread(), before);
}

// Spheres at x = 8^k: every binned split can only peel off the outermost few, so the tree reaches the depth limit and
// ends in a large leaf. Coordinates up to 8^99 need double.
SceneDescription depth_limited_scene() {
  SceneDescription scene = empty_scene();
  for (int k = 0; k < 100; ++k) {
    const double x = std::pow(8.0, k);
    scene.objects.push_back(object(Sphere<double>{{x, 0, 0}, 0.1 * x}));
  }
  return scene;
}

TEST(BvhMatchesBruteForceAtDepthLimit, GeometricallySpacedSpheresInDouble) {
  const FlatScene<double> flat = flatten_scene<double>(depth_limited_scene(), RenderSettings{});
  ASSERT_EQ(flat.bvh_depth, kBvhMaxDepth);
  std::vector<Ray<double>> rays;
  TestRandom rng(5);
  for (int i = 0; i < 4000; ++i) {
    const double x = std::pow(8.0, static_cast<double>(rng.below(100)));
    const Vec3d target{x * rng.uniform(0.9, 1.1), x * rng.uniform(-0.1, 0.1), 0};
    const Vec3d origin = Vec3d{x, 0, 0} + x * Vec3d{rng.uniform(-1, 1), rng.uniform(-1, 1), 3};
    rays.push_back(Ray<double>{origin, normalize(target - origin), 0.0});
  }
  const Comparison<double> result = compare_with_brute_force(flat, rays);
  EXPECT_EQ(result.mismatches, 0) << result.first_mismatch;
  EXPECT_GT(result.hits, 1000);
}

// Bounds of one flat primitive, in double, as the kernels see it during the shutter interval [0, 1].
template <class T>
Aabb primitive_bounds(const FlatScene<T>& flat, const Primitive<T>& p) {
  Aabb box;
  auto point = [&](const Vec3<T>& v) { box.grow(Vec3d{static_cast<double>(v.x), static_cast<double>(v.y), static_cast<double>(v.z)}); };
  auto sphere = [&](const Vec3<T>& c, T r) {
    point(c - Vec3<T>::splat(r));
    point(c + Vec3<T>::splat(r));
  };
  if (const auto* s = std::get_if<Sphere<T>>(&p.shape)) sphere(s->center, s->radius);
  if (const auto* s = std::get_if<MovingSphere<T>>(&p.shape)) {
    sphere(moving_sphere_center(*s, T(0)), s->radius);
    sphere(moving_sphere_center(*s, T(1)), s->radius);
  }
  if (const auto* t = std::get_if<Triangle<T>>(&p.shape)) {
    point(t->p0);
    point(t->p0 + t->edge1);
    point(t->p0 + t->edge2);
  }
  if (const auto* q = std::get_if<Quad<T>>(&p.shape)) {
    Vec3<T> u, v;
    quad_edges(*q, u, v);
    point(q->corner);
    point(q->corner + u);
    point(q->corner + v);
    point(q->corner + u + v);
  }
  if (const auto* m = std::get_if<ConstantMedium<T>>(&p.shape))
    for (u32 i = 0; i < m->boundary_count; ++i) box.grow(primitive_bounds(flat, flat.boundaries[m->first_boundary + i]));
  return box;
}

template <class T>
bool box_inside(const Vec3<T>& lo, const Vec3<T>& hi, const Vec3<T>& outer_lo, const Vec3<T>& outer_hi) {
  return lo.x >= outer_lo.x && lo.y >= outer_lo.y && lo.z >= outer_lo.z && hi.x <= outer_hi.x && hi.y <= outer_hi.y && hi.z <= outer_hi.z;
}

template <class T>
void check_structure(const FlatScene<T>& flat) {
  const std::vector<BvhNode<T>>& nodes = flat.nodes;
  ASSERT_FALSE(nodes.empty());
  std::vector<int> seen(flat.primitives.size(), 0);
  std::vector<int> visited(nodes.size(), 0);
  u32 max_depth = 0;
  int boxes_outside = 0, primitives_outside = 0;
  struct Entry {
    u32 node, depth;
  };
  std::vector<Entry> stack{{0, 1}};
  while (!stack.empty()) {
    const Entry e = stack.back();
    stack.pop_back();
    ASSERT_LT(e.node, nodes.size());
    ASSERT_EQ(visited[e.node]++, 0) << "node " << e.node << " reached twice";
    max_depth = std::max(max_depth, e.depth);
    const BvhNode<T>& n = nodes[e.node];
    if (n.count > 0) {
      ASSERT_LE(static_cast<u64>(n.left_first) + n.count, flat.primitives.size());
      for (u32 i = n.left_first; i < n.left_first + n.count; ++i) {
        ++seen[i];
        // Compared in double, where the primitive's bounds are exact.
        const Aabb b = primitive_bounds(flat, flat.primitives[i]);
        if (!(b.lo.x >= n.lo.x && b.lo.y >= n.lo.y && b.lo.z >= n.lo.z && b.hi.x <= n.hi.x && b.hi.y <= n.hi.y && b.hi.z <= n.hi.z))
          ++primitives_outside;
      }
    } else {
      const u32 first = e.node + 1, second = n.left_first;
      ASSERT_LT(first, nodes.size());
      ASSERT_LT(second, nodes.size());
      ASSERT_GT(second, first);
      for (u32 child : {first, second}) {
        if (!box_inside(nodes[child].lo, nodes[child].hi, n.lo, n.hi)) ++boxes_outside;
        stack.push_back({child, e.depth + 1});
      }
    }
  }
  EXPECT_EQ(boxes_outside, 0) << "child boxes not inside their parent";
  EXPECT_EQ(primitives_outside, 0) << "primitives not inside their leaf's box";
  for (std::size_t i = 0; i < seen.size(); ++i) ASSERT_EQ(seen[i], 1) << "primitive " << i << " is in " << seen[i] << " leaves";
  for (std::size_t i = 0; i < visited.size(); ++i) ASSERT_EQ(visited[i], 1) << "node " << i << " is unreachable";
  EXPECT_LE(max_depth, kBvhMaxDepth);
  EXPECT_EQ(max_depth, flat.bvh_depth);
}

// The wide tree: every primitive in exactly one leaf child whose box holds it, every node reached once, 2 to
// kWideBvhWidth children a node (1 only for a one-leaf scene), and no deeper than the binary tree (the stack is sized by it).
template <class T>
void check_wide_structure(const FlatScene<T>& flat) {
  const std::vector<WideBvhNode<T>>& nodes = flat.wide_nodes;
  ASSERT_FALSE(nodes.empty());
  std::vector<int> seen(flat.primitives.size(), 0);
  std::vector<int> visited(nodes.size(), 0);
  u32 max_depth = 0;
  int primitives_outside = 0;
  std::vector<std::pair<u32, u32>> stack{{0, 1}};
  while (!stack.empty()) {
    const auto [index, depth] = stack.back();
    stack.pop_back();
    ASSERT_LT(index, nodes.size());
    ASSERT_EQ(visited[index]++, 0) << "wide node " << index << " reached twice";
    max_depth = std::max(max_depth, depth);
    const WideBvhNode<T>& n = nodes[index];
    // The used slots come first, without gaps; each is a leaf (count > 0) or an inner node (count 0), never both.
    const u32 used = n.leaf_mask | n.inner_mask;
    const u32 child_count = static_cast<u32>(__builtin_popcount(used));
    ASSERT_EQ(n.leaf_mask & n.inner_mask, 0u) << "wide node " << index;
    ASSERT_LE(child_count, kWideBvhWidth);
    ASSERT_EQ(used, (1u << child_count) - 1u) << "wide node " << index;
    if (flat.primitives.size() > 1) {
      EXPECT_GE(child_count, 2u) << "wide node " << index;
    }
    for (u32 lane = 0; lane < child_count; ++lane)
      EXPECT_EQ(n.count[lane] > 0, (n.leaf_mask >> lane & 1u) != 0) << "wide node " << index << ", slot " << lane;
    for (u32 lane = 0; lane < child_count; ++lane) {
      if (n.count[lane] == 0) {
        stack.push_back({n.child[lane], depth + 1});
        continue;
      }
      ASSERT_LE(static_cast<u64>(n.child[lane]) + n.count[lane], flat.primitives.size());
      for (u32 i = n.child[lane]; i < n.child[lane] + n.count[lane]; ++i) {
        ++seen[i];
        const Aabb b = primitive_bounds(flat, flat.primitives[i]);
        if (!(b.lo.x >= n.bounds[0][lane] && b.lo.y >= n.bounds[1][lane] && b.lo.z >= n.bounds[2][lane] && b.hi.x <= n.bounds[3][lane] &&
              b.hi.y <= n.bounds[4][lane] && b.hi.z <= n.bounds[5][lane]))
          ++primitives_outside;
      }
    }
  }
  EXPECT_EQ(primitives_outside, 0) << "primitives not inside their leaf's box";
  for (std::size_t i = 0; i < seen.size(); ++i) ASSERT_EQ(seen[i], 1) << "primitive " << i << " is in " << seen[i] << " wide leaves";
  for (std::size_t i = 0; i < visited.size(); ++i) ASSERT_EQ(visited[i], 1) << "wide node " << i << " is unreachable";
  EXPECT_LE(max_depth, flat.bvh_depth);
}

TYPED_TEST(BvhStructure, WideTreeHoldsEveryPrimitiveOnceAndIsNoDeeper) {
  using T = TypeParam;
  const FlatScene<T> flat = flatten_scene<T>(random_scene(12345), RenderSettings{});
  check_wide_structure(flat);
  // Folding every other level: about half the binary tree's interior nodes are left.
  EXPECT_LT(flat.wide_nodes.size(), flat.nodes.size() / 2);
}

// Expected cost per ray of a wide tree under the folding's cost model (kWideNodeCost per node visited,
// kWidePrimitiveCost per primitive tested, visits in proportion to box surface area), in units of the root's area.
template <class T>
double box_area(const BvhNode<T>& n) {
  const double dx = static_cast<double>(n.hi.x - n.lo.x), dy = static_cast<double>(n.hi.y - n.lo.y), dz = static_cast<double>(n.hi.z - n.lo.z);
  return dx * dy + dy * dz + dz * dx;
}

template <class T>
double wide_tree_cost(const FlatScene<T>& flat) {
  double cost = box_area(flat.nodes[0]) * kWideNodeCost;
  for (const WideBvhNode<T>& n : flat.wide_nodes)
    for (u32 used = n.leaf_mask | n.inner_mask, lane = 0; lane < kWideBvhWidth; ++lane) {
      if (!(used >> lane & 1u)) continue;
      const double dx = static_cast<double>(n.bounds[3][lane] - n.bounds[0][lane]), dy = static_cast<double>(n.bounds[4][lane] - n.bounds[1][lane]),
                   dz = static_cast<double>(n.bounds[5][lane] - n.bounds[2][lane]);
      const double area = dx * dy + dy * dz + dz * dx;
      cost += n.leaf_mask >> lane & 1u ? area * n.count[lane] * kWidePrimitiveCost : area * kWideNodeCost;
    }
  return cost / box_area(flat.nodes[0]);
}

// The same, and the number of wide nodes, for the folding that opens the inner child with the largest box until a
// node has kWideBvhWidth children or only leaves, computed on the binary tree.
template <class T>
double greedy_folding_cost(const FlatScene<T>& flat, u32 index, std::size_t& nodes) {
  const std::vector<BvhNode<T>>& b = flat.nodes;
  std::vector<u32> children{index + 1, b[index].left_first};
  while (children.size() < kWideBvhWidth) {
    int widest = -1;
    for (std::size_t k = 0; k < children.size(); ++k)
      if (b[children[k]].count == 0 && (widest < 0 || box_area(b[children[k]]) > box_area(b[children[widest]]))) widest = static_cast<int>(k);
    if (widest < 0) break;
    const u32 opened = children[widest];
    children[widest] = opened + 1;
    children.push_back(b[opened].left_first);
  }
  ++nodes;
  double cost = box_area(b[index]) * kWideNodeCost;
  for (u32 c : children) cost += b[c].count > 0 ? box_area(b[c]) * b[c].count * kWidePrimitiveCost : greedy_folding_cost(flat, c, nodes);
  return cost;
}

// Folding by dynamic programming finds the cheapest wide tree the binary tree allows, so it costs no more than the
// greedy folding; and where the greedy folding leaves nodes at the bottom with two children, it fills them.
// Walking a mesh instance is a tree walk of its own: two in one leaf would be walked in the order they are stored,
// not the nearer first, so each instance keeps a leaf of its own in the binary and the wide tree (40 overlapping
// instances in a row, beside concentric spheres, which still share leaves).
TYPED_TEST(BvhStructure, EveryMeshInstanceHasALeafOfItsOwn) {
  using T = TypeParam;
  TestRandom rng(5);
  SceneDescription scene = empty_scene();
  const u32 file = add_mesh_file(scene, test::triangle_soup(rng, 200), "/objects");
  for (int i = 0; i < 40; ++i) test::place_mesh(scene, file, {0.5, 0.5, 0.5}, {3.0 * i, 7.0 * i, 0}, {0.6 * i, 0.1 * (i % 3), 0});
  for (int i = 0; i < 50; ++i) {  // four spheres a centre: no split separates them, so they share a leaf
    const Vec3d centre = rng.vec3(-10, 10);
    for (int k = 1; k <= 4; ++k) scene.objects.push_back(object(Sphere<double>{centre, 0.1 * k}));
  }
  RenderSettings settings;
  const FlatScene<T> flat = flatten_scene<T>(scene, settings);
  auto is_instance = [&](u32 p) { return std::holds_alternative<MeshInstance<T>>(flat.primitives[p].shape); };
  int instances = 0, shared_sphere_leaves = 0;
  for (const BvhNode<T>& n : flat.nodes)
    for (u32 p = n.left_first; n.count > 0 && p < n.left_first + n.count; ++p)
      if (is_instance(p)) {
        EXPECT_EQ(n.count, 1u) << "a binary leaf holds instance " << p << " and more";
      }
  for (const WideBvhNode<T>& n : flat.wide_nodes)
    for (u32 lane = 0; lane < kWideBvhWidth; ++lane) {
      if (!(n.leaf_mask >> lane & 1u)) continue;
      for (u32 p = n.child[lane]; p < n.child[lane] + n.count[lane]; ++p) {
        if (is_instance(p)) {
          ++instances;
          EXPECT_EQ(n.count[lane], 1u) << "a wide leaf holds instance " << p << " and more";
        }
      }
      if (n.count[lane] > 1) ++shared_sphere_leaves;
    }
  EXPECT_EQ(instances, 40);
  EXPECT_GT(shared_sphere_leaves, 10);
}

TYPED_TEST(BvhStructure, FoldedWideTreeCostsNoMoreThanGreedyFoldingWithFewerNodes) {
  using T = TypeParam;
  for (u64 seed : {12345u, 777u}) {
    const FlatScene<T> flat = flatten_scene<T>(random_scene(seed), RenderSettings{});
    std::size_t greedy_nodes = 0;
    const double folded = wide_tree_cost(flat), greedy = greedy_folding_cost(flat, 0, greedy_nodes) / box_area(flat.nodes[0]);
    EXPECT_LE(folded, greedy * (1 + 1e-9)) << "seed " << seed;
    EXPECT_GT(folded, 1.0);  // at least the root and one primitive
    EXPECT_LT(flat.wide_nodes.size(), greedy_nodes) << "seed " << seed;
  }
}

TYPED_TEST(BvhStructure, EveryPrimitiveInOneLeafAndChildBoxesInsideParents) {
  using T = TypeParam;
  const SceneDescription scene = random_scene(12345);
  const FlatScene<T> flat = flatten_scene<T>(scene, RenderSettings{});
  check_structure(flat);
  EXPECT_GT(flat.bvh_depth, 8u);  // a real tree, not one leaf
}

TYPED_TEST(BvhStructure, InvariantsHoldForSkewedAndCoincidentCentroids) {
  using T = TypeParam;
  SceneDescription scene = empty_scene();
  for (int k = 0; k < 120; ++k) {
    const double x = std::pow(1.2, k * 0.5);
    scene.objects.push_back(object(Sphere<double>{{x, 0, 0}, 0.05 * x}));
  }
  // Many primitives with one centroid.
  for (int i = 0; i < 40; ++i) scene.objects.push_back(object(Sphere<double>{{-5, -5, -5}, 0.01 * (i + 1)}));
  const FlatScene<T> flat = flatten_scene<T>(scene, RenderSettings{});
  check_structure(flat);
}

// Primitives whose centroids all coincide give the surface-area heuristic nothing to separate; the builder then
// splits by count, so that no leaf grows beyond its usual size (one leaf of them all made every ray test each one).
TEST(BvhStructure, CoincidentSpheresGiveSmallLeaves) {
  SceneDescription scene = empty_scene();
  // Radii apart, so that they are not copies of one sphere (those are drawn once: below).
  for (int i = 0; i < 10000; ++i) scene.objects.push_back(object(Sphere<double>{{1, 2, 3}, 0.5 + 1e-6 * i}));
  const FlatScene<float> flat = flatten_scene<float>(scene, RenderSettings{});
  ASSERT_EQ(flat.primitives.size(), 10000u);
  check_structure(flat);
  u32 largest_leaf = 0;
  for (const BvhNode<float>& n : flat.nodes) largest_leaf = std::max(largest_leaf, n.count);
  EXPECT_LE(largest_leaf, kMaxLeafSize);
  u32 largest_wide_leaf = 0;
  for (const WideBvhNode<float>& n : flat.wide_nodes)
    for (u32 lane = 0; lane < kWideBvhWidth; ++lane)
      if (n.leaf_mask >> lane & 1u) largest_wide_leaf = std::max(largest_wide_leaf, static_cast<u32>(n.count[lane]));
  EXPECT_LE(largest_wide_leaf, kMaxLeafSize);
}

// Copies of one primitive are hit at one distance, where the first found wins; no split separates them, so every
// ray reaching them tested them all (100,000 copies of a sphere traced about 5,000 rays a second). Exact copies of
// the same material are drawn once, as the first written; a copy of another material, or turned the other way, is
// another surface and is kept.
TEST(BvhStructure, ExactCopiesAreDrawnOnce) {
  SceneDescription scene = empty_scene();
  scene.materials.push_back(scene.materials[0]);
  for (int i = 0; i < 100000; ++i) {
    scene.objects.push_back(object(Sphere<double>{{0, 0, -1}, 0.5}));
    scene.objects.push_back(object(TriangleSettings{{Vec3d{0, 0, -2}, Vec3d{1, 0, -2}, Vec3d{0, 1, -2}}, std::nullopt, std::nullopt}));
  }
  scene.objects.push_back(object(Sphere<double>{{0, 0, -1}, 0.5}, 2));  // another material
  scene.objects.push_back(object(TriangleSettings{{Vec3d{0, 0, -2}, Vec3d{0, 1, -2}, Vec3d{1, 0, -2}}, std::nullopt, std::nullopt}));  // turned over
  scene.objects.push_back(object(Sphere<double>{{0, 0, -1}, 0.5}, 0, RigidTransform::from_euler_degrees({0, 0, 0}, {0, 0, 1e-9})));
  const FlatScene<float> flat = flatten_scene<float>(scene, RenderSettings{});
  EXPECT_EQ(flat.primitives.size(), 5u);
  check_structure(flat);

  // In a mesh: a triangle written again from another corner is the same triangle; with its corners turned the other
  // way, or of another material, it is not.
  test::TempDir dir;
  std::string obj = "mtllib two.mtl\nv 0 0 -2\nv 1 0 -2\nv 0 1 -2\nusemtl a\n";
  for (int i = 0; i < 100000; ++i) obj += i % 3 == 0 ? "f 1 2 3\n" : i % 3 == 1 ? "f 2 3 1\n" : "f 3 1 2\n";
  obj += "f 1 3 2\nusemtl b\nf 1 2 3\n";
  test::write_text_file(dir / "copies.obj", obj);
  test::write_text_file(dir / "two.mtl", "newmtl a\nKd 0.5 0.5 0.5\nnewmtl b\nKd 0.8 0.2 0.2\n");
  const FlatScene<float> mesh = flatten_scene<float>(load_scene_file(dir / "copies.obj"), RenderSettings{});
  EXPECT_EQ(mesh.mesh_triangles.size(), 3u);
}

TYPED_TEST(BvhStructure, SinglePrimitiveSceneIsOneLeaf) {
  using T = TypeParam;
  SceneDescription scene = empty_scene();
  scene.objects.push_back(object(Sphere<double>{{0, 0, -5}, 1}));
  const FlatScene<T> flat = flatten_scene<T>(scene, RenderSettings{});
  ASSERT_EQ(flat.nodes.size(), 1u);
  EXPECT_EQ(flat.nodes[0].count, 1u);
  check_structure(flat);
  const SceneView<T> view = flat.view();
  const SampleRandom random = SampleRandom::make(1, 0, 0);
  const IntersectContext<T> context{view.boundaries, &random, 0};
  Hit<T> hit;
  ASSERT_TRUE(closest_hit(view, Ray<T>{test::to<T>({0, 0, 0}), test::to<T>({0, 0, -1}), T(0)}, context, hit));
  EXPECT_NEAR(hit.t, 4.0, 1e-5);
  EXPECT_FALSE(closest_hit(view, Ray<T>{test::to<T>({0, 0, 0}), test::to<T>({0, 0, 1}), T(0)}, context, hit));
}

TEST(BvhStructure, BuilderStopsAtTheDepthLimitWithALargerLeaf) {
  const FlatScene<double> flat = flatten_scene<double>(depth_limited_scene(), RenderSettings{});
  check_structure(flat);
  EXPECT_EQ(flat.bvh_depth, kBvhMaxDepth);
  u32 largest_leaf = 0;
  for (const BvhNode<double>& n : flat.nodes) largest_leaf = std::max(largest_leaf, n.count);
  EXPECT_GT(largest_leaf, kMaxLeafSize);
}

// A scene without primitives has a root with an inverted box: no ray enters it, and nothing past the one-node
// array is read (the parser requires an object, but flatten_scene accepts an empty description).
TEST(BvhStructure, EmptySceneHasNoHits) {
  const FlatScene<float> flat = flatten_scene<float>(empty_scene(), RenderSettings{});
  const SceneView<float> view = flat.view();
  const SampleRandom random = SampleRandom::make(1, 0, 0);
  const IntersectContext<float> context{view.boundaries, &random, 0};
  Hit<float> hit;
  EXPECT_FALSE(closest_hit(view, Ray<float>{{0, 0, 0}, {0, 0, -1}, 0.0f}, context, hit));
}

// Mesh BVHs are built over float boxes (half the memory of double ones). Where the vertices are floats, as a PLY
// file's usually are, the boxes are exact and the tree must be the one double boxes give, node for node.
TEST(BvhBuilder, FloatBoxesOfFloatVerticesGiveTheDoubleTree) {
  TestRandom random(15);
  std::vector<Aabb> bounds;
  std::vector<FloatBox> float_bounds;
  for (int i = 0; i < 50000; ++i) {  // more than one parallel subtree (16,384 primitives)
    const Vec3d centre = random.vec3(-100, 100);
    Aabb box;
    for (int corner = 0; corner < 3; ++corner) {
      const Vec3d v = centre + random.vec3(-0.5, 0.5);
      box.grow(Vec3d{static_cast<float>(v.x), static_cast<float>(v.y), static_cast<float>(v.z)});
    }
    bounds.push_back(box);
    float_bounds.push_back(outward_float_box(box));
  }
  const BuiltBvh<double> wide = build_bvh(bounds);
  const BuiltBvh<float> narrow = build_bvh(float_bounds);
  ASSERT_EQ(wide.nodes.size(), narrow.nodes.size());
  EXPECT_EQ(wide.order, narrow.order);
  EXPECT_EQ(wide.depth, narrow.depth);
  for (std::size_t i = 0; i < wide.nodes.size(); ++i) {
    const BvhNode<double>& a = wide.nodes[i];
    const BvhNode<float>& b = narrow.nodes[i];
    ASSERT_TRUE(a.left_first == b.left_first && a.count == b.count && a.lo.x == b.lo.x && a.lo.y == b.lo.y && a.lo.z == b.lo.z && a.hi.x == b.hi.x &&
                a.hi.y == b.hi.y && a.hi.z == b.hi.z)
        << "node " << i;
  }
}

// Where they are not floats, each corner is rounded outward, by at most one float step.
TEST(BvhBuilder, FloatBoxesContainTheirDoubleBoxes) {
  TestRandom random(16);
  for (int i = 0; i < 10000; ++i) {
    Aabb box;
    const double magnitude = std::ldexp(1.0, static_cast<int>(random.uniform(-60, 60)));
    box.grow(random.vec3(-magnitude, magnitude));
    box.grow(random.vec3(-magnitude, magnitude));
    const FloatBox f = outward_float_box(box);
    for (int axis = 0; axis < 3; ++axis) {
      ASSERT_LE(static_cast<double>(f.lo[axis]), box.lo[axis]);
      ASSERT_GE(static_cast<double>(f.hi[axis]), box.hi[axis]);
      ASSERT_GT(static_cast<double>(std::nextafter(f.lo[axis], largest<float>())), box.lo[axis]);
      ASSERT_LT(static_cast<double>(std::nextafter(f.hi[axis], -largest<float>())), box.hi[axis]);
    }
  }
}

// Flattening that lets go of the description as it goes (the render command's, for large scenes' memory) gives the
// flat scene of the one that keeps it: the same image, bit for bit; the description keeps its source and loses its
// objects, materials, textures and texels. Scenes with an image texture, a medium and many objects.
// A shipped scene's settings for a small render: 24x16 pixels, 4 samples each.
RenderSettings small_render(const SceneDescription& scene) {
  RenderSettings settings = scene.render;
  settings.width = 24;
  settings.height = 16;
  settings.samples_per_pixel = 4;
  return settings;
}

// Both flat scenes render to the same image on the CPU, bit for bit.
void expect_same_cpu_image(const FlatScene<float>& a, const FlatScene<float>& b, const char* name) {
  auto renderer = make_backend<float>("cpu", 0, 0);
  const LinearImage x = render_scene(*renderer, a).image, y = render_scene(*renderer, b).image;
  ASSERT_EQ(x.rgb.size(), y.rgb.size()) << name;
  EXPECT_EQ(std::memcmp(x.rgb.data(), y.rgb.data(), x.rgb.size() * sizeof(float)), 0) << name;
}

TEST(FlattenReleasing, GivesTheSameImageAndLetsTheDescriptionGo) {
  for (const char* name : {"tiny.json", "seed-default.json", "book2-final.json"}) {
    SceneDescription scene = load_scene_file(test::scene_path(name));
    const RenderSettings settings = small_render(scene);
    const FlatScene<float> kept = flatten_scene<float>(scene, settings);
    const std::size_t texels = scene.texels.size();
    const FlatScene<float> released = flatten_scene_releasing<float>(scene, settings);
    EXPECT_TRUE(scene.objects.empty() && scene.materials.empty() && scene.textures.empty() && scene.texels.empty()) << name;
    EXPECT_EQ(released.texels.size(), texels) << name;
    EXPECT_NE(scene.source.find(name), std::string::npos) << name;
    EXPECT_EQ(kept.bytes(), released.bytes()) << name;
    expect_same_cpu_image(kept, released, name);
  }
}

TEST(FlattenReleasing, WithoutTheBinaryTreeTheCpuGivesTheSameImage) {
  // The render command keeps only the wide tree for the CPU backend: the lights' view of the scene's box (the
  // background's power) and the image must be those of the scene with both trees.
  for (const char* name : {"seed-default.json", "cornell-box.json", "meshes.json"}) {
    SceneDescription scene = load_scene_file(test::scene_path(name));
    const RenderSettings settings = small_render(scene);
    const FlatScene<float> both = flatten_scene<float>(scene, settings);
    const FlatScene<float> wide = flatten_scene_releasing<float>(scene, settings, 0, false);
    EXPECT_FALSE(both.nodes.empty()) << name;
    EXPECT_TRUE(wide.nodes.empty()) << name;
    EXPECT_EQ(both.wide_nodes.size(), wide.wide_nodes.size()) << name;
    for (int axis = 0; axis < 3; ++axis) {
      // The box of the bounds in double, padded; the tree's root, built over float boxes, holds it.
      EXPECT_LE(both.nodes[0].lo[axis], both.scene_lo[axis]) << name;
      EXPECT_GE(both.nodes[0].hi[axis], both.scene_hi[axis]) << name;
      EXPECT_EQ(wide.scene_lo[axis], both.scene_lo[axis]) << name;
      EXPECT_EQ(wide.scene_hi[axis], both.scene_hi[axis]) << name;
    }
    expect_same_cpu_image(both, wide, name);
  }
}

}  // namespace
}  // namespace pt
