// Checks white-furnace invariance (albedo-1 objects vanish under a uniform sky) and cases with exactly known radiance.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "test_support.hpp"

namespace pt {
namespace {

std::string scene_json(const std::string& render, const std::string& camera, const std::string& background, const std::string& objects) {
  return R"({"render": )" + render + R"(, "camera": )" + camera + R"(, "background": )" + background + R"(, "objects": [)" + objects + "]}";
}

const std::string kFrontCamera = R"({"look_from": [0, 0, 4], "look_at": [0, 0, 0], "vertical_fov": 40})";
const std::string kWhiteSky = R"({"type": "constant", "color": [1, 1, 1]})";

// Light sampling "none" by default: with only scattering, every sample of a white furnace is exactly 1, which the
// exact tests below rely on; next-event estimation keeps the mean but not each sample (tested apart).
std::string furnace_render(int max_depth, int roulette_depth = 0, int spp = 8, const std::string& light_sampling = "none") {
  return R"({"width": 32, "height": 24, "samples_per_pixel": )" + std::to_string(spp) + R"(, "max_depth": )" + std::to_string(max_depth) +
         R"(, "russian_roulette_depth": )" + std::to_string(roulette_depth) + R"(, "light_sampling": ")" + light_sampling + R"("})";
}

// The image mean of every channel and the mean of each quarter of the image (about 6000 samples each: enough for a
// trustworthy variance estimate, which a single pixel of mostly equal samples is not) are within a few standard
// errors of 1.
void expect_mean_one(const test::PixelStatistics& stats) {
  for (int k = 0; k < 3; ++k) {
    const double se = stats.image_mean_standard_error(k);
    EXPECT_NEAR(stats.image_mean(k), 1.0, 4 * se + 1e-6) << "channel " << k;
  }
  for (u32 qy = 0; qy < 2; ++qy)
    for (u32 qx = 0; qx < 2; ++qx) {
      const u32 w = stats.width / 2, h = stats.height / 2;
      double mean = 0, variance = 0;
      for (u32 y = qy * h; y < (qy + 1) * h; ++y)
        for (u32 x = qx * w; x < (qx + 1) * w; ++x) {
          const std::size_t i = 3 * (static_cast<std::size_t>(y) * stats.width + x);
          mean += stats.mean[i] / (w * h);
          variance += stats.variance[i] / stats.samples / (static_cast<double>(w) * h * w * h);
        }
      EXPECT_NEAR(mean, 1.0, 5 * std::sqrt(variance) + 1e-6) << "quarter " << qx << "," << qy;
    }
}

// Largest |pixel - 1| over all channels.
double largest_deviation_from_one(const LinearImage& image) {
  double worst = 0;
  for (float v : image.rgb) worst = std::max(worst, std::abs(static_cast<double>(v) - 1.0));
  return worst;
}

struct FurnaceCase {
  const char* name;
  const char* objects;
};

// How gtest names a case in messages and in CTest's test list.
void PrintTo(const FurnaceCase& c, std::ostream* out) { *out << c.name; }

const FurnaceCase kFurnaceCases[] = {
    {"LambertianSphere", R"({"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": {"type": "lambertian", "albedo": [1, 1, 1]}})"},
    {"LambertianOpenBox",
     // Five faces of a box open towards the camera, with a sphere inside: light bounces many times before escaping.
     R"({"type": "quad", "corner": [-1, -1, -1], "u": [2, 0, 0], "v": [0, 2, 0], "material": "white"},
        {"type": "quad", "corner": [-1, -1, -1], "u": [0, 0, 2], "v": [0, 2, 0], "material": "white"},
        {"type": "quad", "corner": [1, -1, -1], "u": [0, 0, 2], "v": [0, 2, 0], "material": "white"},
        {"type": "quad", "corner": [-1, -1, -1], "u": [2, 0, 0], "v": [0, 0, 2], "material": "white"},
        {"type": "quad", "corner": [-1, 1, -1], "u": [2, 0, 0], "v": [0, 0, 2], "material": "white"},
        {"type": "sphere", "center": [0, -0.5, 0], "radius": 0.4, "material": "white"})"},
    {"IsotropicMedium",
     R"({"type": "medium", "boundary": {"type": "sphere", "center": [0, 0, 0], "radius": 1}, "density": 3, "material": {"type": "isotropic", "albedo": [1, 1, 1]}})"},
    {"DielectricSphere",
     R"({"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": {"type": "dielectric", "ior": 1.5, "tint": [1, 1, 1]}})"},
    {"MirrorSphere", R"({"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": {"type": "metal", "albedo": [1, 1, 1], "fuzz": 0}})"},
    {"FogGlassAndDiffuseBox",
     R"({"type": "medium", "boundary": {"type": "box", "min": [-1.5, -1, -1], "max": [0, 1, 1]}, "density": 1, "material": {"type": "isotropic", "albedo": [1, 1, 1]}},
        {"type": "sphere", "center": [0.8, 0, 0], "radius": 0.7, "material": {"type": "dielectric", "ior": 1.33}},
        {"type": "box", "min": [-0.5, -1.2, -0.5], "max": [1.5, -1, 0.5], "material": "white"})"},
};

class WhiteFurnace : public ::testing::TestWithParam<FurnaceCase> {};

std::string with_white_material(const std::string& json) {
  // Inserts the shared albedo-1 material before the objects.
  const std::string marker = R"("objects": [)";
  std::string out = json;
  out.insert(out.find(marker), R"("materials": {"white": {"type": "lambertian", "albedo": [1, 1, 1]}}, )");
  return out;
}

TEST_P(WhiteFurnace, AlbedoOneObjectVanishesInFloat) {
  // Every path carries throughput 1 and escapes to a sky of radiance 1: each sample is exactly 1.
  const FurnaceCase& c = GetParam();
  const SceneDescription scene = test::parse(with_white_material(scene_json(furnace_render(200), kFrontCamera, kWhiteSky, c.objects)));
  const RenderResult result = test::render(test::flatten<float>(scene), 2);
  EXPECT_EQ(result.stats.dropped_samples, 0u);
  EXPECT_LT(largest_deviation_from_one(result.image), 1e-5);
}

TEST_P(WhiteFurnace, AlbedoOneObjectVanishesInDouble) {
  const FurnaceCase& c = GetParam();
  const SceneDescription scene = test::parse(with_white_material(scene_json(furnace_render(200), kFrontCamera, kWhiteSky, c.objects)));
  const RenderResult result = test::render(test::flatten<double>(scene), 2);
  EXPECT_LT(largest_deviation_from_one(result.image), 1e-12);
}

TEST_P(WhiteFurnace, ObjectIsInView) {
  // Guards the two tests above: with max_depth 1 nothing escapes after a scattering, so the object shows dark, and
  // it must cover a good part of the image.
  const SceneDescription scene = test::parse(with_white_material(scene_json(furnace_render(1), kFrontCamera, kWhiteSky, GetParam().objects)));
  const LinearImage image = test::render(test::flatten<float>(scene), 2).image;
  int dark = 0;
  for (std::size_t i = 0; i < image.rgb.size(); i += 3) dark += image.rgb[i] < 0.99f;
  EXPECT_GT(dark, static_cast<int>(image.rgb.size() / 3 / 10));
}

TEST_P(WhiteFurnace, RussianRouletteKeepsTheMeanAtOne) {
  // With roulette from the first bounce, samples are 0 or 1 / q^k: noisy, but the mean must stay 1.
  const FurnaceCase& c = GetParam();
  const SceneDescription scene = test::parse(with_white_material(scene_json(furnace_render(200, 1, 32), kFrontCamera, kWhiteSky, c.objects)));
  const test::PixelStatistics stats = test::sample_statistics(test::flatten<float>(scene), 32);
  ASSERT_EQ(stats.non_finite, 0u);
  for (int k = 0; k < 3; ++k) EXPECT_GT(stats.image_mean_standard_error(k), 0.0);  // roulette must actually have fired
  expect_mean_one(stats);
}

TEST_P(WhiteFurnace, NextEventEstimationKeepsTheMeanAtOne) {
  // The sky is a light: shadow rays towards it and scattered rays that reach it share each path's light by multiple
  // importance sampling. Samples are no longer exactly 1, but nothing may be counted twice or lost.
  const FurnaceCase& c = GetParam();
  const SceneDescription scene = test::parse(with_white_material(scene_json(furnace_render(200, 0, 32, "nee"), kFrontCamera, kWhiteSky, c.objects)));
  const test::PixelStatistics stats = test::sample_statistics(test::flatten<double>(scene), 32);
  ASSERT_EQ(stats.non_finite, 0u);
  expect_mean_one(stats);
}

INSTANTIATE_TEST_SUITE_P(Objects, WhiteFurnace, ::testing::ValuesIn(kFurnaceCases),
                         [](const ::testing::TestParamInfo<FurnaceCase>& info) { return std::string(info.param.name); });

// ---- analytic cases ----

TEST(AnalyticRadiance, ConvexLambertianUnderConstantSkyIsAlbedoTimesSky) {
  // One bounce off a convex object, then the ray escapes: exactly albedo * L. With max_depth 1 the path ends
  // at the object, which emits nothing: exactly 0.
  const std::string sphere = R"({"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": {"type": "lambertian", "albedo": [0.3, 0.5, 0.7]}})";
  const std::string sky = R"({"type": "constant", "color": [2, 1, 0.5]})";
  const std::string camera = R"({"look_from": [0, 0, 5], "look_at": [0, 0, 0], "vertical_fov": 30})";
  const double albedo[3] = {0.3, 0.5, 0.7}, radiance[3] = {2, 1, 0.5};
  // Without light sampling, so that every sample is exactly that.
  for (int depth : {2, 3, 50}) {
    const SceneDescription scene = test::parse(
        scene_json(R"({"width": 32, "height": 32, "samples_per_pixel": 4, "light_sampling": "none", "max_depth": )" + std::to_string(depth) + "}",
                   camera, sky, sphere));
    const LinearImage image = test::render(test::flatten<float>(scene), 2).image;
    // The central 8x8 pixels see only the sphere (it spans about +-11.5 degrees of the 30-degree view).
    for (u32 y = 12; y < 20; ++y)
      for (u32 x = 12; x < 20; ++x)
        for (int k = 0; k < 3; ++k) EXPECT_NEAR(image.rgb[3 * (y * 32 + x) + k], albedo[k] * radiance[k], 1e-6) << x << "," << y;
    // The corners see only the sky.
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(image.rgb[k], radiance[k], 1e-6);
  }
  const SceneDescription one = test::parse(scene_json(R"({"width": 32, "height": 32, "samples_per_pixel": 4, "max_depth": 1})", camera, sky, sphere));
  const LinearImage black = test::render(test::flatten<float>(one), 2).image;
  EXPECT_EQ(black.rgb[3 * (16 * 32 + 16)], 0.0f);
}

TEST(AnalyticRadiance, LambertianFloorUnderSkyGradientIsCosineWeightedSkyMean) {
  // The sky is linear in direction.y, so a lambertian floor (normal +y) with cosine-weighted scattering reflects
  // albedo * lerp(horizon, zenith, 0.5 * (1 + E[cos])) with E[cos] = 2/3, i.e. the sky at 5/6. (Uniform
  // hemisphere sampling would give 3/4: many standard errors away.)
  const std::string render = R"({"width": 24, "height": 24, "samples_per_pixel": 64, "max_depth": 2})";
  const std::string camera = R"({"look_from": [0, 5, 0], "look_at": [0, 0, 0], "up": [0, 0, -1], "vertical_fov": 60})";
  const std::string sky = R"({"type": "sky", "horizon": [1, 0.8, 0.6], "zenith": [0.2, 0.4, 1.0]})";
  const std::string floor =
      R"({"type": "quad", "corner": [-1000, 0, -1000], "u": [2000, 0, 0], "v": [0, 0, 2000], "material": {"type": "lambertian", "albedo": [0.9, 0.6, 0.3]}})";
  const test::PixelStatistics stats = test::sample_statistics(test::flatten<double>(test::parse(scene_json(render, camera, sky, floor))), 64);
  const double horizon[3] = {1, 0.8, 0.6}, zenith[3] = {0.2, 0.4, 1.0}, albedo[3] = {0.9, 0.6, 0.3};
  for (int k = 0; k < 3; ++k) {
    const double expected = albedo[k] * (horizon[k] + (zenith[k] - horizon[k]) * 5.0 / 6.0);
    const double uniform_hemisphere = albedo[k] * (horizon[k] + (zenith[k] - horizon[k]) * 3.0 / 4.0);
    const double se = stats.image_mean_standard_error(k);
    ASSERT_LT(6 * se, std::abs(expected - uniform_hemisphere));  // the test can tell the two apart
    EXPECT_NEAR(stats.image_mean(k), expected, 4 * se) << "channel " << k;
  }
}

TEST(AnalyticRadiance, EmissionIsWeightedByThePathThroughput) {
  // A mirror of albedo a reflects a large light of emission E: every sample is exactly a * E.
  const std::string render = R"({"width": 16, "height": 16, "samples_per_pixel": 4, "max_depth": 4})";
  const std::string camera = R"({"look_from": [0, 0, 0], "look_at": [0, 0, -1], "vertical_fov": 10})";
  const std::string black = R"({"type": "constant", "color": [0, 0, 0]})";
  const std::string objects =
      R"({"type": "quad", "corner": [-10, -10, -2], "u": [20, 0, 0], "v": [0, 20, 0], "material": {"type": "metal", "albedo": [0.5, 0.25, 0.8]}},
         {"type": "quad", "corner": [-50, -50, 1], "u": [100, 0, 0], "v": [0, 100, 0], "material": {"type": "diffuse_light", "emission": [2, 4, 1]}})";
  const LinearImage image = test::render(test::flatten<float>(test::parse(scene_json(render, camera, black, objects))), 2).image;
  const double expected[3] = {1.0, 1.0, 0.8};
  for (std::size_t i = 0; i < image.rgb.size(); ++i) EXPECT_NEAR(image.rgb[i], expected[i % 3], 1e-6) << "value " << i;
}

TEST(AnalyticRadiance, LightSeenDirectlyGivesItsEmission) {
  const std::string camera = R"({"look_from": [0, 0, 5], "look_at": [0, 0, 0], "vertical_fov": 40})";
  const std::string black = R"({"type": "constant", "color": [0, 0, 0]})";
  const std::string light = R"({"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": {"type": "diffuse_light", "emission": [4, 2, 1]}})";
  for (int depth : {1, 10}) {
    const std::string render = R"({"width": 9, "height": 9, "samples_per_pixel": 4, "max_depth": )" + std::to_string(depth) + "}";
    const LinearImage image = test::render(test::flatten<float>(test::parse(scene_json(render, camera, black, light))), 1).image;
    const std::size_t centre = 3 * (4 * 9 + 4);
    EXPECT_EQ(image.rgb[centre + 0], 4.0f);
    EXPECT_EQ(image.rgb[centre + 1], 2.0f);
    EXPECT_EQ(image.rgb[centre + 2], 1.0f);
    EXPECT_EQ(image.rgb[0], 0.0f);  // the corner sees the black background
  }
}

// The sky formula of docs/scene-format.md: lerp(horizon, zenith, 0.5 * (direction.y + 1)).
double sky(double horizon, double zenith, double direction_y) { return horizon + (zenith - horizon) * 0.5 * (direction_y + 1); }

TEST(AnalyticRadiance, BackgroundSeenThroughPinholeMatchesSkyFormulaPerPixel) {
  // Direction through each pixel centre from the camera definition (look_from, look_at, up, vertical_fov; rows from
  // the top); the pixel mean over jittered rays matches the sky there up to second order in the pixel size.
  const double elevation = 20 * test::kPi / 180, fov = 50;
  const Vec3d look_at{0, std::sin(elevation), -std::cos(elevation)};
  const u32 width = 33, height = 25;
  const std::string render = R"({"width": 33, "height": 25, "samples_per_pixel": 64, "max_depth": 4})";
  const std::string camera =
      R"({"look_from": [0, 0, 0], "look_at": [0, )" + std::to_string(look_at.y) + ", " + std::to_string(look_at.z) + R"(], "vertical_fov": 50})";
  const std::string sky_json = R"({"type": "sky", "horizon": [1, 0.9, 0.8], "zenith": [0.1, 0.3, 0.9]})";
  const std::string behind =
      R"({"type": "sphere", "center": [0, 0, 50], "radius": 1, "material": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}})";
  const SceneDescription scene = test::parse(scene_json(render, camera, sky_json, behind));
  const test::PixelStatistics stats = test::sample_statistics(test::flatten<double>(scene), 64);
  const Vec3d w = normalize(Vec3d{0, 0, 0} - normalize(look_at)), u = normalize(cross(Vec3d{0, 1, 0}, w)), v = cross(w, u);
  const double half_height = std::tan(fov * test::kPi / 360), half_width = half_height * width / height;
  const double horizon[3] = {1, 0.9, 0.8}, zenith[3] = {0.1, 0.3, 0.9};
  int failures = 0;
  for (u32 y = 0; y < height; ++y)
    for (u32 x = 0; x < width; ++x) {
      const double s = (x + 0.5) / width * 2 - 1, t = 1 - (y + 0.5) / height * 2;
      const Vec3d direction = normalize(-w + s * half_width * u + t * half_height * v);
      for (int k = 0; k < 3; ++k) {
        const std::size_t i = 3 * (y * width + x) + k;
        // 6 standard errors: 2475 values with variances estimated from 64 samples each; the slack covers the
        // second-order difference between the pixel mean and the value at its centre (about 5e-5 here).
        if (std::abs(stats.mean[i] - sky(horizon[k], zenith[k], direction.y)) > 6 * stats.standard_error(i) + 2e-4) ++failures;
      }
    }
  EXPECT_EQ(failures, 0);
}

TEST(AnalyticRadiance, CentrePixelsLookingAtHorizonAndZenith) {
  const std::string sky_json = R"({"type": "sky", "horizon": [1, 0.9, 0.8], "zenith": [0.1, 0.3, 0.9]})";
  const std::string behind =
      R"({"type": "sphere", "center": [0, -50, 50], "radius": 1, "material": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}})";
  const std::string render = R"({"width": 9, "height": 9, "samples_per_pixel": 256, "max_depth": 4})";
  const double horizon[3] = {1, 0.9, 0.8}, zenith[3] = {0.1, 0.3, 0.9};
  const std::size_t centre = 3 * (4 * 9 + 4);
  // Straight up (narrow view): the centre pixel's rays are within 0.2 degrees of +y, so it is the zenith colour.
  const std::string up = R"({"look_from": [0, 0, 0], "look_at": [0, 1, 0], "up": [0, 0, -1], "vertical_fov": 2})";
  const LinearImage zenith_image = test::render(test::flatten<double>(test::parse(scene_json(render, up, sky_json, behind))), 2).image;
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(zenith_image.rgb[centre + k], zenith[k], 2e-5);
  // Level: the centre pixel's rays are symmetric about direction.y = 0, so it is the average of the two colours.
  const std::string level = R"({"look_from": [0, 0, 0], "look_at": [0, 0, -1], "vertical_fov": 2})";
  const LinearImage level_image = test::render(test::flatten<double>(test::parse(scene_json(render, level, sky_json, behind))), 2).image;
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(level_image.rgb[centre + k], 0.5 * (horizon[k] + zenith[k]), 1e-4);
  // The top row is nearer the zenith than the bottom row (rows run from the top).
  EXPECT_LT(level_image.rgb[0], level_image.rgb[3 * 8 * 9]);
}

}  // namespace
}  // namespace pt
