// Next-event estimation with multiple importance sampling changes the noise, never the expected value: against
// paths that find lights only by scattering, on every shipped scene and on every kind of light; and the light
// table picks each light by its share of the power.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "kernel/fixed_point.hpp"
#include "scene_cases.hpp"
#include "test_support.hpp"
#if PT_HAVE_CUDA
#include "backends/cuda/cuda_backend.hpp"
#endif

namespace pt {
namespace {

using test::case_settings;
using test::expect_blocks_agree;
using test::load_case_scene;
using test::scene_case;
using test::SceneCase;
using test::statistics_on;

RenderSettings with_light_sampling(RenderSettings settings, LightSampling light_sampling) {
  settings.light_sampling = light_sampling;
  return settings;
}

// Both renders in float on one backend, with independent seeds; `factor` multiplies the samples of the scene's case.
void expect_next_event_matches_naive(const std::string& name, const std::string& backend, u32 factor) {
  const SceneDescription scene = load_case_scene(name);
  const SceneCase& c = scene_case(name);
  const u32 samples = (c.nee_samples ? c.nee_samples : c.samples) * factor;
  const RenderSettings nee = with_light_sampling(case_settings(scene, c, samples, 707), LightSampling::kNextEvent);
  const RenderSettings naive = with_light_sampling(case_settings(scene, c, samples, 808), LightSampling::kNone);
  const test::PixelStatistics a = statistics_on<float>(backend, flatten_scene<float>(scene, nee));
  const test::PixelStatistics b = statistics_on<float>(backend, flatten_scene<float>(scene, naive));
  EXPECT_EQ(a.non_finite, 0u);
  expect_blocks_agree(a, b, "nee", "naive", name + " (" + backend + ")");
}

class NextEventMatchesNaive : public ::testing::TestWithParam<std::string> {};

TEST_P(NextEventMatchesNaive, BlockMeansAgreeWithinNoise) { expect_next_event_matches_naive(GetParam(), "cpu", 1); }

// At 16 times the samples, where a bias of a fraction of a percent would show: on a GPU.
TEST_P(NextEventMatchesNaive, CudaBlockMeansAgreeAtHighSampleCounts) {
#if !PT_HAVE_CUDA
  GTEST_SKIP() << "the CUDA backend is not built (no nvcc)";
#else
  if (cuda_device_count() == 0) GTEST_SKIP() << "no usable GPU on this machine";
  expect_next_event_matches_naive(GetParam(), "cuda", 16);
#endif
}

INSTANTIATE_TEST_SUITE_P(Scenes, NextEventMatchesNaive,
                         ::testing::Values("tiny", "meshes", "seed-default", "book1-final", "book2-final", "cornell-box", "cornell-smoke",
                                           "precision"),
                         test::scene_test_name);

// ---- Every kind of light ----

// A floor lit by one light of each kind the sampler treats apart: a quad, a triangle, a sphere seen from outside
// (sampled by its cone), a moving sphere, an emitting mesh placed twice (once mirrored and stretched: the triangle's
// share and its area in the world differ from the mesh's), fog that shadow rays cross, and around everything an
// emitting sphere seen from inside (sampled by area) that stands for a sky.
SceneDescription every_kind_of_light() {
  SceneDescription scene = test::parse(R"({
    "render": {"width": 48, "height": 32, "samples_per_pixel": 1, "max_depth": 6},
    "camera": {"look_from": [0, 6, 14], "look_at": [0, 1, 0], "vertical_fov": 45},
    "background": {"type": "constant", "color": [0, 0, 0]},
    "materials": {
      "floor": {"type": "lambertian", "albedo": [0.7, 0.6, 0.5]},
      "warm": {"type": "diffuse_light", "emission": [6, 3, 1]},
      "cool": {"type": "diffuse_light", "emission": [1, 3, 6]},
      "dim": {"type": "diffuse_light", "emission": [0.2, 0.2, 0.2]}
    },
    "objects": [
      {"type": "quad", "corner": [-8, 0, -8], "u": [16, 0, 0], "v": [0, 0, 16], "material": "floor"},
      {"type": "sphere", "center": [0, 1, 0], "radius": 1, "material": "floor"},
      {"type": "quad", "corner": [-5, 3, -1], "u": [1, 0, 0], "v": [0, 0, 1.5], "material": "warm"},
      {"type": "triangle", "vertices": [[3, 2.5, -2], [4.5, 2.5, -2], [3, 4, -1]], "material": "cool"},
      {"type": "sphere", "center": [-2, 3.5, 2], "radius": 0.4, "material": "warm"},
      {"type": "moving_sphere", "center0": [2, 2, 2], "center1": [2.5, 2.5, 2], "radius": 0.3, "material": "cool"},
      {"type": "medium", "boundary": {"type": "box", "min": [-6, 0, -4], "max": [-2, 2, 0]}, "density": 0.3,
       "material": {"type": "isotropic", "albedo": [0.8, 0.8, 0.8]}},
      {"type": "sphere", "center": [0, 0, 0], "radius": 40, "material": "dim"}
    ]})");
  test::TestRandom rng(11);
  std::shared_ptr<MeshFile> soup = test::triangle_soup(rng, 40, 0.6);
  soup->materials[0].emission = {2, 5, 2};
  const u32 file = add_mesh_file(scene, soup, "/objects");
  test::place_mesh(scene, file, {0.5, 0.5, 0.5}, {0, 0, 0}, {-1, 4, -3});
  test::place_mesh(scene, file, {-0.4, 0.9, 0.6}, {20, 40, 0}, {3, 4, 1});
  return scene;
}

TEST(EveryKindOfLight, NextEventMatchesNaiveWithinNoise) {
  const SceneDescription scene = every_kind_of_light();
  RenderSettings settings = scene.render;
  settings.samples_per_pixel = 2048 / test::kSampleDivisor;
  const FlatScene<double> nee = flatten_scene<double>(scene, with_light_sampling(settings, LightSampling::kNextEvent));
  // Every emitter is in the table: four shapes, two mesh instances and the enclosing sphere.
  ASSERT_EQ(nee.light_entries.size(), 7u);
  settings.seed = 2;
  const FlatScene<double> naive = flatten_scene<double>(scene, with_light_sampling(settings, LightSampling::kNone));
  const test::PixelStatistics a = test::sample_statistics(nee, settings.samples_per_pixel);
  const test::PixelStatistics b = test::sample_statistics(naive, settings.samples_per_pixel);
  EXPECT_EQ(a.non_finite, 0u);
  expect_blocks_agree(a, b, "nee", "naive", "every kind of light");
}

// The reason for it all: a floor under a small light, lit directly, is nearly free of noise with light sampling and
// speckled without (a scattered ray finds the light one time in 40). 256 samples a pixel give naive paths a few
// hits each, so its variance estimate is trustworthy.
TEST(NextEventEstimation, LeavesLessNoiseUnderASmallLight) {
  const SceneDescription scene = test::parse(R"({
    "render": {"width": 16, "height": 16, "samples_per_pixel": 256, "max_depth": 2},
    "camera": {"look_from": [0, 6, 0.01], "look_at": [0, 0, 0], "vertical_fov": 40},
    "background": {"type": "constant", "color": [0, 0, 0]},
    "objects": [
      {"type": "quad", "corner": [-4, 0, -4], "u": [8, 0, 0], "v": [0, 0, 8], "material": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}},
      {"type": "quad", "corner": [-0.5, 3, -0.5], "u": [1, 0, 0], "v": [0, 0, 1], "material": {"type": "diffuse_light", "emission": [10, 10, 10]}}
    ]})");
  const test::PixelStatistics a =
      test::sample_statistics(flatten_scene<double>(scene, with_light_sampling(scene.render, LightSampling::kNextEvent)), 256);
  const test::PixelStatistics b = test::sample_statistics(flatten_scene<double>(scene, with_light_sampling(scene.render, LightSampling::kNone)), 256);
  // Over the floor's pixels (the light's own, seen directly, and its edges are alike in both).
  double variance_a = 0, variance_b = 0;
  u32 floor_pixels = 0;
  for (std::size_t i = 0; i < a.variance.size(); ++i)
    if (a.mean[i] < 1) {
      variance_a += a.variance[i];
      variance_b += b.variance[i];
      ++floor_pixels;
    }
  EXPECT_GT(floor_pixels, a.variance.size() / 2);
  EXPECT_LT(variance_a, 0.05 * variance_b) << variance_a << " against " << variance_b;
}

