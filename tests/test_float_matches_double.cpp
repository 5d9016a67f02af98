// Float renders are the same picture as double renders, and moving or scaling a scene changes no float render, within noise.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include "backends/registry.hpp"
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

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Float and double renders of the same scene with independent seeds (so the bound's independence holds exactly).
void expect_float_matches_double(const std::string& name, const std::string& float_backend) {
  const auto start = std::chrono::steady_clock::now();
  const SceneDescription scene = load_case_scene(name);
  const SceneCase& c = scene_case(name);
  const test::PixelStatistics f = statistics_on<float>(float_backend, flatten_scene<float>(scene, case_settings(scene, c, c.samples, 101)));
  const test::PixelStatistics d = statistics_on<double>("cpu", flatten_scene<double>(scene, case_settings(scene, c, c.samples, 202)));
  expect_blocks_agree(f, d, "float", "double", name + " (float on " + float_backend + ", double on cpu)");
  std::printf("%s: %ux%u, %u spp, %.1f s\n", name.c_str(), c.width, c.height, f.samples, seconds_since(start));
}

class FloatMatchesDouble : public ::testing::TestWithParam<std::string> {};

TEST_P(FloatMatchesDouble, BlockMeansAgreeWithinNoise) { expect_float_matches_double(GetParam(), "cpu"); }

// The same on the GPU: float on the CUDA backend against double on the CPU.
TEST_P(FloatMatchesDouble, CudaBlockMeansAgreeWithCpuDoubleWithinNoise) {
#if !PT_HAVE_CUDA
  GTEST_SKIP() << "the CUDA backend is not built (no nvcc)";
#else
  if (cuda_device_count() == 0) GTEST_SKIP() << "no usable GPU on this machine";
  expect_float_matches_double(GetParam(), "cuda");
#endif
}

INSTANTIATE_TEST_SUITE_P(Scenes, FloatMatchesDouble,
                         ::testing::Values("tiny", "meshes", "seed-default", "book1-final", "book2-final", "cornell-box", "cornell-smoke",
                                           "precision"),
                         test::scene_test_name);

// The metallic-roughness material in every form a scene gives it: a metal, a dielectric with an image base colour,
// a rough metal whose roughness and metallic come from an image (read as linear data), and the smallest roughness (a
// near mirror) on a quad, under a small light and the sky. Every sample finite, and float the same picture as double.
SceneDescription metallic_roughness_scene() {
  return test::parse(R"({
    "render": {"width": 64, "height": 48, "samples_per_pixel": 128, "max_depth": 8},
    "camera": {"look_from": [0, 1, 4], "look_at": [0, 0.5, 0], "vertical_fov": 45},
    "background": {"type": "sky", "horizon": [1, 1, 1], "zenith": [0.5, 0.7, 1.0]},
    "textures": {"planet": {"type": "image", "file": "textures/planet-1024x512.png"}},
    "materials": {"ground": {"type": "metallic_roughness", "base_color": [0.5, 0.5, 0.5], "roughness": 0.8}},
    "objects": [
      {"type": "sphere", "center": [0, -100, 0], "radius": 100, "material": "ground"},
      {"type": "sphere", "center": [-1.2, 0.5, 0], "radius": 0.5, "material": {"type": "metallic_roughness", "base_color": [0.95, 0.64, 0.54], "metallic": 1, "roughness": 0.3}},
      {"type": "sphere", "center": [0, 0.5, 0], "radius": 0.5, "material": {"type": "metallic_roughness", "texture": "planet", "roughness": 0.2}},
      {"type": "sphere", "center": [1.2, 0.5, 0], "radius": 0.5, "material": {"type": "metallic_roughness", "base_color": [0.9, 0.9, 0.9], "metallic": 1, "roughness": 1, "metallic_roughness_texture": "planet"}},
      {"type": "quad", "corner": [-1.8, 0, -1.5], "u": [3.6, 0, 0], "v": [0, 1.8, 0], "material": {"type": "metallic_roughness", "base_color": [0.8, 0.8, 0.8], "metallic": 1, "roughness": 0}},
      {"type": "sphere", "center": [0.6, 1.35, 0.6], "radius": 0.15, "material": {"type": "diffuse_light", "emission": [6, 5, 4]}}
    ]
  })");
}

