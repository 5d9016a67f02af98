// Checks that written PNG, PFM and OpenEXR files read back as the rendered image, and leave no temporary behind.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <stb/stb_image.h>

#include "test_support.hpp"

namespace pt {
namespace {

// A small image whose every value differs, including values outside [0, 1].
LinearImage synthetic_image(u32 width, u32 height) {
  LinearImage image;
  image.width = width;
  image.height = height;
  for (u32 i = 0; i < width * height * 3; ++i) image.rgb.push_back(static_cast<float>(i) * 0.0371f - 0.25f + (i % 7 == 0 ? 3.5f : 0.0f));
  return image;
}

// The first 12 bytes of a file: a PFM header for a one-digit-sized image.
std::string read_text_header(const std::filesystem::path& path) { return test::read_text_file(path).substr(0, 12); }

bool same_bits(const std::vector<float>& a, const std::vector<float>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

unsigned char png_byte(float linear) {
  const float clamped = std::isfinite(linear) ? std::clamp(linear, 0.0f, 1.0f) : 0.0f;
  return static_cast<unsigned char>(std::lround(linear_to_srgb(clamped) * 255.0f));
}

std::vector<unsigned char> read_png(const std::filesystem::path& path, int& width, int& height) {
  int channels = 0;
  unsigned char* data = stbi_load(path.c_str(), &width, &height, &channels, 3);
  if (!data) return {};
  std::vector<unsigned char> bytes(data, data + static_cast<std::size_t>(width) * height * 3);
  stbi_image_free(data);
  EXPECT_EQ(channels, 3);
  return bytes;
}

LinearImage read_exr(const std::filesystem::path& path) {
  Imf::InputFile file(path.c_str());
  const Imath::Box2i window = file.header().dataWindow();
  LinearImage image;
  image.width = static_cast<u32>(window.max.x - window.min.x + 1);
  image.height = static_cast<u32>(window.max.y - window.min.y + 1);
  image.rgb.resize(static_cast<std::size_t>(image.width) * image.height * 3);
  const std::size_t x_stride = 3 * sizeof(float), y_stride = x_stride * image.width;
  char* base = reinterpret_cast<char*>(image.rgb.data()) - window.min.x * x_stride - window.min.y * y_stride;
  Imf::FrameBuffer frame;
  frame.insert("R", Imf::Slice(Imf::FLOAT, base, x_stride, y_stride));
  frame.insert("G", Imf::Slice(Imf::FLOAT, base + sizeof(float), x_stride, y_stride));
  frame.insert("B", Imf::Slice(Imf::FLOAT, base + 2 * sizeof(float), x_stride, y_stride));
  file.setFrameBuffer(frame);
  file.readPixels(window.min.y, window.max.y);
  return image;
}

TEST(OutputFilesReadBack, PfmIsExactWithRowsFromTheTop) {
  test::TempDir dir;
  const LinearImage image = synthetic_image(5, 3);
  write_image(dir / "image.pfm", image);
  EXPECT_EQ(read_text_header(dir / "image.pfm"), "PF\n5 3\n-1.0\n");
  EXPECT_EQ(std::filesystem::file_size(dir / "image.pfm"), std::string("PF\n5 3\n-1.0\n").size() + 5 * 3 * 3 * sizeof(float));
  const LinearImage back = test::read_pfm(dir / "image.pfm");
  EXPECT_EQ(back.width, 5u);
  EXPECT_EQ(back.height, 3u);
  EXPECT_TRUE(same_bits(back.rgb, image.rgb));
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"image.pfm"});
}

TEST(OutputFilesReadBack, PngIsEightBitSrgbClampedWithRowsFromTheTop) {
  test::TempDir dir;
  LinearImage image;
  image.width = 4;
  image.height = 2;
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  image.rgb = {0.0f,  0.0031308f, 0.2f,  0.5f,  1.0f,  2.0f,  -1.0f, nan,  inf,  0.01f, 0.7f, 0.99f,  // top row
               0.25f, 0.25f,      0.25f, 0.75f, 0.75f, 0.75f, 0.0f,  1.0f, 0.0f, 0.1f,  0.2f, 0.3f};
  write_image(dir / "image.png", image);
  int width = 0, height = 0;
  const std::vector<unsigned char> bytes = read_png(dir / "image.png", width, height);
  ASSERT_EQ(width, 4);
  ASSERT_EQ(height, 2);
  ASSERT_EQ(bytes.size(), image.rgb.size());
  for (std::size_t i = 0; i < bytes.size(); ++i) EXPECT_EQ(bytes[i], png_byte(image.rgb[i])) << "value " << i;
  // Known points of the sRGB curve: linear 0.5 is 188, 0.2 is 124; clamping and NaN.
  EXPECT_EQ(bytes[3], 188);
  EXPECT_EQ(bytes[2], 124);
  EXPECT_EQ(bytes[5], 255);
  EXPECT_EQ(bytes[6], 0);
  EXPECT_EQ(bytes[7], 0);
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"image.png"});
}