// A shadow ray through a constant medium weighs by its exact transmittance instead of being stopped at random: the
// floor under a black (purely absorbing) slab of optical depth about 1 is lit with nearly the relative noise of a
// floor without it. A shadow ray stopped by a free-flight draw would add (1 - T) / T, about 1.7, to the squared
// coefficient of variation of every floor pixel.
TEST(NextEventEstimation, ShadowRaysThroughMediaWeighByTheirTransmittance) {
  auto floor_noise = [](bool slab) {
    std::string objects = R"(
      {"type": "quad", "corner": [-4, 0, -4], "u": [8, 0, 0], "v": [0, 0, 8], "material": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}},
      {"type": "quad", "corner": [-0.5, 3, -0.5], "u": [1, 0, 0], "v": [0, 0, 1], "material": {"type": "diffuse_light", "emission": [10, 10, 10]}})";
    if (slab)
      objects += R"(, {"type": "medium", "boundary": {"type": "box", "min": [-5, 1.5, -5], "max": [5, 2, 5]}, "density": 2,
                      "material": {"type": "isotropic", "albedo": [0, 0, 0]}})";
    const SceneDescription scene = test::parse(R"({
      "render": {"width": 16, "height": 16, "samples_per_pixel": 256, "max_depth": 2, "sampler": "independent"},
      "camera": {"look_from": [0, 0.6, 5], "look_at": [0, 0, 0], "vertical_fov": 30},
      "background": {"type": "constant", "color": [0, 0, 0]},
      "objects": [)" + objects + "]}");
    const test::PixelStatistics stats = test::sample_statistics(flatten_scene<double>(scene, scene.render), 256);
    double cv2 = 0;
    u32 pixels = 0;
    for (std::size_t i = 0; i < stats.values(); ++i)
      if (stats.mean[i] > 0) {
        cv2 += stats.variance[i] / (stats.mean[i] * stats.mean[i]);
        ++pixels;
      }
    EXPECT_GT(pixels, stats.values() / 2);
    return cv2 / pixels;
  };
  const double without = floor_noise(false), with = floor_noise(true);
  EXPECT_LT(with, without + 0.5) << with << " against " << without << " without the slab";
}

