// Image files cut short, in every format stb_image reads: each is refused on one line naming the image, never
// decoded with zeros or uninitialised memory in place of the missing texels, and never left looping.
#include <signal.h>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <stb/stb_image_write.h>

#include "image/image_data_check.hpp"
#include "image/image_io.hpp"
#include "test_support.hpp"

// A namespace of its own: the test files are compiled several to a source (tests/CMakeLists.txt).
namespace pt::truncated_images {
namespace {

constexpr int kWidth = 8, kHeight = 6;  // 8 x 3 bytes a row: no BMP padding; at least 8 wide: run-length HDR

// Texels with some runs and some noise, so that run-length encoders write both kinds of packet.
std::vector<u8> texels(int channels, int width = kWidth) {
  std::vector<u8> bytes(static_cast<std::size_t>(width) * kHeight * channels);
  u32 state = 12345;
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    state = state * 1664525u + 1013904223u;
    bytes[i] = (i / channels) % 3 == 0 ? static_cast<u8>(40 * (i % channels)) : static_cast<u8>(state >> 24);
  }
  return bytes;
}

void append(void* context, void* data, int size) {
  static_cast<std::string*>(context)->append(static_cast<const char*>(data), static_cast<std::size_t>(size));
}

std::string written(const std::function<int(std::string*)>& write) {
  std::string bytes;
  EXPECT_NE(write(&bytes), 0);
  return bytes;
}

std::string png() {
  const std::vector<u8> pixels = texels(3);
  return written([&](std::string* out) { return stbi_write_png_to_func(append, out, kWidth, kHeight, 3, pixels.data(), kWidth * 3); });
}
std::string bmp() {
  const std::vector<u8> pixels = texels(3);
  return written([&](std::string* out) { return stbi_write_bmp_to_func(append, out, kWidth, kHeight, 3, pixels.data()); });
}
std::string tga(bool run_length) {
  const std::vector<u8> pixels = texels(3);
  const int before = stbi_write_tga_with_rle;
  stbi_write_tga_with_rle = run_length ? 1 : 0;
  std::string bytes = written([&](std::string* out) { return stbi_write_tga_to_func(append, out, kWidth, kHeight, 3, pixels.data()); });
  stbi_write_tga_with_rle = before;
  return bytes;
}
std::string jpeg() {
  const std::vector<u8> pixels = texels(3);
  return written([&](std::string* out) { return stbi_write_jpg_to_func(append, out, kWidth, kHeight, 3, pixels.data(), 90); });
}
// Width 8 is written as run-length scanlines, width 7 as flat pixels.
std::string radiance(int width) {
  const std::vector<u8> bytes = texels(3, width);
  std::vector<float> pixels(bytes.begin(), bytes.end());
  for (float& p : pixels) p /= 64.0f;
  return written([&](std::string* out) { return stbi_write_hdr_to_func(append, out, width, kHeight, 3, pixels.data()); });
}
std::string ppm() {
  const std::vector<u8> pixels = texels(3);
  return "P6\n# a comment\n8 6\n255\n" + std::string(pixels.begin(), pixels.end());
}
std::string pgm16() {
  const std::vector<u8> pixels = texels(2);
  return "P5\n8 6\n65535\n" + std::string(pixels.begin(), pixels.end());
}
// Photoshop RGB, three channel planes or four with alpha, 8 bits (plain or as PackBits rows, each row one literal
// packet) or 16 (plain). With alpha, the colours are composited over white, as stb_image takes them.
std::vector<u8> psd_planes(int channels) {
  std::vector<u8> planes = texels(channels);
  if (channels < 4) return planes;
  const std::size_t pixels = kWidth * kHeight;
  for (std::size_t i = 0; i < pixels; ++i) {
    const unsigned alpha = i % 4 == 0 ? 255 : i % 4 == 1 ? 0 : 1 + (planes[3 * pixels + i] % 254);
    planes[3 * pixels + i] = static_cast<u8>(alpha);
    for (std::size_t c = 0; c < 3; ++c) planes[c * pixels + i] = static_cast<u8>(255 - alpha + planes[c * pixels + i] * alpha / 255);
  }
  return planes;
}
std::string psd(bool run_length, int channels = 3, int depth = 8, const std::vector<u8>& planes = {}) {
  std::string bytes = "8BPS";
  const auto be16 = [&](unsigned v) { bytes += static_cast<char>(v >> 8), bytes += static_cast<char>(v & 255); };
  const auto be32 = [&](u32 v) { be16(v >> 16), be16(v & 0xffff); };
  be16(1);
  bytes.append(6, '\0');
  be16(channels), be32(kHeight), be32(kWidth), be16(depth), be16(3);
  be32(0), be32(0), be32(0);  // colour mode data, image resources, layers
  be16(run_length ? 1 : 0);
  const std::vector<u8> samples = planes.empty() ? psd_planes(channels) : planes;
  if (!run_length) {
    for (const u8 sample : samples) {
      if (depth == 16)
        be16(sample * 257u);
      else
        bytes += static_cast<char>(sample);
    }
    return bytes;
  }
  for (int row = 0; row < channels * kHeight; ++row) be16(kWidth + 1);
  for (int row = 0; row < channels * kHeight; ++row) {
    bytes += static_cast<char>(kWidth - 1);
    bytes.append(reinterpret_cast<const char*>(samples.data()) + row * kWidth, kWidth);
  }
  return bytes;
}
// One texel, white, from a two-entry global colour table; the last byte is the trailer, which stb does not need.
std::string gif() {
  return std::string("GIF89a\x01\x00\x01\x00\x80\x00\x00\xff\xff\xff\x00\x00\x00\x2c\x00\x00\x00\x00\x01\x00\x01\x00\x00\x02\x02\x44\x01\x00\x3b",
                     35);
}

struct Format {
  const char* name;
  std::string bytes;
  std::size_t needed;  // the bytes stb needs of it: a cut anywhere before this is refused
};

std::vector<Format> formats() {
  std::vector<Format> all;
  const auto add = [&](const char* name, std::string bytes, std::size_t unneeded_tail = 0) {
    const std::size_t needed = bytes.size() - unneeded_tail;
    all.push_back({name, std::move(bytes), needed});
  };
  add("png", png(), 12);  // the IEND chunk: stb stops at its type
  add("bmp", bmp());
  add("tga", tga(false));
  add("rle.tga", tga(true));
  add("jpg", jpeg());
  add("rle.hdr", radiance(8));
  add("flat.hdr", radiance(7));
  add("ppm", ppm());
  add("16.pgm", pgm16());
  add("psd", psd(false));
  add("rle.psd", psd(true));
  add("alpha.psd", psd(false, 4));
  add("alpha.rle.psd", psd(true, 4));
  add("alpha.16.psd", psd(false, 4, 16));
  add("gif", gif(), 1);
  return all;
}

std::span<const u8> span_of(const std::string& bytes) { return {reinterpret_cast<const u8*>(bytes.data()), bytes.size()}; }

TEST(TruncatedImages, EveryFormatReadsWholeAndIsRefusedWhenCutAnywhere) {
  for (const Format& format : formats()) {
    SCOPED_TRACE(format.name);
    ASSERT_FALSE(image_data_problem(span_of(format.bytes)).has_value()) << *image_data_problem(span_of(format.bytes));
    if (std::string(format.name).ends_with("hdr")) {
      test::TempDir dir;
      test::write_text_file(dir / format.name, format.bytes);
      EXPECT_EQ(read_environment_image(dir / format.name).width, std::string(format.name) == "flat.hdr" ? 7u : 8u);
    } else {
      const TextureImage whole = read_texture_image_from_memory(span_of(format.bytes), format.name);
      EXPECT_EQ(whole.width * whole.height, std::string(format.name) == "gif" ? 1u : u32{kWidth * kHeight});
    }
    // From a file too, cut by one byte and by a quarter: files and memory take the same checks.
    for (const std::size_t cut : {format.needed - 1, format.needed * 3 / 4}) {
      test::TempDir dir;
      test::write_text_file(dir / format.name, format.bytes.substr(0, cut));
      const bool radiance = std::string(format.name).ends_with("hdr");
      EXPECT_THROW(radiance ? (void)read_environment_image(dir / format.name) : (void)read_texture_image(dir / format.name), InputError) << cut;
    }
    for (std::size_t cut = 1; cut < format.needed; ++cut) {
      const std::string part = format.bytes.substr(0, cut);
      try {
        read_texture_image_from_memory(span_of(part), format.name);
        ADD_FAILURE() << "accepted when cut to " << cut << " of " << format.bytes.size() << " bytes";
      } catch (const InputError& e) {
        const std::string message = e.what();
        EXPECT_NE(message.find("image '" + std::string(format.name) + "'"), std::string::npos) << message;
        EXPECT_EQ(message.find('\n'), std::string::npos) << message;
      }
    }
  }
}

// The bytes that make stb_image 2.27 loop for ever (CVE-2021-42715): a Radiance header, then the start of one
// run-length scanline and the end of the file; and a scanline with a run of length 0. Both are refused as
// environments and as textures; a header without pixels is refused too.
TEST(TruncatedImages, RadianceScanlinesThatWouldNeverEndAreRefused) {
  test::TempDir dir;
  const std::string header = "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 32 +X 64\n";
  // A header line that starts with a NUL byte ends the header for stb (it reads lines as C strings): the size line
  // is the one after it, and the scanline's run-length data ends early (found by fuzz/fuzz_texture_image, a hang).
  const std::string nul_line = std::string(
      "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\0\0\n-Y 1 +X 64\n\x02\x02\x00\x40"
      "1\n2#\n\n-Y 1 +X 1\n",
      68);
  const std::string cases[] = {header + std::string("\x02\x02\x00\x40", 4), header + std::string("\x02\x02\x00\x40\x00\x00", 6), header, nul_line};
  const char* expected[] = {"truncated: Radiance scanline 1 of 32", "corrupt: Radiance scanline 1 has a run of length 0", "truncated",
                            "truncated: Radiance scanline 1 of 1"};
  for (int i = 0; i < 4; ++i) {
    test::write_text_file(dir / "sky.hdr", cases[i]);
    try {
      read_environment_image(dir / "sky.hdr");
      ADD_FAILURE() << i;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("cannot read image file '" + (dir / "sky.hdr").string() + "': " + expected[i]), std::string::npos)
          << e.what();
    }
    EXPECT_THROW(read_texture_image(dir / "sky.hdr"), InputError) << i;
    EXPECT_THROW(read_texture_image_from_memory(span_of(cases[i]), "sky"), InputError) << i;
  }
}

