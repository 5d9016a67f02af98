// Environment lighting: the background's sampling density against the sampled directions (chi-square) and against
// its image, its integral, rotation and strength, what an escaped ray sees, and renders under an environment image.
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfOutputFile.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "flat/environment.hpp"
#include "kernel/fixed_point.hpp"
#include "test_support.hpp"

namespace pt {
namespace {

// A small map with strong contrast: a dim sky gradient, a sun of one texel 20000 times brighter than the sky, a
// coloured patch and a black band (where the density must be 0).
constexpr u32 kWidth = 24, kHeight = 12;
constexpr u32 kSunColumn = 17, kSunRow = 3;

EnvironmentSettings sun_map(double strength = 1, const Vec3d& degrees = {}) {
  EnvironmentSettings map;
  map.width = kWidth;
  map.height = kHeight;
  map.rgb.resize(3 * kWidth * kHeight);
  for (u32 row = 0; row < kHeight; ++row)
    for (u32 column = 0; column < kWidth; ++column) {
      float* t = map.rgb.data() + 3 * (row * kWidth + column);
      const float sky = 0.2f + 0.05f * static_cast<float>(row) + 0.01f * static_cast<float>(column);
      t[0] = sky;
      t[1] = sky;
      t[2] = 1.5f * sky;
      if (row == 8) t[0] = t[1] = t[2] = 0.0f;  // the black band
      if (row == 5 && column < 6) t[0] = 3.0f, t[1] = 0.0f, t[2] = 0.5f;
    }
  float* sun = map.rgb.data() + 3 * (kSunRow * kWidth + kSunColumn);
  sun[0] = sun[1] = sun[2] = 5000.0f;
  map.strength = strength;
  map.rotation = RigidTransform::from_euler_degrees(degrees, {});
  return map;
}

template <class T>
FlatScene<T> scene_with(const EnvironmentSettings& map) {
  SceneDescription scene = test::generated_scene({0, 0, 3});
  scene.environment = map;
  return test::flatten<T>(scene);
}

// A uniform number in [0, 1) on 24 bits, as the renderer draws them (never rounded up to 1).
template <class T>
T uniform(test::TestRandom& rng) {
  return static_cast<T>(static_cast<double>(rng.next() >> 40) * 0x1p-24);
}

// The map's (u, v) of a world direction, through the map's rotation given in the scene.
void map_uv(const EnvironmentSettings& map, const Vec3d& world, double& u, double& v) {
  const RigidTransform& r = map.rotation;
  // The inverse rotation (the transpose) takes world directions into the map's frame.
  const Vec3d d{r.rotation[0][0] * world.x + r.rotation[1][0] * world.y + r.rotation[2][0] * world.z,
                r.rotation[0][1] * world.x + r.rotation[1][1] * world.y + r.rotation[2][1] * world.z,
                r.rotation[0][2] * world.x + r.rotation[1][2] * world.y + r.rotation[2][2] * world.z};
  u = std::atan2(d.x, -d.z) / (2 * test::kPi) + 0.5;
  v = std::acos(std::clamp(d.y / length(d), -1.0, 1.0)) / test::kPi;
}

// The world direction of the map's (u, v).
Vec3d map_direction(const EnvironmentSettings& map, double u, double v) {
  const double azimuth = 2 * test::kPi * (u - 0.5), theta = test::kPi * v;
  return map.rotation.apply_vector({std::sin(theta) * std::sin(azimuth), std::cos(theta), -std::sin(theta) * std::cos(azimuth)});
}

Vec3d texel_centre(const EnvironmentSettings& map, u32 column, u32 row) {
  return map_direction(map, (column + 0.5) / map.width, (row + 0.5) / map.height);
}

// P(chi-square with `dof` degrees of freedom >= x) is below about 1e-4 when this z exceeds 3.72 (Wilson and
// Hilferty's normal approximation of the chi-square distribution, close for the hundreds of bins used here).
double chi_square_z(double x, double dof) {
  const double m = 2 / (9 * dof);
  return (std::cbrt(x / dof) - (1 - m)) / std::sqrt(m);
}

// Sampled directions against background_pdf, as Mitsuba's and pbrt's sampling tests do: directions fall into bins
// of half a texel on a side in the map's (u, v) square (so that a texel's patch is checked for uniformity too), the
// expected count of a bin is N times the integral of background_pdf over it, and bins expected to hold fewer than 5
// are merged. Bins aligned with the texels make the integral exact: pdf sin(theta) 2 pi^2 is constant on a texel.
template <class T>
void expect_samples_follow_pdf(const EnvironmentSettings& map, u64 seed) {
  const FlatScene<T> flat = scene_with<T>(map);
  const Background<T> background = flat.view().background;
  const u32 columns = 2 * map.width, rows = 2 * map.height;
  std::vector<double> expected(columns * rows);
  for (u32 row = 0; row < rows; ++row)
    for (u32 column = 0; column < columns; ++column) {
      const double u = (column + 0.5) / columns, v = (row + 0.5) / rows;
      const double pdf = static_cast<double>(background_pdf(background, test::to<T>(map_direction(map, u, v))));
      expected[row * columns + column] = pdf * 2 * test::kPi * test::kPi * std::sin(test::kPi * v) / (static_cast<double>(columns) * rows);
    }
  double total = 0;
  for (double e : expected) total += e;
  EXPECT_NEAR(total, 1.0, 1e-5);
  constexpr u32 kSamples = 1'000'000;
  std::vector<double> observed(expected.size(), 0.0);
  test::TestRandom rng(seed);
  for (u32 i = 0; i < kSamples; ++i) {
    const T u1 = uniform<T>(rng);
    const T u2 = uniform<T>(rng);
    const BackgroundSample<T> s = background_sample(background, u1, u2);
    double u, v;
    map_uv(map, Vec3d{static_cast<double>(s.direction.x), static_cast<double>(s.direction.y), static_cast<double>(s.direction.z)}, u, v);
    const u32 column = std::min(static_cast<u32>(u * columns), columns - 1), row = std::min(static_cast<u32>(v * rows), rows - 1);
    observed[row * columns + column] += 1;
  }
  // Bins expected to be nearly empty are pooled (in order), then the statistic.
  double chi_square = 0, pooled_expected = 0, pooled_observed = 0;
  int bins = 0;
  for (std::size_t i = 0; i < expected.size(); ++i) {
    const double e = expected[i] * kSamples;
    if (e < 5) {
      pooled_expected += e;
      pooled_observed += observed[i];
      continue;
    }
    chi_square += (observed[i] - e) * (observed[i] - e) / e;
    ++bins;
  }
  if (pooled_expected >= 5) {
    chi_square += (pooled_observed - pooled_expected) * (pooled_observed - pooled_expected) / pooled_expected;
    ++bins;
  } else {
    EXPECT_LE(pooled_observed, 20) << "directions where the density is about 0";
  }
  const double z = chi_square_z(chi_square, bins - 1);
  EXPECT_LT(z, 3.72) << "chi-square " << chi_square << " over " << bins << " bins";
}

TEST(Environment, SampledDirectionsFollowThePdf) { expect_samples_follow_pdf<float>(sun_map(), 1); }
TEST(Environment, SampledDirectionsFollowThePdfWhenRotated) { expect_samples_follow_pdf<float>(sun_map(1, {30, 75, -20}), 2); }
TEST(Environment, SampledDirectionsFollowThePdfInDouble) { expect_samples_follow_pdf<double>(sun_map(2, {0, -40, 0}), 3); }

// The density integrates to one over the sphere. Integrated on a grid in the map's own (u, v) (dOmega =
// 2 pi^2 sin(theta) du dv), aligned with the texels, where pdf sin(theta) is constant on each cell and the midpoint
// rule is exact; and on a grid in the world's spherical coordinates (z = cos(theta) uniform, dOmega = dz dphi), not
// aligned with the rotated texels, where the sun's edges leave an error of a few 1e-3.
template <class T>
double pdf_integral_in_map(const EnvironmentSettings& map, const Background<T>& background, u32 per_texel) {
  const u32 columns = per_texel * map.width, rows = per_texel * map.height;
  double sum = 0;
  for (u32 row = 0; row < rows; ++row)
    for (u32 column = 0; column < columns; ++column) {
      const double u = (column + 0.5) / columns, v = (row + 0.5) / rows;
      sum += static_cast<double>(background_pdf(background, test::to<T>(map_direction(map, u, v)))) * 2 * test::kPi * test::kPi *
             std::sin(test::kPi * v);
    }
  return sum / (static_cast<double>(columns) * rows);
}

template <class T>
double pdf_integral_in_world(const Background<T>& background, u32 n) {
  double sum = 0;
  for (u32 i = 0; i < n; ++i)
    for (u32 j = 0; j < 2 * n; ++j) {
      const double z = -1 + 2 * (i + 0.5) / n, phi = 2 * test::kPi * (j + 0.5) / (2 * n), r = std::sqrt(1 - z * z);
      sum += static_cast<double>(background_pdf(background, test::to<T>(Vec3d{r * std::cos(phi), z, r * std::sin(phi)})));
    }
  return sum * (2.0 / n) * (2 * test::kPi / (2 * n));
}

TEST(Environment, PdfIntegratesToOne) {
  for (const Vec3d& degrees : {Vec3d{}, Vec3d{10, 33, 71}}) {
    const EnvironmentSettings map = sun_map(1, degrees);
    const FlatScene<double> flat = scene_with<double>(map);
    EXPECT_NEAR(pdf_integral_in_map(map, flat.view().background, 8), 1.0, 1e-6) << degrees.x << " " << degrees.y << " " << degrees.z;
    EXPECT_NEAR(pdf_integral_in_world(flat.view().background, 1500), 1.0, 5e-3) << degrees.x << " " << degrees.y << " " << degrees.z;
  }
  // The gradient and the constant: uniform.
  SceneDescription sky = test::generated_scene({0, 0, 3});
  EXPECT_NEAR(pdf_integral_in_world(test::flatten<float>(sky).view().background, 200), 1.0, 1e-5);
}

// The density matches its image: at each texel's centre the density per solid angle is the texel's luminance times
// one factor, the same for every texel (sin(theta) weights the texel's row and the Jacobian divides it out again),
// and 0 exactly where the texel is black.
TEST(Environment, PdfIsProportionalToEachTexelsLuminance) {
  const EnvironmentSettings map = sun_map(3, {0, 50, 0});
  const FlatScene<double> flat = scene_with<double>(map);
  const Background<double> background = flat.view().background;
  double total_weight = 0;
  for (u32 row = 0; row < kHeight; ++row)
    for (u32 column = 0; column < kWidth; ++column) {
      const float* t = map.rgb.data() + 3 * (row * kWidth + column);
      total_weight += luminance(t[0], t[1], t[2]) * std::sin(test::kPi * (row + 0.5) / kHeight);
    }
  // pdf = luminance sin(theta) / (the mean of luminance sin(theta) over the texels) / (2 pi^2 sin(theta))
  const double factor = static_cast<double>(kWidth * kHeight) / total_weight / (2 * test::kPi * test::kPi);
  for (u32 row = 0; row < kHeight; ++row)
    for (u32 column = 0; column < kWidth; ++column) {
      const float* t = map.rgb.data() + 3 * (row * kWidth + column);
      const double l = luminance(t[0], t[1], t[2]);
      const double pdf = background_pdf(background, texel_centre(map, column, row));
      if (l == 0)
        EXPECT_EQ(pdf, 0.0) << column << ", " << row;
      else
        EXPECT_NEAR(pdf / l, factor, 1e-6 * factor) << column << ", " << row;
    }
  // The sun's texel holds most of the probability.
  const double sun = background_pdf(background, texel_centre(map, kSunColumn, kSunRow));
  EXPECT_GT(sun * 2 * test::kPi * test::kPi * std::sin(test::kPi * (kSunRow + 0.5) / kHeight) / (kWidth * kHeight), 0.9);
}

// What a sample says about its direction is what the density and the radiance say about it, bit for bit, for every
// kind of background and every scalar type (the NEE weights depend on it).
template <class T>
void expect_sample_matches_pdf(const FlatScene<T>& flat, u64 seed) {
  const Background<T> background = flat.view().background;
  test::TestRandom rng(seed);
  for (int i = 0; i < 20000; ++i) {
    const T u1 = uniform<T>(rng);
    const T u2 = uniform<T>(rng);
    const BackgroundSample<T> s = background_sample(background, u1, u2);
    ASSERT_NEAR(static_cast<double>(length(s.direction)), 1.0, 1e-5);
    const T pdf = background_pdf(background, s.direction);
    ASSERT_TRUE(pdf == s.pdf) << static_cast<double>(pdf) << " != " << static_cast<double>(s.pdf) << " at " << static_cast<double>(u1) << ", "
                              << static_cast<double>(u2);
    const Color<T> radiance = background_radiance(background, s.direction);
    ASSERT_TRUE(radiance.x == s.radiance.x && radiance.y == s.radiance.y && radiance.z == s.radiance.z);
  }
}

TEST(Environment, SamplePdfEqualsPdfOfItsDirection) {
  expect_sample_matches_pdf(scene_with<float>(sun_map(2, {15, 100, 5})), 4);
  expect_sample_matches_pdf(scene_with<double>(sun_map(2, {15, 100, 5})), 5);
  using Q32 = Fixed<32, 32>;
  expect_sample_matches_pdf(scene_with<Q32>(sun_map(1, {0, 90, 0})), 6);
  SceneDescription sky = test::generated_scene({0, 0, 3});
  expect_sample_matches_pdf(test::flatten<float>(sky), 7);
  sky.background = {{0.3, 0.4, 0.5}, {0.3, 0.4, 0.5}, {}};
  expect_sample_matches_pdf(test::flatten<double>(sky), 8);
  for (const Color<float>& c : {Color<float>{}, Color<float>{1, 2, 3}}) {
    // Uniform on the sphere for the gradient and the constant.
    const Background<float> background{c, c, {}};
    test::TestRandom rng(9);
    double y_sum = 0;
    for (int i = 0; i < 4000; ++i) {
      const float u1 = uniform<float>(rng);
      const BackgroundSample<float> s = background_sample(background, u1, uniform<float>(rng));
      EXPECT_FLOAT_EQ(s.pdf, static_cast<float>(1 / (4 * test::kPi)));
      y_sum += s.direction.y;
    }
    EXPECT_NEAR(y_sum / 4000, 0.0, 4 * std::sqrt(1.0 / 3 / 4000));
  }
}

// Rotation moves the sun where the rotation takes it: 90 degrees about the up axis takes the image's centre (ahead,
// -z) to -x; [90, 0, 0] takes it up to +y. The map's sun is put at the image's centre here.
TEST(Environment, RotationMovesTheBrightSpot) {
  EnvironmentSettings map = sun_map();
  // The sun moved to the centre texel's corner nearest (u, v) = (0.5, 0.5): texel (12, 6) spans u in [0.5, 0.54).
  std::fill(map.rgb.begin() + 3 * (kSunRow * kWidth + kSunColumn), map.rgb.begin() + 3 * (kSunRow * kWidth + kSunColumn) + 3, 0.5f);
  for (int c = 0; c < 3; ++c) map.rgb[3 * (6 * kWidth + 12) + c] = 5000.0f;
  const double half_texel = test::kPi / kHeight / 2;  // the sun's texel centre is half a texel right of and below the centre
  const Vec3d sun_in_map = texel_centre(map, 12, 6);
  EXPECT_NEAR(sun_in_map.z, -std::cos(half_texel) * std::cos(half_texel), 1e-12);
  struct Case {
    Vec3d degrees;
    Vec3d sun;  // where the sun's centre goes
  };
  const double s = std::sin(half_texel), c = std::cos(half_texel);
  for (const Case& k : {Case{{0, 0, 0}, {c * s, -s, -c * c}}, Case{{0, 90, 0}, {-c * c, -s, -c * s}}, Case{{90, 0, 0}, {c * s, c * c, -s}}}) {
    map.rotation = RigidTransform::from_euler_degrees(k.degrees, {});
    const FlatScene<double> flat = scene_with<double>(map);
    const Background<double> background = flat.view().background;
    EXPECT_EQ(background_radiance(background, k.sun).x, 5000.0) << k.degrees.y;
    if (k.degrees.x != 0 || k.degrees.y != 0) {
      EXPECT_LT(background_radiance(background, sun_in_map).x, 10.0);
    }
    // Most samples land within the sun's texel around its new place.
    test::TestRandom rng(10);
    int near_sun = 0;
    for (int i = 0; i < 1000; ++i) {
      const double u1 = uniform<double>(rng);
      const BackgroundSample<double> sample = background_sample(background, u1, uniform<double>(rng));
      if (dot(sample.direction, k.sun) > std::cos(0.2)) ++near_sun;
    }
    EXPECT_GT(near_sun, 900) << k.degrees.x << " " << k.degrees.y;
  }
}

// A camera ray that leaves the scene sees the texel it points at, times the strength: a narrow camera aimed at a
// texel's centre, every sample of every pixel, through the scene file, the EXR reader, flattening and the kernels.
TEST(Environment, EscapedCameraRaySeesTexelTimesStrength) {
  test::TempDir dir;
  LinearImage image;
  image.width = 8;
  image.height = 4;
  for (u32 i = 0; i < 32; ++i)
    for (int c = 0; c < 3; ++c) image.rgb.push_back(static_cast<float>(i + 1) * (c + 1) * 0.25f);
  write_image(dir / "map.exr", image);
  // Texel (5, 1): u = 0.6875 (the azimuth 2 pi (u - 0.5), 67.5 degrees from -z towards +x), v = 0.375 (theta 67.5
  // degrees from +y); then rotated 30 degrees about y, as the scene says.
  const double azimuth = 2 * test::kPi * (0.6875 - 0.5), theta = test::kPi * 0.375;
  const Vec3d in_map{std::sin(theta) * std::sin(azimuth), std::cos(theta), -std::sin(theta) * std::cos(azimuth)};
  const Vec3d aim = RigidTransform::from_euler_degrees({0, 30, 0}, {}).apply_vector(in_map);
  const std::string text = R"({"render": {"width": 4, "height": 4, "samples_per_pixel": 4, "max_depth": 4},
    "camera": {"look_from": [0, 0, 0], "look_at": [)" +
                           std::to_string(aim.x) + ", " + std::to_string(aim.y) + ", " + std::to_string(aim.z) +
                           R"(], "vertical_fov": 1},
    "background": {"type": "environment", "file": "map.exr", "strength": 2.5, "rotate": 30},
    "objects": [{"type": "sphere", "center": [0, -100, 0], "radius": 1, "material": {"type": "lambertian", "albedo": [1, 1, 1]}}]})";
  test::write_text_file(dir / "scene.json", text);
  const SceneDescription scene = load_scene_file(dir / "scene.json");
  const float* texel = image.rgb.data() + 3 * (1 * 8 + 5);
  const test::PixelStatistics stats = test::sample_statistics(test::flatten<float>(scene), 4);
  for (u32 p = 0; p < 16; ++p)
    for (int c = 0; c < 3; ++c) {
      EXPECT_FLOAT_EQ(static_cast<float>(stats.mean[3 * p + c]), texel[c] * 2.5f) << p;
      EXPECT_EQ(stats.variance[3 * p + c], 0.0);
    }
  // The double kernels, the escape step itself.
  const FlatScene<double> flat = test::flatten<double>(scene);
  PathState<double> path{Ray<double>{{0, 0, 0}, aim, 0}, {}, Color<double>{0.5, 1, 2}, 0, 0, 0.0};
  path_escaped(flat.view(), path);
  const Color<double> throughput{0.5, 1, 2};
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(path.radiance[c], throughput[c] * texel[c] * 2.5, 1e-6 * texel[c]);
}

// The estimator NEE will use, E[L cos / pdf] with directions from background_sample, gives the irradiance the map
// sends onto a surface (summed over texels on a fine grid), within a bound derived from its sample variance.
TEST(Environment, LightSamplingEstimatesIrradiance) {
  const EnvironmentSettings map = sun_map(1, {20, 40, 0});
  const FlatScene<double> flat = scene_with<double>(map);
  const Background<double> background = flat.view().background;
  for (const Vec3d& normal : {Vec3d{0, 1, 0}, normalize(Vec3d{1, -0.3, -2}), normalize(Vec3d{-1, 0.2, 0.5})}) {
    // The exact value: each texel's radiance times its integral of cos+ over its patch (a 32x32 grid in (u, v)
    // with the 2 pi^2 sin(theta) Jacobian).
    double exact = 0;
    for (u32 row = 0; row < kHeight; ++row)
      for (u32 column = 0; column < kWidth; ++column) {
        const float* t = map.rgb.data() + 3 * (row * kWidth + column);
        double integral = 0;
        for (int a = 0; a < 32; ++a)
          for (int b = 0; b < 32; ++b) {
            const double u = (column + (a + 0.5) / 32) / kWidth, v = (row + (b + 0.5) / 32) / kHeight;
            integral += std::max(0.0, dot(normal, map_direction(map, u, v))) * 2 * test::kPi * test::kPi * std::sin(test::kPi * v) /
                        (32.0 * 32 * kWidth * kHeight);
          }
        exact += t[1] * integral;
      }
    test::TestRandom rng(11);
    constexpr int kSamples = 200000;
    double sum = 0, sum_squares = 0;
    for (int i = 0; i < kSamples; ++i) {
      const double u1 = uniform<double>(rng);
      const BackgroundSample<double> s = background_sample(background, u1, uniform<double>(rng));
      const double value = s.pdf > 0 ? s.radiance.y * std::max(0.0, dot(normal, s.direction)) / s.pdf : 0.0;
      sum += value;
      sum_squares += value * value;
    }
    const double mean = sum / kSamples, variance = (sum_squares / kSamples - mean * mean) * kSamples / (kSamples - 1);
    EXPECT_NEAR(mean, exact, 4 * std::sqrt(variance / kSamples) + 1e-4 * exact) << normal.x << " " << normal.y << " " << normal.z;
  }
}

TEST(Environment, MeanRadianceIsTheSolidAngleWeightedTexelMean) {
  EnvironmentSettings map = sun_map();
  std::fill(map.rgb.begin(), map.rgb.end(), 0.25f);
  map.strength = 4;
  const Color<double> mean = background_mean_radiance(scene_with<float>(map));
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean[c], 1.0, 1e-12);
  SceneDescription sky = test::generated_scene({0, 0, 3});
  const Color<double> gradient = background_mean_radiance(test::flatten<double>(sky));
  EXPECT_NEAR(gradient.x, 0.75, 1e-12);
  EXPECT_NEAR(gradient.z, 1.0, 1e-12);
  // The sun's map: its texels weighted by solid angle, (2 pi / width)(cos theta0 - cos theta1) / 4 pi.
  const EnvironmentSettings sun = sun_map(2);
  double expected = 0;
  for (u32 row = 0; row < kHeight; ++row)
    for (u32 column = 0; column < kWidth; ++column)
      expected += 2 * sun.rgb[3 * (row * kWidth + column)] * (std::cos(test::kPi * row / kHeight) - std::cos(test::kPi * (row + 1) / kHeight)) /
                  (2.0 * kWidth);
  EXPECT_NEAR(background_mean_radiance(scene_with<double>(sun)).x, expected, 1e-9 * expected);
}