// The encoder deflates bands of 32 rows on separate threads and joins them into one stream, split into IDAT chunks
// of 1 MiB: an image of many bands, a last band that is not full, and noise that does not compress (so the data
// spans several chunks) must read back byte for byte.
TEST(OutputFilesReadBack, PngOfManyBandsAndChunksReadsBackExactly) {
  test::TempDir dir;
  LinearImage image;
  image.width = 1031;
  image.height = 421;  // 13 full bands of 32 rows and one of 5
  image.rgb.resize(static_cast<std::size_t>(image.width) * image.height * 3);
  u32 state = 12345;
  for (float& v : image.rgb) {
    state = state * 1664525u + 1013904223u;
    v = static_cast<float>(state >> 8) * 0x1p-24f * 1.2f;  // some above 1, to be clamped
  }
  write_image(dir / "noise.png", image);
  EXPECT_GT(std::filesystem::file_size(dir / "noise.png"), 1u << 20);
  int width = 0, height = 0;
  const std::vector<unsigned char> bytes = read_png(dir / "noise.png", width, height);
  ASSERT_EQ(width, 1031);
  ASSERT_EQ(height, 421);
  ASSERT_EQ(bytes.size(), image.rgb.size());
  std::size_t mismatches = 0;
  for (std::size_t i = 0; i < bytes.size(); ++i) mismatches += bytes[i] != png_byte(image.rgb[i]);
  EXPECT_EQ(mismatches, 0u);
}

TEST(OutputFilesReadBack, ExrHasTheMagicNumberAndExactFloats) {
  test::TempDir dir;
  const LinearImage image = synthetic_image(7, 4);
  write_image(dir / "image.exr", image);
  const std::string bytes = test::read_text_file(dir / "image.exr");
  ASSERT_GT(bytes.size(), 4u);
  // 20000630 = 0x01312f76, stored little-endian.
  EXPECT_EQ(static_cast<unsigned char>(bytes[0]), 0x76);
  EXPECT_EQ(static_cast<unsigned char>(bytes[1]), 0x2f);
  EXPECT_EQ(static_cast<unsigned char>(bytes[2]), 0x31);
  EXPECT_EQ(static_cast<unsigned char>(bytes[3]), 0x01);
  const LinearImage back = read_exr(dir / "image.exr");
  EXPECT_EQ(back.width, 7u);
  EXPECT_EQ(back.height, 4u);
  EXPECT_TRUE(same_bits(back.rgb, image.rgb));
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"image.exr"});
}

TEST(OutputFilesReadBack, RenderedImageInAllThreeFormats) {
  test::TempDir dir;
  const FlatScene<float> scene = test::tiny_reference_scene<float>(2, 3);
  const LinearImage image = test::render(scene, 2).image;
  for (const char* name : {"render.png", "render.pfm", "render.exr"}) write_image(dir / name, image);
  EXPECT_EQ(dir.entries(), (std::vector<std::string>{"render.exr", "render.pfm", "render.png"}));
  EXPECT_TRUE(same_bits(test::read_pfm(dir / "render.pfm").rgb, image.rgb));
  EXPECT_TRUE(same_bits(read_exr(dir / "render.exr").rgb, image.rgb));
  int width = 0, height = 0;
  const std::vector<unsigned char> bytes = read_png(dir / "render.png", width, height);
  ASSERT_EQ(width, 64);
  ASSERT_EQ(height, 48);
  int mismatches = 0;
  for (std::size_t i = 0; i < bytes.size(); ++i) mismatches += bytes[i] != png_byte(image.rgb[i]);
  EXPECT_EQ(mismatches, 0);
}

TEST(OutputFilesReadBack, RewritingReplacesTheFile) {
  test::TempDir dir;
  write_image(dir / "image.pfm", synthetic_image(5, 3));
  const LinearImage second = synthetic_image(2, 2);
  write_image(dir / "image.pfm", second);
  EXPECT_TRUE(same_bits(test::read_pfm(dir / "image.pfm").rgb, second.rgb));
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"image.pfm"});
}