// A PNM header whose numbers have more digits than an int holds: stb_image 2.27 read them into an int, overflowing
// (undefined behaviour, found by fuzz/fuzz_texture_image), before any size was checked. Refused from the header,
// as textures and as environments; so is a header that does not end within its first 64 KiB of comments.
TEST(TruncatedImages, PnmHeaderNumbersBeyondAnImagesSizeAreRefusedBeforeStbReadsThem) {
  test::TempDir dir;
  const std::string cases[] = {"P5" + std::string(122, '3') + "\n16\t", "P6 16 " + std::string(40, '9') + " 255\n",
                               "P5 16 16 " + std::string(30, '7') + "\n", "P5\n#" + std::string(70000, 'c') + "\n16 16 255\n"};
  const char* expected[] = {"corrupt: the PNM's width is more than 16777216", "corrupt: the PNM's height is more than 16777216",
                            "corrupt: the PNM's largest value is more than 16777216", "corrupt: the PNM header runs past its first 65536 bytes"};
  for (int i = 0; i < 4; ++i) {
    SCOPED_TRACE(i);
    test::write_text_file(dir / "big.pgm", cases[i]);
    for (const bool environment : {false, true}) {
      try {
        if (environment)
          read_environment_image(dir / "big.pgm");
        else
          read_texture_image(dir / "big.pgm");
        ADD_FAILURE() << "accepted";
      } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("cannot read image file '" + (dir / "big.pgm").string() + "': " + expected[i]), std::string::npos)
            << e.what();
      }
    }
    EXPECT_THROW(read_texture_image_from_memory(span_of(cases[i]), "big"), InputError);
  }
}