// The other formats an environment image may come in: Radiance .hdr (RGBE, read by stb_image) and a grey OpenEXR
// image (one Y channel), each told by its first bytes, not its name.
TEST(Environment, RadianceHdrAndGreyExrAreRead) {
  test::TempDir dir;
  // 4x2 texels, flat (not run-length encoded) RGBE: mantissa * 2^(exponent - 136).
  std::string hdr = "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 4\n";
  const unsigned char texels[8][4] = {{128, 128, 128, 129}, {128, 0, 0, 128},   {192, 64, 128, 130},  {0, 0, 0, 0},
                                      {128, 128, 128, 136}, {255, 128, 1, 129}, {128, 128, 128, 129}, {128, 128, 128, 129}};
  for (const auto& t : texels) hdr.append(reinterpret_cast<const char*>(t), 4);
  test::write_text_file(dir / "sky.pic", hdr);
  const LinearImage radiance = read_environment_image(dir / "sky.pic");
  ASSERT_EQ(radiance.width, 4u);
  ASSERT_EQ(radiance.height, 2u);
  const std::vector<float> expected_radiance = {1, 1, 1, 0.5f, 0, 0, 3, 1, 2, 0, 0, 0, 128, 128, 128, 255 / 128.0f, 1, 1 / 128.0f, 1, 1, 1, 1, 1, 1};
  EXPECT_EQ(radiance.rgb, expected_radiance);

  Imf::Header header(3, 2);
  header.channels().insert("Y", Imf::Channel(Imf::FLOAT));
  const float grey[6] = {0.25f, 1, 2, 4, 8, 1000};
  {
    Imf::OutputFile out((dir / "grey.hdr").c_str(), header);  // an EXR, whatever its name says
    Imf::FrameBuffer frame;
    frame.insert("Y", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(const_cast<float*>(grey)), sizeof(float), 3 * sizeof(float)));
    out.setFrameBuffer(frame);
    out.writePixels(2);
  }
  const LinearImage exr = read_environment_image(dir / "grey.hdr");
  ASSERT_EQ(exr.width, 3u);
  ASSERT_EQ(exr.height, 2u);
  for (int i = 0; i < 6; ++i)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(exr.rgb[3 * i + c], grey[i]) << i;
}

