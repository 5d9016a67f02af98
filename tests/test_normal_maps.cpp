// Normal maps: the mapped normal and the tangent frames it is read in (derived from uvs, from a mesh's tangents, on
// quads and spheres, on back faces), the frame shared by sampling and evaluation, and renders with normal maps.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "backends/registry.hpp"
#include "kernel/integrator.hpp"
#include "scene_cases.hpp"
#include "test_support.hpp"
#if PT_HAVE_CUDA
#include "backends/cuda/cuda_backend.hpp"
#endif

namespace pt {
namespace {

using V = Vec3<double>;

void expect_vec_near(const V& a, const V& b, double tolerance) {
  EXPECT_NEAR(a.x, b.x, tolerance);
  EXPECT_NEAR(a.y, b.y, tolerance);
  EXPECT_NEAR(a.z, b.z, tolerance);
}

const TriangleAttributes<double>* const kNoTriangleAttributes = nullptr;

Ray<double> ray_to(const V& from, const V& to) { return Ray<double>{from, normalize(to - from), 0}; }

// ---- The mapped normal ----

TEST(NormalFromMap, EqualsTheHandComputedNormalAndIsUnitLength) {
  const V n{0, 0, 1}, t{1, 0, 0};
  // Texel (0.75, 0.5, 1): tangent-space (0.5, 0, 1).
  V mapped = normal_from_map(n, t, 1.0, V{0.75, 0.5, 1.0}, 1.0);
  expect_vec_near(mapped, V{0.5, 0, 1} / std::sqrt(1.25), 1e-15);
  EXPECT_NEAR(length(mapped), 1.0, 1e-15);
  // The scale multiplies x and y only: (1, 0, 1).
  mapped = normal_from_map(n, t, 1.0, V{0.75, 0.5, 1.0}, 2.0);
  expect_vec_near(mapped, V{1, 0, 1} / std::sqrt(2.0), 1e-15);
  // y runs along the bitangent, handedness x normal x tangent = (0, 1, 0) for +1.
  mapped = normal_from_map(n, t, 1.0, V{0.5, 0.75, 1.0}, 1.0);
  expect_vec_near(mapped, V{0, 0.5, 1} / std::sqrt(1.25), 1e-15);
  mapped = normal_from_map(n, t, -1.0, V{0.5, 0.75, 1.0}, 1.0);
  expect_vec_near(mapped, V{0, -0.5, 1} / std::sqrt(1.25), 1e-15);
  // A tilted frame: normal (0, 1, 0), tangent (0, 0, -1), bitangent normal x tangent = (-1, 0, 0).
  mapped = normal_from_map(V{0, 1, 0}, V{0, 0, -1}, 1.0, V{1.0, 0.0, 0.5 + 0.5 * std::sqrt(0.5)}, std::sqrt(0.5));
  // (x, y, z) = (sqrt(.5), -sqrt(.5), sqrt(.5)): sqrt(.5) ((0, 0, -1) - (-1, 0, 0) + (0, 1, 0)), normalised.
  expect_vec_near(mapped, V{1, 1, -1} / std::sqrt(3.0), 1e-15);
  EXPECT_NEAR(length(mapped), 1.0, 1e-15);
  // A flat texel leaves the normal exactly; a texel of zeros' middle (no direction) falls back to it.
  EXPECT_EQ(normal_from_map(n, t, 1.0, V{0.5, 0.5, 1.0}, 1.0).z, 1.0);
  const V none = normal_from_map(n, t, 1.0, V{0.5, 0.5, 0.5}, 1.0);
  EXPECT_TRUE(none.x == 0 && none.y == 0 && none.z == 1);
}

TEST(EnsureValidReflection, MirrorDirectionStaysAboveTheGeometricSurfaceAndValidNormalsAreKept) {
  test::TestRandom rng(11);
  const V ng{0, 0, 1};
  int corrected = 0;
  for (int i = 0; i < 20000; ++i) {
    V wo = rng.unit_vector();
    wo.z = std::abs(wo.z);
    const V n = rng.unit_vector();
    const V out = ensure_valid_reflection(ng, wo, n);
    ASSERT_NEAR(length(out), 1.0, 1e-9);
    const double threshold = std::min(0.9 * wo.z, 0.01);
    const V reflected = 2 * dot(out, wo) * out - wo;
    const bool valid_before = dot(n, wo) > 0 && dot(2 * dot(n, wo) * n - wo, ng) >= threshold;
    if (valid_before) {
      EXPECT_TRUE(out.x == n.x && out.y == n.y && out.z == n.z);
      continue;
    }
    ++corrected;
    EXPECT_GE(dot(reflected, ng), threshold - 1e-7) << "wo " << wo.x << " " << wo.y << " " << wo.z << ", n " << n.x << " " << n.y << " " << n.z;
    EXPECT_GT(out.z, 0.0);
    if (wo.z > 1e-3) {
      EXPECT_GT(dot(out, wo), 0.0);
    }
    // Turned towards the geometric normal in the plane of the two: no part across it.
    EXPECT_NEAR(dot(cross(ng, n), out), 0.0, 1e-9);
  }
  EXPECT_GT(corrected, 5000);
}

// ---- Tangent frames ----

// The frame describe_hit gives a triangle hit at its centroid from `from`, with texture coordinates (us, vs) or none.
SurfacePoint<double> triangle_hit(const V& p0, const V& p1, const V& p2, const double* us, const double* vs, const V& from) {
  TriangleAttributes<double> attributes{};
  if (us) {
    attributes.has_uvs = 1;
    for (int k = 0; k < 3; ++k) attributes.u[k] = us[k], attributes.v[k] = vs[k];
  }
  const Triangle<double> triangle{p0, p1 - p0, p2 - p0, 0};
  const Ray<double> ray = ray_to(from, (p0 + p1 + p2) / 3.0);
  Hit<double> hit{};
  EXPECT_TRUE(intersect_triangle(triangle, ray, 0.0, 1e30, hit));
  return describe_hit(Primitive<double>{triangle, 0}, &attributes, MeshData<double>{}, ray, hit, true, true);
}

TEST(DerivedTangents, FollowIncreasingUOfTheTriangleUvs) {
  const V p0{0, 0, 0}, p1{2, 0, 0}, p2{0, 3, 0}, above{0.3, 0.4, 5};
  {
    const double us[3] = {0, 1, 0}, vs[3] = {0, 0, 1};  // u along x, v along y
    const SurfacePoint<double> at = triangle_hit(p0, p1, p2, us, vs, above);
    expect_vec_near(at.tangent, V{1, 0, 0}, 1e-15);
    EXPECT_EQ(at.handedness, 1.0);
  }
  {
    const double us[3] = {0, 0, -1}, vs[3] = {0, 1, 0};  // u down y, v along x
    const SurfacePoint<double> at = triangle_hit(p0, p1, p2, us, vs, above);
    expect_vec_near(at.tangent, V{0, -1, 0}, 1e-15);
    EXPECT_EQ(at.handedness, 1.0);
  }
  {
    const double us[3] = {1, 0, 1}, vs[3] = {0, 0, 1};  // mirrored: u against x, v along y
    const SurfacePoint<double> at = triangle_hit(p0, p1, p2, us, vs, above);
    expect_vec_near(at.tangent, V{-1, 0, 0}, 1e-15);
    EXPECT_EQ(at.handedness, -1.0);
  }
  // A tilted triangle with skewed uvs: the tangent lies in its plane, v does not change along it and u grows.
  test::TestRandom rng(5);
  for (int i = 0; i < 200; ++i) {
    const V a = rng.vec3(-1, 1), b = rng.vec3(-1, 1), c = rng.vec3(-1, 1);
    const double us[3] = {rng.uniform(), rng.uniform(), rng.uniform()};
    const double vs[3] = {rng.uniform(), rng.uniform(), rng.uniform()};
    const V e1 = b - a, e2 = c - a, n = normalize(cross(e1, e2));
    const double du1 = us[1] - us[0], du2 = us[2] - us[0], dv1 = vs[1] - vs[0], dv2 = vs[2] - vs[0];
    if (std::abs(du1 * dv2 - du2 * dv1) < 1e-3 || length(cross(e1, e2)) < 1e-3) continue;
    const SurfacePoint<double> at = triangle_hit(a, b, c, us, vs, (a + b + c) / 3.0 + 3.0 * n);
    ASSERT_NEAR(length(at.tangent), 1.0, 1e-12);
    EXPECT_NEAR(dot(at.tangent, n), 0.0, 1e-12);
    // at.tangent = s e1 + r e2: solved through the Gram matrix of the edges.
    const double g11 = dot(e1, e1), g12 = dot(e1, e2), g22 = dot(e2, e2), det = g11 * g22 - g12 * g12;
    const double t1 = dot(at.tangent, e1), t2 = dot(at.tangent, e2);
    const double s = (g22 * t1 - g12 * t2) / det, r = (g11 * t2 - g12 * t1) / det;
    EXPECT_NEAR(s * dv1 + r * dv2, 0.0, 1e-9 * (1 + std::abs(s * du1 + r * du2)));
    EXPECT_GT(s * du1 + r * du2, 0.0);
    // The bitangent's side: v grows along handedness x normal x tangent.
    const V bitangent = at.handedness * cross(n, at.tangent);
    const double b1 = dot(bitangent, e1), b2 = dot(bitangent, e2);
    EXPECT_GT(((g22 * b1 - g12 * b2) * dv1 + (g11 * b2 - g12 * b1) * dv2) / det, 0.0);
  }
}

TEST(DerivedTangents, DegenerateOrMissingUvsGiveNoFrameAndNoNaN) {
  const V p0{0, 0, 0}, p1{2, 0, 0}, p2{0, 3, 0}, above{0.3, 0.4, 5};
  const double same_u[3] = {0.5, 0.5, 0.5}, same_v[3] = {0.5, 0.5, 0.5};
  const double line_u[3] = {0, 1, 2}, line_v[3] = {0, 1, 2};
  std::vector<SurfacePoint<double>> points = {triangle_hit(p0, p1, p2, same_u, same_v, above), triangle_hit(p0, p1, p2, line_u, line_v, above),
                                              triangle_hit(p0, p1, p2, nullptr, nullptr, above)};
  // A normal map on such points leaves the shading normal, and scattering stays finite.
  const std::vector<u8> texels = {255, 128, 128};
  const float decode[256] = {};
  const std::vector<Texture<double>> textures = {SolidTexture<double>{{0.8, 0.8, 0.8}}, SolidTexture<double>{{0, 0.5, 0}},
                                                 ImageTexture<double>{1, 1, 0, 1.0, {1, 1, 1}, 1}};
  const TextureData<double> data{texels.data(), decode, nullptr, nullptr};
  const MetallicRoughness<double> material{0, 1, 2, 1.0};
  for (const SurfacePoint<double>& at : points) {
    EXPECT_TRUE(at.tangent.x == 0 && at.tangent.y == 0 && at.tangent.z == 0);
    const V wo = normalize(above - at.p);
    const V n = metallic_roughness_normal(material, at, wo, textures.data(), data);
    EXPECT_TRUE(n.x == at.normal.x && n.y == at.normal.y && n.z == at.normal.z);
    const SampleRandom random = SampleRandom::make(1, 2, 3);
    for (u32 bounce = 0; bounce < 100; ++bounce) {
      Scatter<double> s;
      if (material_scatter(Material<double>{material}, Ray<double>{above, -wo, 0}, at, textures.data(), data, BounceRandom{&random, bounce}, s)) {
        EXPECT_TRUE(is_finite(s.attenuation) && std::isfinite(s.pdf));
      }
    }
  }
}

TEST(TangentFrames, QuadsFollowTheirEdgesAndSpheresTheirLongitude) {
  {
    // Normal u x v = +y; u along x, v along -z.
    const Quad<double> quad = make_quad<double>(V{0, 0, 0}, V{2, 0, 0}, V{0, 0, -3});
    const Ray<double> ray = ray_to(V{1, 4, -1}, V{1, 0, -1});
    Hit<double> hit{};
    ASSERT_TRUE(intersect_quad(quad, ray, 0.0, 1e30, hit));
    const SurfacePoint<double> at = describe_hit(Primitive<double>{quad, 0}, kNoTriangleAttributes, MeshData<double>{}, ray, hit, true, true);
    expect_vec_near(at.tangent, V{1, 0, 0}, 1e-15);
    EXPECT_EQ(at.handedness, 1.0);  // normal x tangent = (0, 0, -1), along v
  }
  const Sphere<double> sphere{V{0, 0, 0}, 1};
  {
    const Ray<double> ray = ray_to(V{4, 0, 0}, V{0, 0, 0});
    Hit<double> hit{};
    ASSERT_TRUE(intersect_sphere(sphere.center, sphere.radius, ray, 0.0, 1e30, hit));
    const SurfacePoint<double> at = describe_hit(Primitive<double>{sphere, 0}, kNoTriangleAttributes, MeshData<double>{}, ray, hit, true, true);
    // u = 1 - (atan2(z, x) + pi) / 2 pi falls towards +z: u grows along -z at (1, 0, 0); v grows up.
    expect_vec_near(at.tangent, V{0, 0, -1}, 1e-12);
    EXPECT_EQ(at.handedness, 1.0);
  }
  {
    const Ray<double> ray = ray_to(V{0, 4, 0}, V{0, 0, 0});  // the pole: no direction of growing u
    Hit<double> hit{};
    ASSERT_TRUE(intersect_sphere(sphere.center, sphere.radius, ray, 0.0, 1e30, hit));
    const SurfacePoint<double> at = describe_hit(Primitive<double>{sphere, 0}, kNoTriangleAttributes, MeshData<double>{}, ray, hit, true, true);
    EXPECT_TRUE(at.tangent.x == 0 && at.tangent.y == 0 && at.tangent.z == 0);
  }
}

TEST(TangentFrames, BackFaceSeesTheMirrorImageOfTheFrontNormal) {
  const V p0{0, 0, 0}, p1{2, 0, 0}, p2{0, 3, 0};
  const double us[3] = {0, 1, 0}, vs[3] = {0, 0, 1};
  const SurfacePoint<double> front = triangle_hit(p0, p1, p2, us, vs, V{0.3, 0.4, 5});
  const SurfacePoint<double> back = triangle_hit(p0, p1, p2, us, vs, V{0.3, 0.4, -5});
  ASSERT_TRUE(front.front_face);
  ASSERT_FALSE(back.front_face);
  const V texel{0.8, 0.35, 0.9};
  const V n_front = normal_from_map(front.normal, front.tangent, front.handedness, texel, 1.0);
  const V n_back = normal_from_map(back.normal, back.tangent, back.handedness, texel, 1.0);
  // The same bump seen from the other side: the facing normal is the front's turned round.
  expect_vec_near(n_back, -n_front, 1e-15);
  EXPECT_GT(n_front.x, 0.0);  // tilted along +u
  EXPECT_LT(n_front.y, 0.0);  // and along -v
}

// ---- Sampling and evaluation in one frame ----

TEST(NormalMappedMaterial, ScatterAndEvaluateShareTheMappedFrame) {
  // A quad in z = 0 with u along x and v along y, its normal map one texel (191, 140, 230), read as linear bytes.
  const Quad<double> quad = make_quad<double>(V{-1, -1, 0}, V{2, 0, 0}, V{0, 2, 0});
  const V eye{0.4, -0.3, 2};
  const Ray<double> ray = ray_to(eye, V{0.1, 0.2, 0});
  Hit<double> hit{};
  ASSERT_TRUE(intersect_quad(quad, ray, 0.0, 1e30, hit));
  const SurfacePoint<double> at = describe_hit(Primitive<double>{quad, 0}, kNoTriangleAttributes, MeshData<double>{}, ray, hit, true, true);
  const std::vector<u8> texels = {191, 140, 230};
  float decode[256];
  for (int i = 0; i < 256; ++i) decode[i] = 0.5f;  // an sRGB reading would give a flat map: the lookup must be linear
  const std::vector<Texture<double>> textures = {SolidTexture<double>{{0.7, 0.6, 0.5}}, SolidTexture<double>{{0, 0.4, 0.3}},
                                                 ImageTexture<double>{1, 1, 0, 1.0, {1, 1, 1}, 1}};
  const TextureData<double> data{texels.data(), decode, nullptr, nullptr};
  const MetallicRoughness<double> m{0, 1, 2, 0.8};
  const Material<double> material{m};
  ASSERT_TRUE(material_needs_tangent(material));
  // By hand: (2c - 1) with x, y times 0.8, in the frame (x, y, z).
  const V expected = normalize(V{(2 * 191 / 255.0 - 1) * 0.8, (2 * 140 / 255.0 - 1) * 0.8, 2 * 230 / 255.0 - 1});
  const V wo = -ray.direction;
  const V shading = metallic_roughness_normal(m, at, wo, textures.data(), data);
  expect_vec_near(shading, expected, 1e-12);
  const ShadingFrame<double> frame = frame_from_normal(expected);
  const MetallicRoughnessParams<double> params = metallic_roughness_params(m, at, textures.data(), data);
  const SampleRandom random = SampleRandom::make(7, 8, 9);
  int scattered = 0;
  for (u32 bounce = 0; bounce < 4000; ++bounce) {
    Scatter<double> s;
    if (!material_scatter(material, ray, at, textures.data(), data, BounceRandom{&random, bounce}, s)) continue;
    ++scattered;
    const V wi = s.ray.direction;
    ASSERT_GT(dot(wi, at.geometric_normal), 0.0);  // never through the surface
    const ScatterValue<double> value = material_evaluate(material, at, wo, wi, textures.data(), data);
    const BsdfEval<double> by_hand = evaluate_metallic_roughness(params, frame.to_local(wo), frame.to_local(wi));
    ASSERT_NEAR(s.pdf, value.pdf, 1e-9 * value.pdf);
    ASSERT_NEAR(value.pdf, by_hand.pdf, 1e-9 * by_hand.pdf);
    for (int c = 0; c < 3; ++c) ASSERT_NEAR(s.attenuation[c], value.value[c] / value.pdf, 1e-9 * (1 + s.attenuation[c]));
  }
  EXPECT_GT(scattered, 3000);
}

// ---- Renders ----

// A floor, a ball, a triangle with uvs and an OBJ quad, each metallic-roughness with the normal map NORMALS (or
// none), under a sky and a small light.
std::string normal_map_scene(const std::string& normal_keys) {
  const std::string material = R"({"type": "metallic_roughness", "base_color": [0.7, 0.7, 0.7], "roughness": 0.6)" + normal_keys + "}";
  const std::string metal = R"({"type": "metallic_roughness", "base_color": [0.9, 0.7, 0.5], "metallic": 1, "roughness": 0.3)" + normal_keys + "}";
  return R"({
    "render": {"width": 48, "height": 36, "samples_per_pixel": 32, "max_depth": 6},
    "camera": {"look_from": [0, 1.5, 4], "look_at": [0, 0.4, 0], "vertical_fov": 45},
    "background": {"type": "sky", "horizon": [1, 1, 1], "zenith": [0.4, 0.6, 1.0]},
    "objects": [
      {"type": "quad", "corner": [-3, 0, 3], "u": [6, 0, 0], "v": [0, 0, -6], "material": )" +
         material + R"(},
      {"type": "sphere", "center": [-0.8, 0.6, 0], "radius": 0.6, "material": )" +
         metal + R"(},
      {"type": "triangle", "vertices": [[0.2, 0, 0.5], [1.6, 0, 0.5], [0.9, 1.4, 0]], "uvs": [[0, 0], [1, 0], [0.5, 1]], "material": )" +
         material + R"(},
      {"type": "mesh", "file": "quad.obj", "transform": {"translate": [0.9, 0.7, -1]}},
      {"type": "sphere", "center": [1.5, 2.5, 1.5], "radius": 0.4, "material": {"type": "diffuse_light", "emission": [8, 7, 6]}}
    ]
  })";
}