TEST(FailedImageWrite, LeavesNoFileAndNamesThePath) {
  test::TempDir dir;
  const LinearImage image = synthetic_image(3, 2);
  // A folder that does not exist.
  const std::filesystem::path nowhere = dir / "missing" / "image.png";
  try {
    write_image(nowhere, image);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(nowhere.string() + ": cannot write the image", 0), 0u) << e.what();
  }
  // A folder standing where the file should go: the temporary is written, the rename fails, the temporary goes.
  for (const char* name : {"taken.png", "taken.pfm", "taken.exr"}) {
    std::filesystem::create_directory(dir / name);
    EXPECT_THROW(write_image(dir / name, image), InputError) << name;
    EXPECT_TRUE(std::filesystem::is_empty(dir / name));
  }
  EXPECT_EQ(dir.entries(), (std::vector<std::string>{"taken.exr", "taken.pfm", "taken.png"}));
}

TEST(ImageFormatFromExtension, KnownExtensionsInAnyCaseOthersRejected) {
  EXPECT_EQ(image_format_for("a.png"), ImageFormat::kPng);
  EXPECT_EQ(image_format_for("dir.x/a.PNG"), ImageFormat::kPng);
  EXPECT_EQ(image_format_for("a.Pfm"), ImageFormat::kPfm);
  EXPECT_EQ(image_format_for("a.exr"), ImageFormat::kExr);
  for (const char* bad : {"a.jpg", "a", "a.png.txt", "png"}) {
    try {
      image_format_for(bad);
      FAIL() << bad;
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()).rfind(std::string(bad) + ": unknown image extension", 0), 0u) << e.what();
    }
  }
}

TEST(TextureImages, PngKeepsItsSrgbBytesAndDecodesToLinear) {
  test::TempDir dir;
  const LinearImage image = synthetic_image(6, 5);
  write_image(dir / "texture.png", image);
  const TextureImage back = read_texture_image(dir / "texture.png");
  ASSERT_EQ(back.width, 6u);
  ASSERT_EQ(back.height, 5u);
  ASSERT_EQ(back.srgb.size(), image.rgb.size());
  const std::vector<float> decode = srgb_decode_table();
  ASSERT_EQ(decode.size(), 256u);
  for (std::size_t i = 0; i < image.rgb.size(); ++i) {
    // Exactly the byte written, and its decoded value close to the original (8-bit sRGB steps are at most 0.013
    // in linear).
    EXPECT_EQ(back.srgb[i], png_byte(image.rgb[i])) << i;
    EXPECT_EQ(decode[back.srgb[i]], srgb_to_linear(back.srgb[i] / 255.0f)) << i;
    EXPECT_NEAR(decode[back.srgb[i]], std::clamp(image.rgb[i], 0.0f, 1.0f), 0.007) << i;
  }
}

// Every channel layout reads as RGB the way stb_image converts it: grey repeated, alpha dropped. A 16-bit grey PGM
// once read past stb_image's buffer (found by fuzz/fuzz_texture_image). Its 16-bit samples have equal bytes here:
// the system's stb_image (2.27) reads them little-endian, not big-endian as Netpbm has them.
TEST(TextureImages, GreyAlphaAndSixteenBitFilesReadAsRgb) {
  test::TempDir dir;
  const std::string grey16 = std::string("P5\n3 1\n65535\n") + std::string("\x12\x12\xab\xab\xff\xff", 6);
  test::write_text_file(dir / "grey16.pgm", grey16);
  TextureImage image = read_texture_image(dir / "grey16.pgm");
  ASSERT_EQ(image.width, 3u);
  ASSERT_EQ(image.height, 1u);
  EXPECT_EQ(image.srgb, (std::vector<u8>{0x12, 0x12, 0x12, 0xab, 0xab, 0xab, 0xff, 0xff, 0xff}));
  const std::string rgb16 = std::string("P6\n1 1\n65535\n") + std::string("\x12\x12\xab\xab\xff\xff", 6);
  test::write_text_file(dir / "rgb16.ppm", rgb16);
  image = read_texture_image(dir / "rgb16.ppm");
  EXPECT_EQ(image.srgb, (std::vector<u8>{0x12, 0xab, 0xff}));
  const std::string grey8 = std::string("P5\n2 1\n255\n") + std::string("\x07\xf0", 2);
  test::write_text_file(dir / "grey8.pgm", grey8);
  image = read_texture_image(dir / "grey8.pgm");
  EXPECT_EQ(image.srgb, (std::vector<u8>{0x07, 0x07, 0x07, 0xf0, 0xf0, 0xf0}));
  // 24-bit TGA (bottom-up, BGR) and 32-bit TGA with alpha: 2x1 texels each.
  const auto tga = [](int bits, const std::string& pixels) {
    std::string header(18, '\0');
    header[2] = 2;  // uncompressed true colour
    header[12] = 2;
    header[14] = 1;
    header[16] = static_cast<char>(bits);
    return header + pixels;
  };
  test::write_text_file(dir / "rgba.tga", tga(32, std::string("\x03\x02\x01\x80\x30\x20\x10\x00", 8)));
  image = read_texture_image(dir / "rgba.tga");
  EXPECT_EQ(image.srgb, (std::vector<u8>{0x01, 0x02, 0x03, 0x10, 0x20, 0x30}));
}

