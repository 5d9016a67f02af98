// The shipped scenes as the statistical tests render them (size, samples, depth), and the block-mean comparison of
// two renders within a bound derived from their variance.
#pragma once

#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "backends/registry.hpp"
#include "test_support.hpp"

namespace pt::test {

// The bound. Two renders of one scene with independent seeds differ in a block mean by noise of variance
// var_a + var_b, each var = sum over the block's pixels of (per-sample variance / samples) / pixels^2; the block
// mean averages 256 pixels x 128 or more samples, so it is close to normal. A block and channel fails when
// |mean_a - mean_b| > k sqrt(var_a + var_b) + floor. For a normal difference P(|z| > 5.5) = 3.8e-8; the suite
// makes about 2,000 such comparisons on the CPU (float against double, next-event estimation against none), so the
// chance that any of them fails without a bias is about 1e-4. The per-sample variance is itself estimated from the same samples; with thousands
// of samples per block its relative error is a few percent, small against the margin of k. A single outlier
// sample (a firefly) cannot fail a block: it moves the mean by x / n and the standard deviation by about as much,
// so its z stays near 1.
inline constexpr double kK = 5.5;
// The floor: blocks whose samples are all alike (an emitter seen directly, a constant background) have zero
// variance, and there the two scalar types differ only by rounding, about 1e-7 relative per operation for float.
// 1e-5 relative plus 1e-6 absolute is far above that and far below an 8-bit step (1 / 255 of display, at least
// 3e-4 in linear radiance near black).
inline constexpr double kAbsoluteFloor = 1e-6;
inline constexpr double kRelativeFloor = 1e-5;
inline constexpr u32 kBlock = 16;

// How each scene is rendered: sizes with 16x16 blocks that cover the picture, and samples enough that a block
// mean is known to a few 8-bit steps. Under the sanitizers (several times slower) the samples are cut, which keeps
// the code paths but weakens the test; release builds run it at full strength.
struct SceneCase {
  const char* name;
  u32 width, height;
  u32 samples;        // float against double
  u32 max_depth;      // 0: the scene's own
  u32 moved_samples;  // the moved and scaled renders against the original (FloatScaleInvariance's scenes)
  u32 nee_samples;    // next-event estimation against none (0: `samples`)
};

#if PT_TEST_SANITIZED
inline constexpr u32 kSampleDivisor = 16;
#else
inline constexpr u32 kSampleDivisor = 1;
#endif

// The Cornell box is the costly one. Float loses light on the front face of the tall block (rays leaving it at
// grazing angles hit it again): about 20% in its lower part, x 32-63, y 64-95 of a 128x128 image. At 64x64 that
// part is one 16x16 block, which gives twice the z of 128x128 for the same work; paths cut at 5 bounces keep the
// loss (most of it is in direct light) and halve the cost.
inline const std::vector<SceneCase>& scene_cases() {
  static const std::vector<SceneCase> cases = {
      {"tiny", 64, 48, 256, 0, 0, 0},          {"meshes", 80, 48, 128, 0, 0, 0},       {"seed-default", 80, 48, 128, 0, 0, 0},
      {"book1-final", 96, 64, 128, 0, 0, 0},   {"book2-final", 64, 64, 128, 0, 0, 0},  {"cornell-box", 64, 64, 2048, 5, 512, 512},
      {"cornell-smoke", 64, 64, 128, 0, 0, 0}, {"precision", 128, 96, 128, 0, 128, 0},
  };
  return cases;
}

inline const SceneCase& scene_case(const std::string& name) {
  for (const SceneCase& c : scene_cases())
    if (name == c.name) return c;
  throw std::runtime_error("no settings for scene " + name);
}

// Shipped scenes live in scenes/; the precision scene (rotated boxes and thin slabs near x = z = 20000, where
// float's spacing is 2^-9, twice the old fixed t_min; grazing rays over a large floor) in tests/data/.
inline SceneDescription load_case_scene(const std::string& name) {
  if (name == "precision") return load_scene_file(source_dir() / "tests" / "data" / "precision.json");
  return load_scene_file(scene_path(name + ".json"));
}

inline RenderSettings case_settings(const SceneDescription& scene, const SceneCase& c, u32 samples, u32 seed) {
  RenderSettings settings = scene.render;
  settings.width = c.width;
  settings.height = c.height;
  settings.samples_per_pixel = samples / kSampleDivisor;
  if (c.max_depth) settings.max_depth = c.max_depth;
  settings.seed = seed;
  return settings;
}

template <class T>
PixelStatistics statistics_on(const std::string& backend_name, const FlatScene<T>& flat) {
  const std::unique_ptr<RenderBackend<T>> backend = make_backend<T>(backend_name, 0, 0);
  return backend_sample_statistics(*backend, flat, flat.samples_per_pixel);
}

// Compares two renders block by block and fails, listing the worst blocks, when any is outside the bound.
inline void expect_blocks_agree(const PixelStatistics& a, const PixelStatistics& b, const char* name_a, const char* name_b, const std::string& what) {
  const std::vector<BlockDifference> blocks = compare_block_means(a, b, kBlock, kK, kAbsoluteFloor, kRelativeFloor);
  std::size_t outside = 0;
  for (const BlockDifference& d : blocks) outside += !d.within;
  EXPECT_EQ(outside, 0u) << what << ": " << outside << " of " << blocks.size() << " block means differ by more than " << kK << " sigma; the worst:\n"
                         << describe_blocks(blocks, 8, name_a, name_b);
  std::printf("%s: worst block z %.2f (%s %.5g, %s %.5g at (%u, %u) %c), %zu of %zu outside\n", what.c_str(), blocks.front().z, name_a,
              blocks.front().mean_a, name_b, blocks.front().mean_b, blocks.front().x, blocks.front().y, "RGB"[blocks.front().channel], outside,
              blocks.size());
}

}  // namespace pt::test