// A diffuse sphere under an environment image of one colour renders as under the constant background of that
// colour: block means agree within the noise bound of their sample variances.
TEST(Environment, ConstantMapRendersAsConstantBackground) {
  test::TempDir dir;
  LinearImage image;
  image.width = 16;
  image.height = 8;
  image.rgb.assign(3 * 16 * 8, 0.0f);
  for (std::size_t i = 0; i < image.rgb.size(); i += 3) image.rgb[i] = 0.6f, image.rgb[i + 1] = 0.3f, image.rgb[i + 2] = 0.9f;
  write_image(dir / "flat.exr", image);
  const std::string scene_text = R"({"render": {"width": 32, "height": 32, "samples_per_pixel": 64, "max_depth": 8},
    "camera": {"look_from": [0, 1, 4], "look_at": [0, 0, 0], "vertical_fov": 40},
    "background": BACKGROUND,
    "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": {"type": "lambertian", "albedo": [0.7, 0.5, 0.3]}},
                {"type": "sphere", "center": [0, -101, 0], "radius": 100, "material": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}}]})";
  auto with_background = [&](const std::string& background) {
    std::string text = scene_text;
    text.replace(text.find("BACKGROUND"), 10, background);
    test::write_text_file(dir / "scene.json", text);
    return load_scene_file(dir / "scene.json");
  };
  const test::PixelStatistics map =
      test::sample_statistics(test::flatten<float>(with_background(R"({"type": "environment", "file": "flat.exr", "strength": 2})")), 256);
  const test::PixelStatistics constant =
      test::sample_statistics(test::flatten<float>(with_background(R"({"type": "constant", "color": [1.2, 0.6, 1.8]})")), 256);
  const std::vector<test::BlockDifference> blocks = test::compare_block_means(map, constant, 8, 4.0, 1e-6, 1e-6);
  EXPECT_TRUE(blocks.front().within) << test::describe_blocks(blocks, 4, "map", "constant");
  EXPECT_GT(constant.image_mean(0), 0.1);
}