// ---- The light table ----

TEST(LightTable, PicksEachLightByItsShareOfPower) {
  // Three quads: areas 1, 2, 4 with emission 4, 1, 1: powers 4 : 2 : 4. The black background is no light.
  const SceneDescription scene = test::parse(R"({
    "camera": {"look_from": [0, 0, 10], "look_at": [0, 0, 0], "vertical_fov": 40},
    "background": {"type": "constant", "color": [0, 0, 0]},
    "objects": [
      {"type": "quad", "corner": [0, 0, 0], "u": [1, 0, 0], "v": [0, 1, 0], "material": {"type": "diffuse_light", "emission": [4, 4, 4]}},
      {"type": "quad", "corner": [2, 0, 0], "u": [2, 0, 0], "v": [0, 1, 0], "material": {"type": "diffuse_light", "emission": [1, 1, 1]}},
      {"type": "quad", "corner": [5, 0, 0], "u": [2, 0, 0], "v": [0, 2, 0], "material": {"type": "diffuse_light", "emission": [1, 1, 1]}},
      {"type": "sphere", "center": [0, -5, 0], "radius": 1, "material": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}}
    ]})");
  const FlatScene<double> flat = flatten_scene<double>(scene, scene.render);
  ASSERT_EQ(flat.light_entries.size(), 3u);
  EXPECT_EQ(flat.background_light, kNoLight);
  std::map<double, double> pmf_by_area;  // area -> pmf
  u32 lights = 0;
  for (u32 p = 0; p < flat.primitives.size(); ++p) {
    const u32 entry = flat.primitive_light[p];
    if (const auto* q = std::get_if<Quad<double>>(&flat.primitives[p].shape)) {
      ASSERT_NE(entry, kNoLight);
      EXPECT_EQ(flat.light_entries[entry].primitive, p);
      pmf_by_area[std::round(quad_area(*q))] = flat.light_entries[entry].pmf;
      ++lights;
    } else {
      EXPECT_EQ(entry, kNoLight);  // the sphere does not emit
    }
  }
  ASSERT_EQ(lights, 3u);
  EXPECT_NEAR(pmf_by_area[1], 0.4, 1e-12);
  EXPECT_NEAR(pmf_by_area[2], 0.2, 1e-12);
  EXPECT_NEAR(pmf_by_area[4], 0.4, 1e-12);
  // The alias table draws each entry with its pmf: a chi-square test over a million draws (2 degrees of freedom;
  // 13.8 is the 0.999 quantile).
  const SceneView<double> view = flat.view();
  std::vector<double> counts(3, 0);
  const u32 draws = 1'000'000;
  for (u32 i = 0; i < draws; ++i) {
    const SampleRandom random = SampleRandom::make(9, i, 0);
    counts[choose_light(view.lights, BounceRandom{&random, 0})] += 1;
  }
  double chi2 = 0;
  for (u32 e = 0; e < 3; ++e) {
    const double expected = draws * flat.light_entries[e].pmf;
    chi2 += (counts[e] - expected) * (counts[e] - expected) / expected;
  }
  EXPECT_LT(chi2, 13.8);
}

TEST(LightTable, BackgroundIsALightWhereItShines) {
  const std::string objects = R"("camera": {"look_from": [0, 0, 10], "look_at": [0, 0, 0], "vertical_fov": 40},
    "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}}])";
  const SceneDescription dark = test::parse(R"({"background": {"type": "constant", "color": [0, 0, 0]}, )" + objects + "}");
  const SceneDescription sky = test::parse(R"({"background": {"type": "sky", "horizon": [1, 1, 1], "zenith": [0.5, 0.7, 1]}, )" + objects + "}");
  EXPECT_TRUE(flatten_scene<float>(dark, with_light_sampling(dark.render, LightSampling::kNextEvent)).light_entries.empty());
  const FlatScene<float> lit = flatten_scene<float>(sky, with_light_sampling(sky.render, LightSampling::kNextEvent));
  ASSERT_EQ(lit.light_entries.size(), 1u);
  EXPECT_EQ(lit.background_light, 0u);
  EXPECT_EQ(lit.light_entries[0].primitive, kNoLight);
  EXPECT_EQ(lit.light_entries[0].pmf, 1.0f);
  EXPECT_EQ(lit.params.next_event, 1u);
}