// The folder of normal_map_scene: a bumpy 8x8 normal map, a flat one, and the OBJ quad with `norm bumps.ppm`.
void write_normal_map_files(const test::TempDir& dir) {
  std::vector<u8> bumps;
  test::TestRandom rng(3);
  for (int i = 0; i < 64; ++i) {
    const double x = rng.uniform(-0.6, 0.6), y = rng.uniform(-0.6, 0.6), z = std::sqrt(std::max(0.0, 1 - x * x - y * y));
    for (const double c : {x, y, z}) bumps.push_back(static_cast<u8>(std::lround((c + 1) * 127.5)));
  }
  test::write_ppm(dir / "bumps.ppm", 8, 8, bumps);
  test::write_ppm(dir / "flat.ppm", 1, 1, {128, 128, 255});
  test::write_text_file(dir / "quad.mtl", "newmtl bumpy\nKd 0.6 0.7 0.8\nPr 0.5\nnorm -bm 1.5 bumps.ppm\n");
  test::write_text_file(dir / "quad.obj",
                        "mtllib quad.mtl\nv -0.5 -0.5 0\nv 0.5 -0.5 0\nv 0.5 0.5 0\nv -0.5 0.5 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                        "vn 0 0 1\nusemtl bumpy\nf 1/1/1 2/2/1 3/3/1 4/4/1\n");
}

SceneDescription load_normal_map_scene(const test::TempDir& dir, const std::string& normal_keys) {
  test::write_text_file(dir / "scene.json", normal_map_scene(normal_keys));
  return load_scene_file(dir / "scene.json");
}

template <class T>
RenderResult render_with(const SceneDescription& scene, Integrator integrator, u32 seed = 5) {
  RenderSettings settings = scene.render;
  settings.seed = seed;
  const FlatScene<T> flat = flatten_scene<T>(scene, settings);
  auto renderer = make_backend<T>("cpu", 2, 0, integrator);
  return render_scene(*renderer, flat);
}

TEST(NormalMapRender, FlatNormalMapLooksLikeNoNormalMap) {
  test::TempDir dir;
  write_normal_map_files(dir);
  const SceneDescription with_map = load_normal_map_scene(dir, R"(, "normal_map": "flat.ppm")");
  const SceneDescription without = load_normal_map_scene(dir, "");
  ASSERT_NE(std::get<MetallicRoughness<double>>(with_map.materials[0]).normal_map, kNoNormalMap);
  const RenderResult a = render_with<float>(with_map, Integrator::kMegakernel);
  const RenderResult b = render_with<float>(without, Integrator::kMegakernel);
  ASSERT_EQ(a.image.rgb.size(), b.image.rgb.size());
  // (128, 128, 255) tilts the normal by 1/255 along u and v: every path bends a little, and the odd one takes another
  // branch (another light, another bounce), so most pixels barely change and the image's mean agrees far inside the
  // noise (measured: sums within 4e-5, a mean difference of 0.2%, 3% of values off by more than 2%). Read as sRGB,
  // the same map would tilt normals by 39 degrees.
  double sum_a = 0, sum_b = 0, difference = 0;
  std::size_t differing = 0;
  for (std::size_t i = 0; i < a.image.rgb.size(); ++i) {
    sum_a += a.image.rgb[i];
    sum_b += b.image.rgb[i];
    difference += std::abs(a.image.rgb[i] - b.image.rgb[i]);
    differing += std::abs(a.image.rgb[i] - b.image.rgb[i]) > 0.02 * (b.image.rgb[i] + 0.05);
  }
  std::printf("flat map against none: sums %.6f, mean difference %.5f of the mean, %zu of %zu values differ by more than 2%%\n", sum_a / sum_b,
              difference / sum_b, differing, a.image.rgb.size());
  EXPECT_NEAR(sum_a / sum_b, 1.0, 0.002);
  EXPECT_LT(difference / sum_b, 0.01);
  EXPECT_LT(differing, a.image.rgb.size() / 16) << "of " << a.image.rgb.size();
}

TEST(NormalMapRender, WavefrontEqualsMegakernelBitwise) {
  test::TempDir dir;
  write_normal_map_files(dir);
  const SceneDescription scene = load_normal_map_scene(dir, R"(, "normal_map": "bumps.ppm", "normal_scale": 1.2)");
  for (const bool light_sampling : {true, false}) {
    SceneDescription described = scene;
    described.render.light_sampling = light_sampling ? LightSampling::kNextEvent : LightSampling::kNone;
    const RenderResult mega = render_with<float>(described, Integrator::kMegakernel);
    const RenderResult wave = render_with<float>(described, Integrator::kWavefront);
    ASSERT_EQ(mega.image.rgb.size(), wave.image.rgb.size());
    EXPECT_EQ(0, std::memcmp(mega.image.rgb.data(), wave.image.rgb.data(), mega.image.rgb.size() * sizeof(float))) << light_sampling;
    EXPECT_EQ(mega.stats.rays, wave.stats.rays);
    EXPECT_EQ(mega.stats.dropped_samples, 0u);
  }
}

// Float on `backend` against double on the CPU, independent seeds, every sample finite.
void expect_normal_maps_float_matches_double(const test::TempDir& dir, const std::string& backend) {
  const SceneDescription scene = load_normal_map_scene(dir, R"(, "normal_map": "bumps.ppm")");
  const test::SceneCase c{"normal-maps", 32, 32, 256, 0, 0, 0};
  const test::PixelStatistics f = test::statistics_on<float>(backend, flatten_scene<float>(scene, test::case_settings(scene, c, c.samples, 41)));
  const test::PixelStatistics d = test::statistics_on<double>("cpu", flatten_scene<double>(scene, test::case_settings(scene, c, c.samples, 42)));
  EXPECT_EQ(f.non_finite, 0u);
  EXPECT_EQ(d.non_finite, 0u);
  test::expect_blocks_agree(f, d, "float", "double", "normal-mapped scene (float on " + backend + ")");
}

// Light sampling with MIS against paths that find lights only by scattering: both must see the same directions as
// reflected (below the geometric surface none is) with the same densities, or the images part.
void expect_next_event_matches_naive(const test::TempDir& dir, const std::string& backend, u32 samples) {
  const SceneDescription scene = load_normal_map_scene(dir, R"(, "normal_map": "bumps.ppm", "normal_scale": 1.5)");
  const test::SceneCase c{"normal-maps", 32, 32, samples, 0, 0, 0};
  RenderSettings nee = test::case_settings(scene, c, samples, 51), naive = test::case_settings(scene, c, samples, 52);
  nee.light_sampling = LightSampling::kNextEvent;
  naive.light_sampling = LightSampling::kNone;
  const test::PixelStatistics a = test::statistics_on<float>(backend, flatten_scene<float>(scene, nee));
  const test::PixelStatistics b = test::statistics_on<float>(backend, flatten_scene<float>(scene, naive));
  EXPECT_EQ(a.non_finite, 0u);
  EXPECT_EQ(b.non_finite, 0u);
  test::expect_blocks_agree(a, b, "nee", "naive", "normal-mapped scene (" + backend + ")");
}

TEST(NormalMapRender, NextEventMatchesNaive) {
  test::TempDir dir;
  write_normal_map_files(dir);
  expect_next_event_matches_naive(dir, "cpu", 1024);
}

TEST(NormalMapRender, CudaNextEventMatchesNaiveAtHighSampleCounts) {
#if !PT_HAVE_CUDA
  GTEST_SKIP() << "the CUDA backend is not built (no nvcc)";
#else
  if (cuda_device_count() == 0) GTEST_SKIP() << "no usable GPU on this machine";
  test::TempDir dir;
  write_normal_map_files(dir);
  expect_next_event_matches_naive(dir, "cuda", 16384);
#endif
}

TEST(NormalMapRender, CudaFiniteAndMatchesCpuDouble) {
#if !PT_HAVE_CUDA
  GTEST_SKIP() << "the CUDA backend is not built (no nvcc)";
#else
  if (cuda_device_count() == 0) GTEST_SKIP() << "no usable GPU on this machine";
  test::TempDir dir;
  write_normal_map_files(dir);
  expect_normal_maps_float_matches_double(dir, "cuda");
#endif
}

TEST(NormalMapRender, ChangesThePictureAndFloatMatchesDouble) {
  test::TempDir dir;
  write_normal_map_files(dir);
  const SceneDescription scene = load_normal_map_scene(dir, R"(, "normal_map": "bumps.ppm")");
  const test::SceneCase c{"normal-maps", 32, 32, 256, 0, 0, 0};
  const test::PixelStatistics f = test::statistics_on<float>("cpu", flatten_scene<float>(scene, test::case_settings(scene, c, c.samples, 31)));
  const test::PixelStatistics d = test::statistics_on<double>("cpu", flatten_scene<double>(scene, test::case_settings(scene, c, c.samples, 32)));
  EXPECT_EQ(f.non_finite, 0u);
  EXPECT_EQ(d.non_finite, 0u);
  test::expect_blocks_agree(f, d, "float", "double", "normal-mapped scene");
  // The map is seen: the same scene without it differs beyond the noise somewhere. At the full sample count even
  // under the sanitizers (which cut the samples above), where 16 samples leave the difference near 5 standard errors.
  const SceneDescription plain = load_normal_map_scene(dir, "");
  const u32 full = c.samples * test::kSampleDivisor;
  const test::PixelStatistics m = test::statistics_on<double>("cpu", flatten_scene<double>(scene, test::case_settings(scene, c, full, 32)));
  const test::PixelStatistics p = test::statistics_on<double>("cpu", flatten_scene<double>(plain, test::case_settings(plain, c, full, 33)));
  double largest = 0;
  for (std::size_t i = 0; i < m.values(); ++i) {
    const double error = std::sqrt(m.variance[i] / m.samples + p.variance[i] / p.samples) + 1e-6;
    largest = std::max(largest, std::abs(m.mean[i] - p.mean[i]) / error);
  }
  EXPECT_GT(largest, 8.0);
}

}  // namespace
}  // namespace pt