// Empty IDAT chunks are legal PNG; stb_image 2.27 copied the first one's zero bytes into a buffer not yet allocated
// (memcpy to a null pointer, reported by UBSan in fuzz/fuzz_texture_image, whose corpus holds that file). They are
// left out before stb decodes: the texels are those of the PNG without them.
TEST(TruncatedImages, EmptyPngDataChunksAreLeftOutBeforeDecoding) {
  const std::string whole = png();
  const std::string empty_idat("\0\0\0\0IDAT\x35\xaf\x06\x1e", 12);
  std::string with_empty = whole;
  with_empty.insert(33, empty_idat);                      // after the signature (8 bytes) and the IHDR chunk (25)
  with_empty.insert(with_empty.size() - 12, empty_idat);  // and before IEND
  ASSERT_EQ(with_empty.substr(45, 8).substr(4), "IDAT");
  const std::optional<std::vector<u8>> kept = png_without_empty_data_chunks(span_of(with_empty));
  ASSERT_TRUE(kept.has_value());
  EXPECT_EQ(std::string(kept->begin(), kept->end()), whole);
  EXPECT_FALSE(png_without_empty_data_chunks(span_of(whole)).has_value());
  const TextureImage a = read_texture_image_from_memory(span_of(whole), "whole"), b = read_texture_image_from_memory(span_of(with_empty), "empty");
  EXPECT_EQ(a.srgb, b.srgb);
  // The file may end inside the empty chunk's check value: the chunk is left out as far as it goes.
  const std::string cut = whole.substr(0, 33) + empty_idat.substr(0, 10);
  const std::optional<std::vector<u8>> cut_kept = png_without_empty_data_chunks(span_of(cut));
  ASSERT_TRUE(cut_kept.has_value());
  EXPECT_EQ(std::string(cut_kept->begin(), cut_kept->end()), whole.substr(0, 33));
  EXPECT_THROW(read_texture_image_from_memory(span_of(cut), "cut"), InputError);
}