void expect_metallic_roughness_float_matches_double(const std::string& float_backend) {
  const SceneDescription scene = metallic_roughness_scene();
  ASSERT_TRUE(std::holds_alternative<MetallicRoughness<double>>(scene.materials[0]));
  const SceneCase c{"metallic-roughness", 64, 48, 128, 0, 0, 0};
  const test::PixelStatistics f = statistics_on<float>(float_backend, flatten_scene<float>(scene, case_settings(scene, c, c.samples, 707)));
  const test::PixelStatistics d = statistics_on<double>("cpu", flatten_scene<double>(scene, case_settings(scene, c, c.samples, 808)));
  EXPECT_EQ(f.non_finite, 0u);
  EXPECT_EQ(d.non_finite, 0u);
  expect_blocks_agree(f, d, "float", "double", "metallic-roughness spheres (float on " + float_backend + ")");
}

TEST(MetallicRoughnessRender, FiniteAndFloatMatchesDouble) { expect_metallic_roughness_float_matches_double("cpu"); }

TEST(MetallicRoughnessRender, CudaFiniteAndMatchesCpuDouble) {
#if !PT_HAVE_CUDA
  GTEST_SKIP() << "the CUDA backend is not built (no nvcc)";
#else
  if (cuda_device_count() == 0) GTEST_SKIP() << "no usable GPU on this machine";
  expect_metallic_roughness_float_matches_double("cuda");
#endif
}

// Scale invariance: float keeps the same relative precision at every magnitude, and with rays spawned robustly the
// picture does not depend on where the scene is. Moved 10^4 away from the origin (float's spacing there, 1e-3, is
// far below the scenes' detail) or with every length multiplied by 10^3, a scene must render as the original does
// (neither scene has textures that read the world position): the moved or scaled float render against the original
// scene in double, on the CPU, independent seeds.
class FloatScaleInvariance : public ::testing::TestWithParam<std::string> {};

TEST_P(FloatScaleInvariance, TranslatedBy1e4MatchesOriginalInDouble) {
  const auto start = std::chrono::steady_clock::now();
  const SceneDescription scene = load_case_scene(GetParam());
  const SceneCase& c = scene_case(GetParam());
  const SceneDescription moved = test::translated(scene, {1e4, 1e4, 1e4});
  // Against double where the scene was written: the moved float picture must be the right one, not only the same
  // as an equally wrong float picture at the origin.
  const test::PixelStatistics original = statistics_on<double>("cpu", flatten_scene<double>(scene, case_settings(scene, c, c.moved_samples, 303)));
  const test::PixelStatistics translated = statistics_on<float>("cpu", flatten_scene<float>(moved, case_settings(moved, c, c.moved_samples, 404)));
  expect_blocks_agree(translated, original, "translated float", "original double", GetParam() + " translated by 1e4");
  std::printf("%s translated: %.1f s\n", GetParam().c_str(), seconds_since(start));
}

TEST_P(FloatScaleInvariance, ScaledBy1e3MatchesOriginalInDouble) {
  const auto start = std::chrono::steady_clock::now();
  const SceneDescription scene = load_case_scene(GetParam());
  const SceneCase& c = scene_case(GetParam());
  const test::PixelStatistics original = statistics_on<double>("cpu", flatten_scene<double>(scene, case_settings(scene, c, c.moved_samples, 505)));
  // Scaled in the description, as a file modelled 1000 times larger would be (flatten_scene's own scale would also
  // carry along any setting of a fixed size, and hide a dependence on it).
  const SceneDescription larger = test::scaled(scene, 1e3);
  const test::PixelStatistics scaled = statistics_on<float>("cpu", flatten_scene<float>(larger, case_settings(larger, c, c.moved_samples, 606)));
  expect_blocks_agree(scaled, original, "scaled float", "original double", GetParam() + " scaled by 1e3");
  std::printf("%s scaled: %.1f s\n", GetParam().c_str(), seconds_since(start));
}

INSTANTIATE_TEST_SUITE_P(Scenes, FloatScaleInvariance, ::testing::Values("cornell-box", "precision"), test::scene_test_name);

}  // namespace
}  // namespace pt
