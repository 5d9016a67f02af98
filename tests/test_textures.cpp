// Checks texture lookups: the 3-D checker's cells, and bilinear image lookups over the shared sRGB texel buffer.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "image/image_io.hpp"
#include "kernel/fixed_point.hpp"
#include "test_support.hpp"

namespace pt {
namespace {

using test::to;

template <class T>
Color<T> lookup(const Texture<T>& texture, const TexturePoint<T>& at, const TextureData<T>& data = TextureData<T>{}) {
  return texture_value(texture, at, data);
}

template <class T>
class CheckerTextures : public ::testing::Test {};
using ScalarTypes = ::testing::Types<float, double>;
TYPED_TEST_SUITE(CheckerTextures, ScalarTypes);

// The cells are where the product of the three sines is negative (the seed's definition), computed here in double
// with the sines themselves. Points within a hair of a cell boundary are skipped: there the sign of a sine is a
// matter of rounding.
TYPED_TEST(CheckerTextures, CellsAreWhereTheProductOfSinesIsNegative) {
  using T = TypeParam;
  const Color<T> odd = to<T>({0.2, 0.3, 0.1}), even = to<T>({0.9, 0.9, 0.9});
  std::mt19937 rng(7);
  for (const double frequency : {10.0, 1.0, 0.37}) {
    const Texture<T> checker = CheckerTexture<T>{odd, even, T(frequency / 3.14159265358979323846)};
    std::uniform_real_distribution<double> coordinate(-200.0, 200.0);
    int odd_cells = 0, checked = 0;
    for (int i = 0; i < 20000; ++i) {
      const Vec3<T> p{T(coordinate(rng)), T(coordinate(rng)), T(coordinate(rng))};
      const double sx = std::sin(frequency * double(p.x)), sy = std::sin(frequency * double(p.y)), sz = std::sin(frequency * double(p.z));
      if (std::min({std::abs(sx), std::abs(sy), std::abs(sz)}) < 1e-3) continue;
      const bool expect_odd = sx * sy * sz < 0;
      const Color<T> got = lookup(checker, TexturePoint<T>{T(0), T(0), p});
      ASSERT_EQ(got.x, expect_odd ? odd.x : even.x) << "frequency " << frequency << " at " << p.x << ", " << p.y << ", " << p.z;
      odd_cells += expect_odd;
      ++checked;
    }
    // Both colours occur, about equally often.
    EXPECT_GT(checked, 15000);
    EXPECT_NEAR(double(odd_cells) / checked, 0.5, 0.03);
  }
}

TYPED_TEST(CheckerTextures, CellsAreHalfPeriodsWide) {
  using T = TypeParam;
  const Color<T> odd = to<T>({0, 0, 0}), even = to<T>({1, 1, 1});
  const Texture<T> checker = CheckerTexture<T>{odd, even, T(10 / 3.14159265358979323846)};
  const double cell = 3.14159265358979323846 / 10;
  // Along x, with y and z inside cells where their sines are positive, the colour flips at every multiple of pi/10.
  const T y = T(0.5 * cell), z = T(0.5 * cell);
  for (int k = -6; k <= 6; ++k) {
    const bool odd_cell = (k % 2 + 2) % 2 == 1;
    const Color<T> inside = lookup(checker, TexturePoint<T>{T(0), T(0), Vec3<T>{T((k + 0.5) * cell), y, z}});
    EXPECT_EQ(inside.x, odd_cell ? odd.x : even.x) << "cell " << k;
  }
}

// A 3x2 image whose bytes are all different, in the texel buffer after another image's texels.
struct SmallImage {
  std::vector<u8> texels;
  std::vector<float> decode = srgb_decode_table();
  ImageTexture<float> texture{3, 2, 1, 1.0f, Color<float>::splat(1.0f)};
  SmallImage() {
    texels.assign(3, 255);  // texel 0 belongs to another image
    for (u8 i = 0; i < 18; ++i) texels.push_back(static_cast<u8>(10 * i + 3));
  }
  TextureData<float> data() const { return TextureData<float>{texels.data(), decode.data(), nullptr, nullptr}; }
  // Linear value of channel c of texel (x, y); y = 0 is the top row.
  float texel(int x, int y, int c) const { return decode[texels[3 * (1 + y * 3 + x) + c]]; }
};

// Fixed-point formats may scale a scene's lengths by a power of two (flatten_scene). The marble's veins must stay
// where they are: its stripes read the scaled position times the scaled frequency, and its turbulence the position
// as written (the scaled position times 1 / scale). It used to read the scaled position, which moved the veins.
TEST(NoiseTextures, MarbleVeinsStayInPlaceWhenTheSceneIsScaled) {
  const SceneDescription scene = load_scene_file(test::scene_path("tiny.json"));
  const FlatScene<double> as_written = flatten_scene<double>(scene, scene.render, 1.0);
  const FlatScene<double> scaled = flatten_scene<double>(scene, scene.render, 0.25);
  int marbles = 0;
  for (std::size_t i = 0; i < as_written.textures.size(); ++i) {
    const auto* noise = std::get_if<NoiseTexture<double>>(&as_written.textures[i]);
    if (!noise || noise->kind != NoiseKind::kMarble) continue;
    ++marbles;
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> coordinate(-2.0, 2.0);
    for (int k = 0; k < 200; ++k) {
      const Vec3d p{coordinate(rng), coordinate(rng), coordinate(rng)};
      const Color<double> expected = lookup(as_written.textures[i], TexturePoint<double>{0, 0, p}, as_written.view().texture_data);
      const Color<double> got = lookup(scaled.textures[i], TexturePoint<double>{0, 0, p * 0.25}, scaled.view().texture_data);
      EXPECT_NEAR(got.x, expected.x, 1e-12) << "at " << p.x << ", " << p.y << ", " << p.z;
    }
  }
  EXPECT_EQ(marbles, 1);
}

TEST(ImageTextures, TexelCentresReturnTheDecodedBytes) {
  const SmallImage image;
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 3; ++x) {
      // u = (x + 0.5) / width; v = 1 is the top row.
      const float u = (x + 0.5f) / 3.0f, v = 1.0f - (y + 0.5f) / 2.0f;
      const Color<float> c = image_lookup(image.data(), image.texture, u, v);
      EXPECT_FLOAT_EQ(c.x, image.texel(x, y, 0)) << x << ", " << y;
      EXPECT_FLOAT_EQ(c.y, image.texel(x, y, 1)) << x << ", " << y;
      EXPECT_FLOAT_EQ(c.z, image.texel(x, y, 2)) << x << ", " << y;
    }
}

TEST(ImageTextures, LookupsBlendNeighboursAndWrapAround) {
  const SmallImage image;
  // Halfway between texel centres (0, 0) and (1, 0).
  const Color<float> between = image_lookup(image.data(), image.texture, 1.0f / 3.0f, 0.75f);
  EXPECT_FLOAT_EQ(between.x, 0.5f * (image.texel(0, 0, 0) + image.texel(1, 0, 0)));
  // At u = 0 the left edge lies halfway between the last column and the first (wrap-around), likewise at v = 0.
  const Color<float> corner = image_lookup(image.data(), image.texture, 0.0f, 0.0f);
  const float expected = 0.25f * (image.texel(2, 1, 1) + image.texel(0, 1, 1) + image.texel(2, 0, 1) + image.texel(0, 0, 1));
  EXPECT_NEAR(corner.y, expected, 1e-6f);
  // Whole periods of u and v (and negative ones) give the same value.
  for (const float shift : {1.0f, -1.0f, 7.0f, -12.0f}) {
    const Color<float> shifted = image_lookup(image.data(), image.texture, 1.0f / 3.0f + shift, 0.75f + shift);
    EXPECT_NEAR(shifted.x, between.x, 1e-5f) << shift;
  }
}

// An image wider than a fixed-point format's range (1024 texels in Q10.10, whose largest value is 512) is looked up
// everywhere as double looks it up: the texel position is formed in integers, not as u times the width in the format
// (which saturated at 512 and read the left half of the image for every u beyond it).
TEST(ImageTextures, ImagesWiderThanTheFormatsRangeAreReadAcrossTheirWholeWidthInQ10_10) {
  using Q = Fixed<10, 10>;
  constexpr u32 kWidth = 1024;
  std::vector<u8> texels;
  for (u32 i = 0; i < kWidth; ++i)
    for (const u32 byte : {i & 255u, i >> 2, 255 - (i >> 2)}) texels.push_back(static_cast<u8>(byte));
  const std::vector<float> decode = srgb_decode_table();
  const ImageTexture<double> wide{kWidth, 1, 0, 1.0, Color<double>::splat(1.0), 1};
  const ImageTexture<Q> narrow{kWidth, 1, 0, Q(1), Color<Q>::splat(Q(1)), 1};
  const TextureData<double> data{texels.data(), decode.data(), nullptr, nullptr};
  const TextureData<Q> narrow_data{texels.data(), decode.data(), nullptr, nullptr};
  // u = i / 1024 is exact in both: halfway between the centres of texels i - 1 and i.
  double largest_difference = 0;
  for (u32 i = 0; i < kWidth; ++i) {
    const Color<double> expected = image_lookup(data, wide, i / 1024.0, 0.5);
    const Color<Q> got = image_lookup(narrow_data, narrow, Q::from_raw(static_cast<Q::Storage>(i)), Q(0.5));
    for (int c = 0; c < 3; ++c) largest_difference = std::max(largest_difference, std::abs(static_cast<double>(got[c]) - expected[c]));
  }
  // Q10.10 holds 1/255 as 4/1024 (0.4 % small): up to 4 steps of 2^-10 at byte 255, and one more for the blend.
  EXPECT_LE(largest_difference, 5.0 / 1024);
}

}  // namespace
}  // namespace pt