// The default, auto, leaves a smooth sky to scattering (which samples it about as well as light sampling would,
// with no shadow ray): with no other light the render is the one without light sampling, bit for bit.
TEST(LightTable, AutoLeavesASmoothSkyToScattering) {
  const SceneDescription sky = test::parse(R"({"render": {"width": 12, "height": 8, "samples_per_pixel": 4, "max_depth": 4},
    "background": {"type": "sky", "horizon": [1, 1, 1], "zenith": [0.5, 0.7, 1]},
    "camera": {"look_from": [0, 1, 6], "look_at": [0, 0, 0], "vertical_fov": 40},
    "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}},
                {"type": "sphere", "center": [0, -101, 0], "radius": 100, "material": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}}]})");
  ASSERT_EQ(sky.render.light_sampling, LightSampling::kAuto);
  const FlatScene<float> automatic = flatten_scene<float>(sky, sky.render);
  EXPECT_LT(automatic.background_scattering_variance, 0.05);
  EXPECT_TRUE(automatic.light_entries.empty());
  EXPECT_EQ(automatic.params.next_event, 0u);
  const RenderResult a = test::render(automatic, 2, Integrator::kMegakernel);
  const RenderResult none = test::render(flatten_scene<float>(sky, with_light_sampling(sky.render, LightSampling::kNone)), 2, Integrator::kMegakernel);
  EXPECT_EQ(a.image.rgb, none.image.rgb);
  EXPECT_EQ(a.stats.rays, none.stats.rays);
}

// Where auto differs from both (a sky left to scattering and a small light sampled: tiny, meshes, the seed's
// scene), its expected image is theirs.
TEST(NextEventMatchesNaive, AutoBlockMeansAgreeWithinNoise) {
  for (const std::string name : {"tiny", "meshes", "seed-default"}) {
    const SceneDescription scene = load_case_scene(name);
    const SceneCase& c = scene_case(name);
    const u32 samples = c.nee_samples ? c.nee_samples : c.samples;
    const FlatScene<float> automatic = flatten_scene<float>(scene, with_light_sampling(case_settings(scene, c, samples, 909), LightSampling::kAuto));
    ASSERT_EQ(automatic.light_entries.size(), 1u) << name;  // the small light alone
    EXPECT_EQ(automatic.background_light, kNoLight) << name;
    const test::PixelStatistics a = statistics_on<float>("cpu", automatic);
    const test::PixelStatistics b =
        statistics_on<float>("cpu", flatten_scene<float>(scene, with_light_sampling(case_settings(scene, c, samples, 808), LightSampling::kNone)));
    expect_blocks_agree(a, b, "auto", "naive", name);
  }
}

// ---- Faint shadow rays traced by chance (the light threshold) ----

// A threshold far above the default leaves most shadow rays out and weights the rest up: fewer rays, the same
// expected image. A floor under a small rectangle (sampled by solid angle) and a small, far, bright sphere (by its
// cone; half the floor's light), whose samples could each add less than the threshold nearly everywhere: both stages
// of the roulette, before the sample is drawn and before its shadow ray is traced, take part.
TEST(LightThreshold, LeavesTheExpectedImageAsItIs) {
  const SceneDescription scene = test::parse(R"({
    "render": {"width": 16, "height": 16, "samples_per_pixel": 1024, "max_depth": 3, "light_sampling": "nee"},
    "camera": {"look_from": [0, 6, 0.01], "look_at": [0, 0, 0], "vertical_fov": 40},
    "background": {"type": "constant", "color": [0, 0, 0]},
    "objects": [
      {"type": "quad", "corner": [-4, 0, -4], "u": [8, 0, 0], "v": [0, 0, 8], "material": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}},
      {"type": "quad", "corner": [-0.5, 3, -0.5], "u": [1, 0, 0], "v": [0, 0, 1], "material": {"type": "diffuse_light", "emission": [1, 1, 1]}},
      {"type": "sphere", "center": [3, 1, 3], "radius": 0.1, "material": {"type": "diffuse_light", "emission": [200, 150, 100]}}
    ]})");
  RenderSettings settings = scene.render;
  settings.samples_per_pixel = 1024 / test::kSampleDivisor;
  settings.light_threshold = 0;
  const FlatScene<double> every = flatten_scene<double>(scene, settings);
  settings.light_threshold = kMaxLightThreshold;
  settings.seed = 2;
  const FlatScene<double> some = flatten_scene<double>(scene, settings);
  const test::PixelStatistics a = test::sample_statistics(every, settings.samples_per_pixel);
  const test::PixelStatistics b = test::sample_statistics(some, settings.samples_per_pixel);
  EXPECT_EQ(b.non_finite, 0u);
  expect_blocks_agree(a, b, "every shadow ray", "faint ones by chance", "a floor under two small lights");
  settings.samples_per_pixel = 16;
  const u64 rays_some = test::render(flatten_scene<float>(scene, settings), 2, Integrator::kMegakernel).stats.rays;
  settings.light_threshold = 0;
  const u64 rays_every = test::render(flatten_scene<float>(scene, settings), 2, Integrator::kMegakernel).stats.rays;
  EXPECT_LT(rays_some, rays_every * 8 / 10);
}