// stb_image takes a PSD's colours as composited over white and removes the white (colour - 255 (1 - a)) / a; a
// colour darker than that allows became a negative number converted to a byte (undefined behaviour, found by
// fuzz/fuzz_texture_image). Such a file is refused naming the pixel; one composited over white reads, its colours
// restored, in every layout stb reads.
TEST(TruncatedImages, PsdColoursDarkerThanTheirWhiteMatteAreRefusedNamingThePixel) {
  const std::vector<u8> planes = psd_planes(4), original = texels(4);
  const std::size_t pixels = kWidth * kHeight;
  for (const auto& [run_length, depth] : {std::pair{false, 8}, std::pair{true, 8}, std::pair{false, 16}}) {
    SCOPED_TRACE(testing::Message() << run_length << " " << depth);
    const TextureImage image = read_texture_image_from_memory(span_of(psd(run_length, 4, depth)), "matte.psd");
    ASSERT_EQ(image.srgb.size(), 3 * pixels);
    for (std::size_t i = 0; i < pixels; ++i) {
      const unsigned alpha = planes[3 * pixels + i];
      for (std::size_t c = 0; c < 3; ++c) {
        // Where alpha is 0 the colour is white and stays so; elsewhere it comes back within the rounding of 8 bits.
        if (alpha == 0)
          EXPECT_EQ(image.srgb[3 * i + c], 255) << i;
        else
          EXPECT_NEAR(image.srgb[3 * i + c], original[c * pixels + i], 255.0 / alpha + 1) << i << " " << alpha;
      }
    }
    // Pixel (3, 2), with alpha neither 0 nor 255, given a green one darker than its white matte allows.
    std::vector<u8> dark = planes;
    const std::size_t at = 2 * kWidth + 3;
    ASSERT_EQ(at % 4, 3u);
    const unsigned alpha = dark[3 * pixels + at];
    dark[pixels + at] = static_cast<u8>(254 - alpha);
    try {
      read_texture_image_from_memory(span_of(psd(run_length, 4, depth, dark)), "dark.psd");
      ADD_FAILURE() << "accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(
                    fmt::format("cannot read image 'dark.psd': corrupt: the PSD's pixel (3, 2) has green {} under alpha {}", 254 - alpha, alpha)),
                std::string::npos)
          << e.what();
    }
    // One step lighter is the darkest a composite over white gives: read.
    dark[pixels + at] = static_cast<u8>(255 - alpha);
    EXPECT_NO_THROW(read_texture_image_from_memory(span_of(psd(run_length, 4, depth, dark)), "dark.psd"));
  }
}

