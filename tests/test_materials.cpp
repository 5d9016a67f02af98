// Checks every material's scattering: energy conservation, unit directions, and the distribution each one promises.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <type_traits>
#include <vector>

#include "test_support.hpp"

namespace pt {
namespace {

using test::to;

// Texture 0: white; texture 1: a colour.
template <class T>
std::vector<Texture<T>> test_textures() {
  return {SolidTexture<T>{Color<T>::splat(T(1))}, SolidTexture<T>{to<T>({0.25, 0.5, 0.75})}};
}

template <class T>
double unit_tolerance() {
  return std::is_same_v<T, float> ? 1e-5 : 1e-12;
}

// One scattering event with a random incoming direction, normal (facing the ray) and side.
template <class T>
struct Trial {
  Ray<T> in;
  SurfacePoint<T> at;
  SampleRandom random;
};

template <class T>
Trial<T> random_trial(test::TestRandom& rng, u32 index) {
  Trial<T> trial{};
  const Vec3d d = rng.unit_vector();
  Vec3d n = rng.unit_vector();
  if (dot(d, n) > 0) n = -n;
  trial.in = Ray<T>{to<T>(rng.vec3(-5, 5)), to<T>(d), static_cast<T>(rng.uniform())};
  trial.at.p = to<T>(rng.vec3(-5, 5));
  trial.at.normal = to<T>(n);
  trial.at.u = static_cast<T>(rng.uniform());
  trial.at.v = static_cast<T>(rng.uniform());
  trial.at.front_face = rng.uniform() < 0.5;
  trial.at.material = 0;
  // Every field set: a ray leaves from p moved by `offset` along the geometric normal, so an unset offset made the
  // origin whatever the stack held (a NaN now and then under the sanitizers). No offset here: rays leave from p.
  trial.at.geometric_normal = trial.at.front_face ? trial.at.normal : -trial.at.normal;
  trial.at.offset = T(0);
  trial.at.tangent = Vec3<T>{T(0), T(0), T(0)};
  trial.at.handedness = T(1);
  trial.random = SampleRandom::make(11, index, 0);
  return trial;
}

template <class T>
bool scatter(const Material<T>& material, const Trial<T>& trial, const std::vector<Texture<T>>& textures, Scatter<T>& out) {
  const BounceRandom bounce{&trial.random, 0};
  return material_scatter(material, trial.in, trial.at, textures.data(), TextureData<T>{}, bounce, out);
}

// An orthonormal basis around n: the azimuth of a direction about n.
double azimuth(const Vec3d& n, const Vec3d& d) {
  const Vec3d helper = std::abs(n.x) < 0.9 ? Vec3d{1, 0, 0} : Vec3d{0, 1, 0};
  const Vec3d a = normalize(cross(n, helper)), b = cross(n, a);
  return std::atan2(dot(d, b), dot(d, a)) + test::kPi;  // in [0, 2 pi]
}

Vec3d to_double(const Vec3<float>& v) { return {v.x, v.y, v.z}; }
Vec3d to_double(const Vec3<double>& v) { return v; }

template <class T>
class MaterialEnergyConservation : public ::testing::Test {};
using ScalarTypes = ::testing::Types<float, double>;
TYPED_TEST_SUITE(MaterialEnergyConservation, ScalarTypes);

TYPED_TEST(MaterialEnergyConservation, AlbedoOneNeverAmplifiesAndDirectionsAreUnit) {
  using T = TypeParam;
  const std::vector<Texture<T>> textures = test_textures<T>();
  const Color<T> white = Color<T>::splat(T(1));
  struct Case {
    const char* name;
    Material<T> material;
    bool always_scatters;
  };
  const Case cases[] = {
      {"lambertian", Lambertian<T>{0}, true},
      {"mirror", Metal<T>{white, T(0)}, true},
      {"fuzzy metal", Metal<T>{white, T(0.7)}, false},
      {"glass", Dielectric<T>{T(1.5), white}, true},
      {"inverse glass", Dielectric<T>{T(0.75), white}, true},
      {"isotropic", Isotropic<T>{0}, true},
  };
  test::TestRandom rng(21);
  for (const Case& c : cases) {
    int scattered = 0;
    for (u32 i = 0; i < 20000; ++i) {
      const Trial<T> trial = random_trial<T>(rng, i);
      Scatter<T> out;
      const bool did = scatter(c.material, trial, textures, out);
      if (c.always_scatters) {
        ASSERT_TRUE(did) << c.name;
      }
      if (!did) continue;
      ++scattered;
      for (int k = 0; k < 3; ++k) {
        ASSERT_GE(out.attenuation[k], T(0)) << c.name;
        ASSERT_LE(out.attenuation[k], T(1)) << c.name;
      }
      ASSERT_NEAR(length(to_double(out.ray.direction)), 1.0, unit_tolerance<T>()) << c.name;
      ASSERT_EQ(out.ray.origin.x, trial.at.p.x) << c.name;
      ASSERT_EQ(out.ray.origin.y, trial.at.p.y) << c.name;
      ASSERT_EQ(out.ray.origin.z, trial.at.p.z) << c.name;
      ASSERT_EQ(out.ray.time, trial.in.time) << c.name;
    }
    EXPECT_GT(scattered, 10000) << c.name;
  }
}

TYPED_TEST(MaterialEnergyConservation, DiffuseLightEmitsAndNeverScatters) {
  using T = TypeParam;
  const std::vector<Texture<T>> textures = test_textures<T>();
  test::TestRandom rng(3);
  const Trial<T> trial = random_trial<T>(rng, 0);
  Scatter<T> out;
  EXPECT_FALSE(scatter<T>(DiffuseLight<T>{1}, trial, textures, out));
  const Color<T> emitted = material_emitted<T>(DiffuseLight<T>{1}, trial.at, textures.data(), TextureData<T>{});
  EXPECT_EQ(emitted.x, T(0.25));
  EXPECT_EQ(emitted.y, T(0.5));
  EXPECT_EQ(emitted.z, T(0.75));
  // Nothing else emits.
  for (const Material<T>& m : {Material<T>{Lambertian<T>{0}}, Material<T>{Metal<T>{Color<T>::splat(T(1)), T(0)}},
                               Material<T>{Dielectric<T>{T(1.5), Color<T>::splat(T(1))}}, Material<T>{Isotropic<T>{0}}}) {
    const Color<T> e = material_emitted(m, trial.at, textures.data(), TextureData<T>{});
    EXPECT_EQ(e.x, T(0));
    EXPECT_EQ(e.y, T(0));
    EXPECT_EQ(e.z, T(0));
  }
}

TYPED_TEST(MaterialEnergyConservation, AttenuationIsTheAlbedoOrTint) {
  using T = TypeParam;
  const std::vector<Texture<T>> textures = test_textures<T>();
  test::TestRandom rng(4);
  const Color<T> colour = to<T>({0.25, 0.5, 0.75});
  for (const Material<T>& m : {Material<T>{Lambertian<T>{1}}, Material<T>{Metal<T>{colour, T(0)}}, Material<T>{Dielectric<T>{T(1.5), colour}},
                               Material<T>{Isotropic<T>{1}}}) {
    const Trial<T> trial = random_trial<T>(rng, 5);
    Scatter<T> out;
    ASSERT_TRUE(scatter(m, trial, textures, out));
    EXPECT_EQ(out.attenuation.x, colour.x);
    EXPECT_EQ(out.attenuation.y, colour.y);
    EXPECT_EQ(out.attenuation.z, colour.z);
  }
}

TEST(LambertianScattering, IsCosineDistributedAboutTheNormal) {
  // For a cosine-weighted hemisphere, cos^2 of the angle to the normal is uniform in [0, 1] and the azimuth is
  // uniform; E[cos] = 2/3.
  const std::vector<Texture<float>> textures = test_textures<float>();
  constexpr int n = 200000, kBins = 20;
  std::vector<long> cos2_counts(kBins, 0), azimuth_counts(kBins, 0);
  double cos_sum = 0;
  test::TestRandom rng(8);
  for (int i = 0; i < n; ++i) {
    const Trial<float> trial = random_trial<float>(rng, static_cast<u32>(i));
    Scatter<float> out;
    ASSERT_TRUE(scatter<float>(Lambertian<float>{0}, trial, textures, out));
    const Vec3d normal = to_double(trial.at.normal), d = to_double(out.ray.direction);
    const double c = dot(normal, d);
    ASSERT_GE(c, -1e-6);  // never below the surface
    cos_sum += c;
    ++cos2_counts[std::min(kBins - 1, static_cast<int>(c * c * kBins))];
    ++azimuth_counts[std::min(kBins - 1, static_cast<int>(azimuth(normal, d) / (2 * test::kPi) * kBins))];
  }
  // Chi-square with 19 degrees of freedom, bounds at p = 1e-6 each side.
  EXPECT_GT(test::chi_square(cos2_counts, n), 2.0);
  EXPECT_LT(test::chi_square(cos2_counts, n), 64.4);
  EXPECT_GT(test::chi_square(azimuth_counts, n), 2.0);
  EXPECT_LT(test::chi_square(azimuth_counts, n), 64.4);
  // The standard deviation of cos is sqrt(1/2 - 4/9) = 0.236.
  EXPECT_NEAR(cos_sum / n, 2.0 / 3.0, 5 * 0.236 / std::sqrt(static_cast<double>(n)));
}

TEST(MetalScattering, MirrorReflectsExactlyAndFuzzStaysInItsCone) {
  const std::vector<Texture<double>> textures = test_textures<double>();
  test::TestRandom rng(9);
  int absorbed = 0;
  for (u32 i = 0; i < 20000; ++i) {
    const Trial<double> trial = random_trial<double>(rng, i);
    const Vec3d mirror = reflect(trial.in.direction, trial.at.normal);
    Scatter<double> out;
    ASSERT_TRUE(scatter<double>(Metal<double>{{1, 1, 1}, 0}, trial, textures, out));
    ASSERT_NEAR(length(out.ray.direction - mirror), 0, 1e-12);
    // Fuzz 0.5: within asin(0.5) = 30 degrees of the mirror direction; absorbed exactly when it would leave below.
    const bool did = scatter<double>(Metal<double>{{1, 1, 1}, 0.5}, trial, textures, out);
    ASSERT_GE(dot(out.ray.direction, mirror), std::sqrt(1 - 0.25) - 1e-12);
    ASSERT_EQ(did, dot(out.ray.direction, trial.at.normal) > 0);
    absorbed += !did;
  }
  EXPECT_GT(absorbed, 0);  // grazing rays do get absorbed
}

// Sine of the angle between a unit direction and the normal's axis.
double sine_to_axis(const Vec3d& d, const Vec3d& n) { return length(cross(d, n)); }

TEST(DielectricScattering, NormalIncidenceReflectsSchlickR0AndRefractsStraightThrough) {
  const std::vector<Texture<double>> textures = test_textures<double>();
  const Dielectric<double> glass{1.5, {1, 1, 1}};
  constexpr int n = 100000;
  int reflected = 0;
  for (int i = 0; i < n; ++i) {
    Trial<double> trial;
    trial.in = Ray<double>{{0, 0, 1}, {0, 0, -1}, 0};
    trial.at = SurfacePoint<double>{{0, 0, 0}, {0, 0, 1}, 0, 0, true, 0, {0, 0, 1}, 0, {}, 0};
    trial.random = SampleRandom::make(12, static_cast<u32>(i), 0);
    Scatter<double> out;
    ASSERT_TRUE(scatter<double>(glass, trial, textures, out));
    if (out.ray.direction.z > 0) {
      ++reflected;
      ASSERT_NEAR(out.ray.direction.z, 1.0, 1e-12);
    } else {
      ASSERT_NEAR(out.ray.direction.z, -1.0, 1e-12);
    }
  }
  const double r0 = 0.04;  // ((1 - 1.5) / (1 + 1.5))^2
  EXPECT_NEAR(static_cast<double>(reflected) / n, r0, 5 * std::sqrt(r0 * (1 - r0) / n));
}

TEST(DielectricScattering, ObliqueRaysObeySnellAndSchlick) {
  const std::vector<Texture<double>> textures = test_textures<double>();
  const double ior = 1.5;
  for (const bool entering : {true, false}) {
    // Entering at 60 degrees (eta = 1/1.5), or leaving at 20 degrees (eta = 1.5, below the critical angle).
    const double angle = (entering ? 60 : 20) * test::kPi / 180, eta = entering ? 1 / ior : ior;
    const Vec3d n{0, 1, 0};
    const Vec3d d{std::sin(angle), -std::cos(angle), 0};
    constexpr int count = 50000;
    int reflected = 0;
    for (int i = 0; i < count; ++i) {
      Trial<double> trial;
      trial.in = Ray<double>{{0, 1, 0}, d, 0};
      trial.at = SurfacePoint<double>{{0, 0, 0}, n, 0, 0, entering, 0, entering ? n : -n, 0, {}, 0};
      trial.random = SampleRandom::make(13, static_cast<u32>(i), 0);
      Scatter<double> out;
      ASSERT_TRUE(scatter<double>(Dielectric<double>{ior, {1, 1, 1}}, trial, textures, out));
      const Vec3d o = out.ray.direction;
      ASSERT_NEAR(o.z, 0, 1e-12);  // stays in the plane of incidence
      if (o.y > 0) {
        ++reflected;
        ASSERT_NEAR(length(o - reflect(d, n)), 0, 1e-12);
      } else {
        ASSERT_NEAR(sine_to_axis(o, n), eta * std::sin(angle), 1e-12);  // Snell: sin t = eta sin i
        ASSERT_GT(o.x, 0);                                              // continues forwards
      }
    }
    const double r0 = std::pow((1 - ior) / (1 + ior), 2);
    const double schlick = r0 + (1 - r0) * std::pow(1 - std::cos(angle), 5);
    EXPECT_NEAR(static_cast<double>(reflected) / count, schlick, 5 * std::sqrt(schlick * (1 - schlick) / count))
        << (entering ? "entering" : "leaving");
  }
}

TEST(DielectricScattering, BeyondTheCriticalAngleReflectsTotally) {
  const std::vector<Texture<double>> textures = test_textures<double>();
  const Vec3d n{0, 1, 0};
  const double angle = 45 * test::kPi / 180;  // critical angle of 1.5 is 41.8 degrees
  const Vec3d d{std::sin(angle), -std::cos(angle), 0};
  for (u32 i = 0; i < 2000; ++i) {
    Trial<double> trial;
    trial.in = Ray<double>{{0, 1, 0}, d, 0};
    trial.at = SurfacePoint<double>{{0, 0, 0}, n, 0, 0, false, 0, -n, 0, {}, 0};  // inside the glass
    trial.random = SampleRandom::make(14, i, 0);
    Scatter<double> out;
    ASSERT_TRUE(scatter<double>(Dielectric<double>{1.5, {1, 1, 1}}, trial, textures, out));
    ASSERT_NEAR(length(out.ray.direction - reflect(d, n)), 0, 1e-12);
  }
}

TEST(IsotropicScattering, IsUniformOnTheSphere) {
  const std::vector<Texture<float>> textures = test_textures<float>();
  constexpr int n = 100000, kBins = 20;
  std::vector<long> counts(kBins, 0);
  Vec3d sum{};
  test::TestRandom rng(15);
  for (int i = 0; i < n; ++i) {
    const Trial<float> trial = random_trial<float>(rng, static_cast<u32>(i));
    Scatter<float> out;
    ASSERT_TRUE(scatter<float>(Isotropic<float>{0}, trial, textures, out));
    const Vec3d d = to_double(out.ray.direction);
    sum += d;
    // Measured against the (random) normal: the phase function must ignore it.
    const double c = dot(d, to_double(trial.at.normal));
    ++counts[std::min(kBins - 1, static_cast<int>((c + 1) / 2 * kBins))];
  }
  EXPECT_GT(test::chi_square(counts, n), 2.0);
  EXPECT_LT(test::chi_square(counts, n), 64.4);
  EXPECT_LT(length(sum / static_cast<double>(n)), 5 * std::sqrt(1.0 / (3 * n)));
}

TEST(LambertianUnderWhiteFurnace, ReflectsItsAlbedo) {
  // A convex lambertian sphere of albedo a under a sky of radiance 1 shows exactly a when only scattering finds the
  // sky; with Russian roulette from the first bounce (q = 0.75, survivors weighted 1/q) it shows a on average.
  auto scene_text = [](int roulette) {
    return R"({"render": {"width": 24, "height": 24, "samples_per_pixel": 64, "max_depth": 100, "light_sampling": "none", "russian_roulette_depth": )" +
           std::to_string(roulette) + R"(},
               "camera": {"look_from": [0, 0, 3], "look_at": [0, 0, 0], "vertical_fov": 30},
               "background": {"type": "constant", "color": [1, 1, 1]},
               "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": {"type": "lambertian", "albedo": [0.25, 0.5, 0.75]}}]})";
  };
  const double albedo[3] = {0.25, 0.5, 0.75};
  const LinearImage exact = test::render(test::flatten<float>(test::parse(scene_text(0))), 2).image;
  const test::PixelStatistics noisy = test::sample_statistics(test::flatten<float>(test::parse(scene_text(1))), 64);
  // Pixels that see only the sphere: those equal to the albedo without roulette.
  std::vector<std::size_t> on_sphere;
  for (std::size_t p = 0; p < exact.rgb.size() / 3; ++p)
    if (std::abs(exact.rgb[3 * p] - albedo[0]) < 1e-6 && std::abs(exact.rgb[3 * p + 2] - albedo[2]) < 1e-6) on_sphere.push_back(p);
  ASSERT_GT(on_sphere.size(), 150u);
  for (int k = 0; k < 3; ++k) {
    double mean = 0, variance = 0;
    for (std::size_t p : on_sphere) {
      mean += noisy.mean[3 * p + k];
      variance += noisy.variance[3 * p + k] / noisy.samples;
    }
    mean /= on_sphere.size();
    const double se = std::sqrt(variance) / on_sphere.size();
    EXPECT_GT(se, 0.0);
    EXPECT_NEAR(mean, albedo[k], 4 * se) << "channel " << k;
  }
}

}  // namespace
}  // namespace pt