// Under the seed scene's small light, far from most of what the camera sees, most shadow rays could add little:
// with the default threshold most of those towards it are left out.
TEST(LightThreshold, LeavesFaintShadowRaysOut) {
  const SceneDescription scene = load_case_scene("seed-default");
  RenderSettings settings = with_light_sampling(scene.render, LightSampling::kAuto);
  settings.width = 100;
  settings.height = 60;
  settings.samples_per_pixel = 8;
  settings.light_threshold = 0;
  const RenderResult every = test::render(flatten_scene<float>(scene, settings), 2, Integrator::kMegakernel);
  settings.light_threshold = RenderSettings{}.light_threshold;
  const RenderResult some = test::render(flatten_scene<float>(scene, settings), 2, Integrator::kMegakernel);
  const double samples = static_cast<double>(every.stats.samples);
  fmt::print("rays a sample: {:.3f} with every shadow ray, {:.3f} with faint ones by chance\n", every.stats.rays / samples, some.stats.rays / samples);
  EXPECT_LT(static_cast<double>(some.stats.rays), 0.9 * static_cast<double>(every.stats.rays));
}

// ---- Rectangles sampled by solid angle ----

// The solid angle of triangle (a, b, c) seen from the origin (Van Oosterom and Strackee): an independent formula.
double triangle_solid_angle(const Vec3<double>& a, const Vec3<double>& b, const Vec3<double>& c) {
  const double la = length(a), lb = length(b), lc = length(c);
  const double numerator = std::abs(dot(a, cross(b, c)));
  const double denominator = la * lb * lc + dot(a, b) * lc + dot(a, c) * lb + dot(b, c) * la;
  return 2 * std::atan2(numerator, denominator);
}

// The solid angle of the part [a0, a1] x [b0, b1] of the quad corner + a u + b v, seen from `from`.
double quad_part_solid_angle(const Vec3<double>& corner, const Vec3<double>& u, const Vec3<double>& v, const Vec3<double>& from, double a0, double a1,
                             double b0, double b1) {
  const Vec3<double> p00 = corner + a0 * u + b0 * v - from, p10 = corner + a1 * u + b0 * v - from;
  const Vec3<double> p11 = corner + a1 * u + b1 * v - from, p01 = corner + a0 * u + b1 * v - from;
  return triangle_solid_angle(p00, p10, p11) + triangle_solid_angle(p00, p11, p01);
}

// Directions towards a rectangular light are spread uniformly over the solid angle it fills: from points close to
// it, far from it, beside it at a grazing height and behind it, the light's solid angle matches an independent
// formula; the sampled directions, binned by where they meet the light (8 x 8 cells), follow each cell's share of
// the solid angle (chi-square, 63 degrees of freedom: 115 is beyond the 0.9999 quantile); each direction's distance
// is where it meets the light, and light_pdf gives the density 1 / solid angle. A parallelogram that is not a
// rectangle, and a light too small to be worth it, are sampled by area.
TEST(RectangleLight, DirectionsAreUniformOverItsSolidAngle) {
  const Vec3<double> corner{-1, 2, -0.5}, u{2, 0, 1}, v{-0.5, 0, 1};  // u.v = 0: a rectangle
  const SceneDescription scene = test::parse(R"({
    "camera": {"look_from": [0, 0, 10], "look_at": [0, 0, 0], "vertical_fov": 40},
    "background": {"type": "constant", "color": [0, 0, 0]},
    "objects": [
      {"type": "quad", "corner": [-1, 2, -0.5], "u": [2, 0, 1], "v": [-0.5, 0, 1], "material": {"type": "diffuse_light", "emission": [1, 1, 1]}},
      {"type": "quad", "corner": [3, 2, 0], "u": [1, 0, 0], "v": [0.5, 0, 1], "material": {"type": "diffuse_light", "emission": [1, 1, 1]}}
    ]})");
  const FlatScene<double> flat = flatten_scene<double>(scene, scene.render);
  const SceneView<double> view = flat.view();
  const u32 entry = flat.primitive_light[0];
  const Quad<double>& quad = std::get<Quad<double>>(flat.primitives[0].shape);
  const double pmf = flat.light_entries[entry].pmf;
  const std::vector<Vec3<double>> points{{0.1, 1.7, 0.2}, {0.4, -6, 1}, {4, 1.9, 3}, {-0.2, 2.6, 0.1}};
  for (const Vec3<double>& from : points) {
    SCOPED_TRACE(testing::Message() << "from " << from.x << " " << from.y << " " << from.z);
    SphericalRectangle<double> rectangle;
    ASSERT_TRUE(spherical_rectangle(rectangle_frame(quad), quad.corner, from, rectangle));
    const double solid_angle = quad_part_solid_angle(corner, u, v, from, 0, 1, 0, 1);
    EXPECT_NEAR(rectangle.solid_angle, solid_angle, 1e-12 * solid_angle + 1e-15);
    constexpr int kCells = 8;
    std::vector<double> counts(kCells * kCells, 0);
    const u32 draws = 400'000;
    for (u32 i = 0; i < draws; ++i) {
      const SampleRandom random = SampleRandom::make(5, i, 0);
      LightSample<double> light;
      ASSERT_TRUE(sample_light(view, entry, from, 0.0, BounceRandom{&random, 0}, light));
      const Ray<double> ray{from, light.direction, 0};
      Hit<double> hit{};
      ASSERT_TRUE(intersect_quad(quad, ray, 0.0, 1e30, hit)) << "sample " << i;
      ASSERT_NEAR(light.distance, hit.t, 1e-9 * hit.t);
      if (i < 100) {
        EXPECT_NEAR(light_pdf(view, entry, ray, hit, SurfacePoint<double>{}), pmf / rectangle.solid_angle, 1e-12 / rectangle.solid_angle);
      }
      const int a = std::min(kCells - 1, static_cast<int>(hit.b1 * kCells)), b = std::min(kCells - 1, static_cast<int>(hit.b2 * kCells));
      counts[a * kCells + b] += 1;
    }
    double chi2 = 0;
    for (int a = 0; a < kCells; ++a) {
      for (int b = 0; b < kCells; ++b) {
        const double share =
            quad_part_solid_angle(corner, u, v, from, double(a) / kCells, double(a + 1) / kCells, double(b) / kCells, double(b + 1) / kCells) /
            solid_angle;
        const double expected = draws * share;
        chi2 += (counts[a * kCells + b] - expected) * (counts[a * kCells + b] - expected) / expected;
      }
    }
    EXPECT_LT(chi2, 115);
  }
  SphericalRectangle<double> rectangle;
  EXPECT_FALSE(spherical_rectangle(rectangle_frame(quad), quad.corner, Vec3<double>{0, 400, 0}, rectangle));  // 1e-5 sr: by area
  const Quad<double>& parallelogram = std::get<Quad<double>>(flat.primitives[1].shape);
  EXPECT_EQ(rectangle_frame(parallelogram).lu, 0.0);
  EXPECT_EQ(flat.light_rectangles[flat.primitive_light[1]].lu, 0.0);
  EXPECT_EQ(flat.light_rectangles[entry].lu, rectangle_frame(quad).lu);  // made by flattening, one per light
  EXPECT_FALSE(spherical_rectangle(rectangle_frame(parallelogram), parallelogram.corner, Vec3<double>{3, 1, 0}, rectangle));  // not a rectangle
}