// Whether the default light sampling (auto) samples the background as a light follows from how noisily scattering
// alone would find it: a sun makes the cosine's estimate of the irradiance vary by hundreds of times its mean
// squared (this one fills a texel of 0.07 sr), a uniform map not at all, a smooth gradient little (flat/environment.cpp).
TEST(Environment, AutoSamplesASunAndLeavesAnEvenMapToScattering) {
  const FlatScene<float> sun = scene_with<float>(sun_map());
  EXPECT_GT(sun.background_scattering_variance, 100 * kBackgroundSamplingVariance);
  EXPECT_NE(sun.background_light, kNoLight);
  EXPECT_EQ(sun.params.next_event, 1u);
  EnvironmentSettings even = sun_map();
  std::fill(even.rgb.begin(), even.rgb.end(), 0.7f);
  const FlatScene<float> flat = scene_with<float>(even);
  EXPECT_LT(flat.background_scattering_variance, 0.01);
  EXPECT_EQ(flat.background_light, kNoLight);
  // Asked for by name, the even map is a light all the same.
  SceneDescription scene = test::generated_scene({0, 0, 3});
  scene.environment = even;
  scene.render.light_sampling = LightSampling::kNextEvent;
  EXPECT_NE(test::flatten<float>(scene).background_light, kNoLight);
  // The measure follows the contrast: a map whose one bright texel is twice its sky varies less than the sun's.
  EnvironmentSettings soft = even;
  soft.rgb[3 * (kSunRow * kWidth + kSunColumn)] = soft.rgb[3 * (kSunRow * kWidth + kSunColumn) + 1] = 1.4f;
  const double soft_variance = scene_with<float>(soft).background_scattering_variance;
  EXPECT_GT(soft_variance, flat.background_scattering_variance);
  EXPECT_LT(soft_variance, kBackgroundSamplingVariance);
}

}  // namespace
}  // namespace pt