// Images embedded in model files go through the same decoding, size checks and limits as image files.
TEST(TextureImages, FromMemoryMatchesTheFileAndKeepsItsLimits) {
  test::TempDir dir;
  write_image(dir / "texture.png", synthetic_image(6, 5));
  const std::string bytes = test::read_text_file(dir / "texture.png");
  const std::span<const u8> span(reinterpret_cast<const u8*>(bytes.data()), bytes.size());
  const TextureImage from_file = read_texture_image(dir / "texture.png");
  const TextureImage from_memory = read_texture_image_from_memory(span, "model.glb: /images/0");
  EXPECT_EQ(from_memory.width, 6u);
  EXPECT_EQ(from_memory.height, 5u);
  EXPECT_EQ(from_memory.srgb, from_file.srgb);
  // A PNG header claiming 20000x20000 texels, refused from the header.
  std::string huge = bytes.substr(0, 33);
  for (const int at : {16, 20}) {
    huge[at] = 0, huge[at + 1] = 0, huge[at + 2] = static_cast<char>(20000 >> 8), huge[at + 3] = static_cast<char>(20000 & 255);
  }
  const auto expect_error = [](const std::string& data, const std::string& part) {
    try {
      read_texture_image_from_memory(std::span<const u8>(reinterpret_cast<const u8*>(data.data()), data.size()), "model.glb: /images/3");
      ADD_FAILURE() << part;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  };
  expect_error(huge, "image 'model.glb: /images/3' is 20000x20000 texels, larger than a texture may be");
  expect_error("", "cannot read image 'model.glb: /images/3': it is empty");
  expect_error("plain text", "cannot read image 'model.glb: /images/3'");
}

TEST(TextureImages, SrgbCurvesAreInverse) {
  for (int i = 0; i <= 1000; ++i) {
    const float x = i / 1000.0f;
    EXPECT_NEAR(srgb_to_linear(linear_to_srgb(x)), x, 2e-6f) << x;
  }
  EXPECT_NEAR(linear_to_srgb(0.5f), 0.7354f, 1e-4f);
  EXPECT_NEAR(srgb_to_linear(0.5f), 0.2140f, 1e-4f);
}

// The PNG writer's bytes come from a table of the 255 values where the byte steps up, not from the power: they
// must be the power's own, rounded. Checked where they could differ (a few hundred floats either side of every
// step, in their bit order), at a million values spread over 0..1, and beyond it.
TEST(ImageOutput, SrgbByteIsTheRoundedTransferFunction) {
  u32 checked = 0;
  for (int byte = 0; byte < 256; ++byte) {
    // The first float at or above the value whose curve is halfway to the next byte, and its neighbours.
    const float middle = srgb_to_linear((byte + 0.5f) / 255.0f);
    const u32 bits = std::bit_cast<u32>(std::min(middle, 1.0f));
    for (u32 k = bits > 300 ? bits - 300 : 0; k <= bits + 300 && k <= std::bit_cast<u32>(1.0f); ++k, ++checked)
      ASSERT_EQ(linear_to_srgb_byte(std::bit_cast<float>(k)), png_byte(std::bit_cast<float>(k))) << std::bit_cast<float>(k);
  }
  for (u32 i = 0; i <= 1000000; ++i, ++checked) {
    const float x = static_cast<float>(i) / 1000000.0f;
    ASSERT_EQ(linear_to_srgb_byte(x), png_byte(x)) << x;
  }
  for (const float x : {-1.0f, -0.0f, 0.0f, 1e-30f, 1.0f, 1.5f, 1e30f, std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(),
                        std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::denorm_min()})
    EXPECT_EQ(linear_to_srgb_byte(x), png_byte(x)) << x;
  EXPECT_GT(checked, 1100000u);
}

TEST(TextureImages, MissingOrInvalidFilesAreInputErrors) {
  test::TempDir dir;
  try {
    read_texture_image(dir / "absent.png");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("does not exist"), std::string::npos) << e.what();
  }
  test::write_text_file(dir / "text.png", "plain text");
  EXPECT_THROW(read_texture_image(dir / "text.png"), InputError);
  // A PFM is not an 8-bit texture format.
  write_image(dir / "float.pfm", synthetic_image(2, 2));
  EXPECT_THROW(read_texture_image(dir / "float.pfm"), InputError);
}

}  // namespace
}  // namespace pt