// Every light sample of a rectangle that nothing blocks reaches it, however grazing the angle: from points at the
// tops of the Cornell box's walls, a hand's breadth below the light's plane, the shadow ray of every sample carries
// the light's emission. In fixed point, rays aimed near an edge at such angles cross the light's plane just beyond
// it, and before they counted as blocked (in Q16.16 several percent of them): a dark seam along the walls' tops.
template <class T>
void expect_every_unblocked_light_sample_reaches_the_light() {
  const SceneDescription scene = test::parse(R"({
    "camera": {"look_from": [278, 278, -800], "look_at": [278, 278, 0], "vertical_fov": 40},
    "background": {"type": "constant", "color": [0, 0, 0]},
    "objects": [{"type": "quad", "corner": [343, 554, 332], "u": [-130, 0, 0], "v": [0, 0, -105],
                 "material": {"type": "diffuse_light", "emission": [15, 15, 15]}}]})");
  const FlatScene<T> flat = flatten_scene<T>(scene, scene.render);
  const SceneView<T> view = flat.view();
  const u32 entry = flat.primitive_light[0];
  const std::vector<Vec3<double>> points{{554.5, 540, 278}, {554.5, 548, 120}, {554.5, 551, 450}, {0.5, 545, 300},
                                         {0.5, 552, 200},   {278, 549, 554.5}, {100, 546, 554.5}, {450, 552, 554.5}};
  constexpr u32 kSamples = 4000;
  for (const Vec3<double>& p : points) {
    SCOPED_TRACE(testing::Message() << "from " << p.x << " " << p.y << " " << p.z);
    const Vec3<T> from{T(p.x), T(p.y), T(p.z)};
    u32 sampled = 0, dark = 0;
    for (u32 i = 0; i < kSamples; ++i) {
      const SampleRandom random = SampleRandom::make(11, i, 0);
      LightSample<T> light;
      if (!sample_light(view, entry, from, T(0), BounceRandom{&random, 0}, light)) continue;
      ++sampled;
      const ShadowRay<T> shadow = shadow_ray_to(light, Ray<T>{from, light.direction, T(0)}, Color<T>::splat(T(1)), T(1));
      const Color<T> c = shadow_contribution(view, shadow, random);
      if (!(static_cast<double>(c.x) > 0)) ++dark;
    }
    EXPECT_EQ(sampled, kSamples);
    EXPECT_EQ(dark, 0u) << "of " << sampled << " samples";
  }
}