// stb_image 2.27 never clears its Huffman and quantisation tables: a scan using one that no segment defined decoded
// with uninitialised memory, its codes indexing past the table's 256 values (found by fuzz/fuzz_texture_image, a
// baseline JPEG with no DQT segment and no AC tables). Refused, naming the table; the file as written reads.
TEST(TruncatedImages, JpegScanUsingATableNeverDefinedIsRefused) {
  const std::string whole = jpeg();
  ASSERT_NO_THROW(read_texture_image_from_memory(span_of(whole), "whole.jpg"));
  const std::size_t scan = whole.find("\xFF\xDA"), frame = whole.find("\xFF\xC0");
  ASSERT_NE(scan, std::string::npos);
  ASSERT_NE(frame, std::string::npos);
  // The scan's first component given AC table 2, and DC table 3; the frame's first component quantisation table 2.
  std::string ac = whole, dc = whole, quantisation = whole;
  ac[scan + 6] = '\x02';
  dc[scan + 6] = '\x30';
  quantisation[frame + 12] = '\x02';
  const std::pair<std::string, std::string> cases[] = {
      {ac, fmt::format("corrupt: the JPEG's scan at byte {} uses AC Huffman table 2, which no DHT segment before it defines", scan)},
      {dc, fmt::format("corrupt: the JPEG's scan at byte {} uses DC Huffman table 3, which no DHT segment before it defines", scan)},
      {quantisation, fmt::format("corrupt: the JPEG's scan at byte {} uses quantisation table 2, which no DQT segment before it defines", scan)}};
  // Bytes that are no marker before the frame, which stb skips (some files are padded so): the file still reads, and
  // a table never defined is still found (the fuzzer's second such file had padding there).
  const std::size_t after_app0 = 4 + 16;
  ASSERT_EQ(whole.substr(2, 2), "\xFF\xE0");
  const std::string padding(7, '\x01');
  const std::string padded = whole.substr(0, after_app0) + padding + whole.substr(after_app0);
  EXPECT_NO_THROW(read_texture_image_from_memory(span_of(padded), "padded.jpg"));
  const std::string padded_ac = ac.substr(0, after_app0) + padding + ac.substr(after_app0);
  for (const auto& [bytes, expected] :
       {cases[0], cases[1], cases[2],
        std::pair{padded_ac, fmt::format("corrupt: the JPEG's scan at byte {} uses AC Huffman table 2, which no DHT segment before it defines",
                                         scan + padding.size())}}) {
    try {
      read_texture_image_from_memory(span_of(bytes), "tables.jpg");
      ADD_FAILURE() << "accepted: " << expected;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("cannot read image 'tables.jpg': " + expected), std::string::npos) << e.what();
    }
  }
}

// A PNG whose data chunk claims 2 GiB in a file of a few hundred bytes: stb_image grew its buffer to the claimed size
// before reading (found by fuzz/fuzz_texture_image as an allocation of 2 GiB). Refused from the chunk's length.
TEST(TruncatedImages, PngChunkRunningPastTheEndIsRefusedBeforeStbAllocatesForIt) {
  std::string bytes = png();
  const std::size_t idat = bytes.find("IDAT") - 4;
  bytes[idat] = '\x7f', bytes[idat + 1] = '\xff', bytes[idat + 2] = '\xff', bytes[idat + 3] = '\xf0';
  try {
    read_texture_image_from_memory(span_of(bytes), "claims");
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(fmt::format("cannot read image 'claims': truncated: the PNG's chunk 'IDAT' at byte {} would end at byte {}",
                                                     idat, idat + 12 + 0x7ffffff0u)),
              std::string::npos)
        << e.what();
  }
}

// The same bytes read twice give the same texels: an uncompressed TGA cut short once left the missing texels as
// whatever the allocator returned.
TEST(TruncatedImages, TruncatedTgaFileIsRefusedNotFilledWithUninitialisedMemory) {
  test::TempDir dir;
  const std::string whole = tga(false);
  test::write_text_file(dir / "cut.tga", whole.substr(0, whole.size() / 2));
  try {
    read_texture_image(dir / "cut.tga");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(
        std::string(e.what()).find("cannot read image file '" + (dir / "cut.tga").string() + "': truncated: the TGA's pixels would end at byte " +
                                   std::to_string(whole.size()) + ", the image has " + std::to_string(whole.size() / 2) + " bytes"),
        std::string::npos)
        << e.what();
  }
}

// A render whose environment is a truncated Radiance file ends by itself with one line naming the file and the
// value that names it, and status 1; a signal while the scene loads ends the program at once.
TEST(TruncatedImages, RenderWithATruncatedEnvironmentEndsWithOneLine) {
  test::TempDir dir;
  test::write_text_file(dir / "sky.hdr", "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 32 +X 64\n" + std::string("\x02\x02\x00\x40", 4));
  test::write_text_file(dir / "scene.json", R"({"camera": {"look_from": [0, 0, 1], "look_at": [0, 0, 0], "vertical_fov": 40},
    "render": {"width": 8, "height": 8, "samples_per_pixel": 1}, "background": {"type": "environment", "file": "sky.hdr"},
    "objects": [{"type": "sphere", "center": [0, 0, -1], "radius": 0.5, "material": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}}]})");
  const test::CommandResult result = test::run_pathtracer("render " + test::quoted(dir / "scene.json") + " -o " + test::quoted(dir / "out.png"), dir);
  EXPECT_EQ(result.exit_code, 1) << result.err;
  EXPECT_NE(result.err.find("/background/file: cannot read image file"), std::string::npos) << result.err;
  EXPECT_NE(result.err.find("truncated: Radiance scanline 1 of 32"), std::string::npos) << result.err;
  EXPECT_EQ(std::count(result.err.begin(), result.err.end(), '\n'), 1) << result.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "out.png"));
}

}  // namespace
}  // namespace pt::truncated_images
