// Float renders are the same picture as double renders, and moving or scaling a scene changes no float render, within noise.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include "app/backends.hpp"
#include "test_support.hpp"
#if PT_HAVE_CUDA
#include "backends/cuda/cuda_backend.hpp"
#endif

namespace pt {
namespace {

// The bound. Two renders of one scene with independent seeds differ in a block mean by noise of variance
// var_a + var_b, each var = sum over the block's pixels of (per-sample variance / samples) / pixels^2; the block
// mean averages 256 pixels x 128 or more samples, so it is close to normal. A block and channel fails when
// |mean_a - mean_b| > k sqrt(var_a + var_b) + floor. For a normal difference P(|z| > 5.5) = 3.8e-8; this file
// makes 825 such comparisons on the CPU (1,266 where a GPU adds its own), so the chance that any of them fails
// without a bias is about 5e-5. The per-sample variance is itself estimated from the same samples; with thousands
// of samples per block its relative error is a few percent, small against the margin of k. A single outlier
// sample (a firefly) cannot fail a block: it moves the mean by x / n and the standard deviation by about as much,
// so its z stays near 1.
constexpr double kK = 5.5;
// The floor: blocks whose samples are all alike (an emitter seen directly, a constant background) have zero
// variance, and there the two scalar types differ only by rounding, about 1e-7 relative per operation for float.
// 1e-5 relative plus 1e-6 absolute is far above that and far below an 8-bit step (1 / 255 of display, at least
// 3e-4 in linear radiance near black).
constexpr double kAbsoluteFloor = 1e-6;
constexpr double kRelativeFloor = 1e-5;
constexpr u32 kBlock = 16;

// How each scene is rendered: sizes with 16x16 blocks that cover the picture, and samples enough that a block
// mean is known to a few 8-bit steps. Under the sanitizers (several times slower) the samples are cut, which keeps
// the code paths but weakens the test; release builds run it at full strength.
struct SceneCase {
  const char* name;
  u32 width, height;
  u32 samples;        // float against double
  u32 max_depth;      // 0: the scene's own
  u32 moved_samples;  // the moved and scaled renders against the original (FloatScaleInvariance's scenes)
};

#if PT_TEST_SANITIZED
constexpr u32 kSampleDivisor = 16;
#else
constexpr u32 kSampleDivisor = 1;
#endif

// The Cornell box is the costly one. Float loses light on the front face of the tall block (rays leaving it at
// grazing angles hit it again): about 20% in its lower part, x 32-63, y 64-95 of a 128x128 image. At 64x64 that
// part is one 16x16 block, which gives twice the z of 128x128 for the same work; paths cut at 5 bounces keep the
// loss (most of it is in direct light) and halve the cost.
const std::vector<SceneCase>& scene_cases() {
  static const std::vector<SceneCase> cases = {
      {"tiny", 64, 48, 256, 0, 0},
      {"meshes", 80, 48, 128, 0, 0},
      {"seed-default", 80, 48, 128, 0, 0},
      {"book1-final", 96, 64, 128, 0, 0},
      {"book2-final", 64, 64, 128, 0, 0},
      {"cornell-box", 64, 64, 2048, 5, 512},
      {"cornell-smoke", 64, 64, 128, 0, 0},
      {"precision", 128, 96, 128, 0, 128},
  };
  return cases;
}

const SceneCase& scene_case(const std::string& name) {
  for (const SceneCase& c : scene_cases())
    if (name == c.name) return c;
  throw std::runtime_error("no settings for scene " + name);
}

// Shipped scenes live in scenes/; the precision scene (rotated boxes and thin slabs near x = z = 20000, where
// float's spacing is 2^-9, twice the old fixed t_min; grazing rays over a large floor) in tests/data/.
SceneDescription load_case_scene(const std::string& name) {
  if (name == "precision") return load_scene_file(test::source_dir() / "tests" / "data" / "precision.json");
  return load_scene_file(test::scene_path(name + ".json"));
}

RenderSettings case_settings(const SceneDescription& scene, const SceneCase& c, u32 samples, u32 seed) {
  RenderSettings settings = scene.render;
  settings.width = c.width;
  settings.height = c.height;
  settings.samples_per_pixel = samples / kSampleDivisor;
  if (c.max_depth) settings.max_depth = c.max_depth;
  settings.seed = seed;
  return settings;
}

template <class T>
test::PixelStatistics statistics_on(const std::string& backend_name, const FlatScene<T>& flat) {
  const std::unique_ptr<RenderBackend<T>> backend = make_backend<T>(backend_name, 0, 0);
  return test::backend_sample_statistics(*backend, flat, flat.samples_per_pixel);
}

// Compares two renders block by block and fails, listing the worst blocks, when any is outside the bound.
void expect_blocks_agree(const test::PixelStatistics& a, const test::PixelStatistics& b, const char* name_a, const char* name_b,
                         const std::string& what) {
  const std::vector<test::BlockDifference> blocks = test::compare_block_means(a, b, kBlock, kK, kAbsoluteFloor, kRelativeFloor);
  std::size_t outside = 0;
  for (const test::BlockDifference& d : blocks) outside += !d.within;
  EXPECT_EQ(outside, 0u) << what << ": " << outside << " of " << blocks.size() << " block means differ by more than " << kK
                         << " sigma; the worst:\n"
                         << test::describe_blocks(blocks, 8, name_a, name_b);
  std::printf("%s: worst block z %.2f (%s %.5g, %s %.5g at (%u, %u) %c), %zu of %zu outside\n", what.c_str(), blocks.front().z, name_a,
              blocks.front().mean_a, name_b, blocks.front().mean_b, blocks.front().x, blocks.front().y, "RGB"[blocks.front().channel],
              outside, blocks.size());
}

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
                         ::testing::Values("tiny", "meshes", "seed-default", "book1-final", "book2-final", "cornell-box", "cornell-smoke", "precision"),
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
  const SceneCase c{"metallic-roughness", 64, 48, 128, 0, 0};
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