TEST(RectangleLight, UnblockedSamplesReachItAtGrazingAnglesInEveryFormat) {
  expect_every_unblocked_light_sample_reaches_the_light<double>();
  expect_every_unblocked_light_sample_reaches_the_light<float>();
  expect_every_unblocked_light_sample_reaches_the_light<Fixed<16, 16>>();
  expect_every_unblocked_light_sample_reaches_the_light<Fixed<12, 12>>();
}

// ---- Shadow rays stop at the first hit that blocks them ----

// Counts the box tests of a walk of the scene's binary tree.
struct BoxTestCounter {
  u64* count;
  template <class T>
  void box_test(const BvhNode<T>&, const BoxRay<T>&, T, T) const {
    ++*count;
  }
  bool keep_walking() const { return true; }
};

// A wall written before a rectangle light, a 2500th of the way behind it as seen from below, shares its leaf: every
// light sample from below reaches the light. A walk that stopped at any hit before the shadow ray's end (which lies
// a 1024th of the way beyond the light's point) would stop at the wall, met first in the leaf.
template <class T>
void expect_a_surface_just_behind_the_light_blocks_nothing() {
  const SceneDescription scene = test::parse(R"({
    "camera": {"look_from": [0, 1, -5], "look_at": [0, 1, 0], "vertical_fov": 40},
    "background": {"type": "constant", "color": [0, 0, 0]},
    "objects": [{"type": "quad", "corner": [-2, 10.004, -2], "u": [4, 0, 0], "v": [0, 0, 4], "material": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}},
                {"type": "quad", "corner": [-1, 10, -1], "u": [2, 0, 0], "v": [0, 0, 2], "material": {"type": "diffuse_light", "emission": [4, 4, 4]}}]})");
  const FlatScene<T> flat = flatten_scene<T>(scene, scene.render);
  ASSERT_EQ(flat.nodes.size(), 1u);             // one leaf holds both,
  ASSERT_EQ(flat.primitive_light[0], kNoLight);  // the wall first
  const SceneView<T> view = flat.view();
  const u32 entry = flat.primitive_light[1];
  u32 dark = 0;
  for (u32 i = 0; i < 2000; ++i) {
    const SampleRandom random = SampleRandom::make(5, i, 0);
    const Vec3<T> from{T(0.3 * std::sin(i * 0.7)), T(0), T(0.3 * std::cos(i * 1.3))};
    LightSample<T> light;
    ASSERT_TRUE(sample_light(view, entry, from, T(0), BounceRandom{&random, 0}, light));
    const ShadowRay<T> shadow = shadow_ray_to(light, Ray<T>{from, light.direction, T(0)}, Color<T>::splat(T(1)), T(1));
    if (!(static_cast<double>(shadow_contribution(view, shadow, random).x) > 0)) ++dark;
  }
  EXPECT_EQ(dark, 0u);
}

// Light through a grid of small spheres over a floor: each shadow ray is blocked or not exactly as the closest-hit
// search says (the closest hit is the light, or nothing and the light reached), and the walks that stop at their
// first blocker test fewer boxes.
template <class T>
void expect_shadow_rays_blocked_as_the_closest_hit_says() {
  std::string objects = R"({"type": "sphere", "center": [0, 8, 0], "radius": 1, "material": {"type": "diffuse_light", "emission": [4, 4, 4]}})";
  for (int layer = 0; layer < 6; ++layer)
    for (int x = -4; x <= 4; ++x)
      for (int z = -4; z <= 4; ++z)
        objects += fmt::format(R"(, {{"type": "sphere", "center": [{}, {}, {}], "radius": 0.3, "material": {{"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}}}})",
                               x + 0.37 * layer, 1 + layer, z - 0.21 * layer);
  const SceneDescription scene = test::parse(R"({"camera": {"look_from": [0, 3, -20], "look_at": [0, 3, 0], "vertical_fov": 40},
    "background": {"type": "constant", "color": [0, 0, 0]}, "objects": [)" + objects + "]}");
  const FlatScene<T> flat = flatten_scene<T>(scene, scene.render);
  const SceneView<T> view = flat.view();
  u32 light_primitive = 0;
  while (flat.primitive_light[light_primitive] == kNoLight) ++light_primitive;
  const u32 entry = flat.primitive_light[light_primitive];
  u32 blocked = 0, reached = 0;
  u64 first_blocker_tests = 0, closest_hit_tests = 0;
  for (u32 i = 0; i < 3000; ++i) {
    const SampleRandom random = SampleRandom::make(9, i, 0);
    const Vec3<T> from{T(4.5 * std::sin(i * 0.37)), T(0), T(4.5 * std::cos(i * 0.53))};
    LightSample<T> light;
    if (!sample_light(view, entry, from, T(0), BounceRandom{&random, 0}, light)) continue;
    const ShadowRay<T> shadow = shadow_ray_to(light, Ray<T>{from, light.direction, T(0)}, Color<T>::splat(T(1)), T(1));
    Hit<T> hit{};
    T depth = T(0);
    const bool found = closest_hit_binary(view, shadow.ray, IntersectContext<T>{view.boundaries, &random, 0, &depth}, hit, shadow.distance,
                                          BoxTestCounter{&closest_hit_tests});
    const bool seen = found && hit.primitive == light_primitive;
    EXPECT_EQ(static_cast<double>(shadow_contribution(view, shadow, random).x) > 0, seen) << "sample " << i;
    (seen ? reached : blocked) += 1;
    IntersectContext<T> first_blocker{view.boundaries, &random, 0, &depth};
    first_blocker.blocked_before = shadow.distance - shadow.distance * T(1.0 / 512);
    first_blocker.light_primitive = light_primitive;
    Hit<T> any{};
    EXPECT_EQ(closest_hit_binary(view, shadow.ray, first_blocker, any, shadow.distance, BoxTestCounter{&first_blocker_tests}), found);
  }
  EXPECT_GT(blocked, 300u);
  EXPECT_GT(reached, 300u);
  EXPECT_LT(static_cast<double>(first_blocker_tests), 0.9 * static_cast<double>(closest_hit_tests));
}

TEST(ShadowRay, StopsAtItsFirstBlockerWithTheClosestHitsAnswer) {
  expect_a_surface_just_behind_the_light_blocks_nothing<float>();
  expect_a_surface_just_behind_the_light_blocks_nothing<double>();
  expect_shadow_rays_blocked_as_the_closest_hit_says<float>();
  expect_shadow_rays_blocked_as_the_closest_hit_says<double>();
}

// ---- The integrators agree bitwise, with light sampling and without ----

// Renders the scene with both integrators (float, 4 samples) and returns the megakernel's ray count.
u64 expect_integrators_bitwise_equal(const SceneDescription& scene, LightSampling light_sampling) {
  RenderSettings settings = with_light_sampling(scene.render, light_sampling);
  settings.samples_per_pixel = 4;
  const FlatScene<float> flat = flatten_scene<float>(scene, settings);
  const RenderResult mega = test::render(flat, 2, Integrator::kMegakernel);
  const RenderResult wave = test::render(flat, 2, Integrator::kWavefront);
  EXPECT_EQ(mega.image.rgb, wave.image.rgb);
  EXPECT_EQ(mega.stats.rays, wave.stats.rays);
  return mega.stats.rays;
}

TEST(EveryKindOfLight, WavefrontEqualsMegakernelBitwise) {
  const SceneDescription scene = every_kind_of_light();
  const u64 without = expect_integrators_bitwise_equal(scene, LightSampling::kNone);
  const u64 with = expect_integrators_bitwise_equal(scene, LightSampling::kNextEvent);
  EXPECT_GT(with, without);  // shadow rays are counted
}

// A small sphere light seen from afar: its density per unit solid angle (160 to 16 000 here) is beyond Q8.24's range
// (128), where it was clamped and its light samples counted up to 120 times too much. Carried as its reciprocal
// (kReciprocalLightDensity), both strategies' weights are double's to within the format's rounding.
TEST(LightDensityInFixedPoint, DensitiesBeyondTheRangeAreCarriedAsReciprocalsInQ8_24) {
  using Q = Fixed<8, 24>;
  static_assert(ScalarTraits<Q>::kReciprocalLightDensity && !ScalarTraits<Fixed<16, 16>>::kReciprocalLightDensity);
  for (const double width : {1e-3, 5.3e-5, 1e-5})
    for (const double scatter : {0.05, 0.3, 2.0}) {
      const Q carried = cone_density(Q(1), Q(width));
      const double density = 1 / (2 * 3.14159265358979323846 * static_cast<double>(Q(width)));
      // The product 2 pi width rounds by half a step of 2^-24, 0.1 % of the smallest width.
      const double light = 1 / (density + scatter * scatter / density);
      EXPECT_NEAR(static_cast<double>(light_sample_weight(carried, Q(scatter))), light, 3e-3 * light + 0x1p-22)
          << "width " << width << " scatter " << scatter;
      const double scattered = scatter * scatter / (scatter * scatter + density * density);
      EXPECT_NEAR(static_cast<double>(scattered_light_weight(Q(scatter), carried)), scattered, 3e-3 * scattered + 0x1p-22)
          << "width " << width << " scatter " << scatter;
    }
  // No density (a light sampling cannot give): the scattered direction takes the whole weight.
  EXPECT_EQ(static_cast<double>(scattered_light_weight(Q(0.3), Q(0))), 1.0);
}

// The solid angle below which a rectangle is sampled by area is 3e-4 sr plus 1024 rounding units; Q8.24 cannot hold
// 1024 (its largest value is 128), which saturated (and was counted) on every light sample of the Cornell scenes.
TEST(LightDensityInFixedPoint, TheSmallestSampledSolidAngleFitsQ8_24) {
  using Q = Fixed<8, 24>;
  const u64 saturations_before = fixed_saturations_this_thread();
  const Q smallest = smallest_sampled_solid_angle<Q>();
  EXPECT_EQ(fixed_saturations_this_thread(), saturations_before);
  EXPECT_NEAR(static_cast<double>(smallest), 3e-4 + 1024 * 0x1p-24, 0x1p-24);
}

}  // namespace
}  // namespace pt
