// Image files: stb reads 8-bit textures; PNG is written here through zlib, OpenEXR through its library, PFM plainly.
#include "image/image_io.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <zlib.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <random>
#include <string>
#include <thread>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfOutputFile.h>
#include <fmt/format.h>
#include <stb/stb_image.h>

#include "base/errors.hpp"
#include "base/input_file.hpp"
#include "base/parallel_loop.hpp"

namespace pt {

float srgb_to_linear(float c) {
  return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

float linear_to_srgb(float c) {
  return c <= 0.0031308f ? 12.92f * c : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f;
}

namespace {

// A PNG's size from its header (the signature, then the IHDR chunk: length, type, width, height, big-endian), read
// here because stb_image's own header check refuses very large PNGs without saying their size.
bool png_header_size(int fd, u64& width, u64& height) {
  unsigned char header[24];
  if (::pread(fd, header, sizeof header, 0) != static_cast<ssize_t>(sizeof header)) return false;
  static constexpr unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (std::memcmp(header, kSignature, 8) != 0 || std::memcmp(header + 12, "IHDR", 4) != 0) return false;
  const auto big_endian = [&](int at) { return (u64{header[at]} << 24) | (u64{header[at + 1]} << 16) | (u64{header[at + 2]} << 8) | header[at + 3]; };
  width = big_endian(16);
  height = big_endian(20);
  return true;
}

void check_texture_size(const std::filesystem::path& path, u64 width, u64 height) {
  if (width == 0 || height == 0 || width > kMaxTextureSide || height > kMaxTextureSide || width * height > kMaxTextureTexels)
    throw InputError(fmt::format("image file '{}' is {}x{} texels, larger than a texture may be (at most {} per side and {} texels in all; "
                                 "see docs/scene-format.md)",
                                 path.string(), width, height, kMaxTextureSide, kMaxTextureTexels));
}

}  // namespace

TextureImage read_texture_image(const std::filesystem::path& path) {
  InputFile input = InputFile::open(path);
  switch (input.problem()) {
    case InputFile::Problem::kNone: break;
    case InputFile::Problem::kMissing: throw InputError(fmt::format("image file '{}' does not exist", path.string()));
    case InputFile::Problem::kFolder: throw InputError(fmt::format("cannot read image file '{}': it is a folder, not a file", path.string()));
    case InputFile::Problem::kNotRegular: throw InputError(fmt::format("cannot read image file '{}': it is {}, not a regular file", path.string(), input.reason()));
    case InputFile::Problem::kCannotOpen: throw InputError(fmt::format("cannot read image file '{}': {}", path.string(), input.reason()));
  }
  // The size is checked from the header, before anything is decoded: a small file can claim an image of gigabytes.
  u64 png_width = 0, png_height = 0;
  if (png_header_size(input.descriptor(), png_width, png_height)) check_texture_size(path, png_width, png_height);
  std::FILE* file = ::fdopen(input.descriptor(), "rb");
  if (!file) throw InputError(fmt::format("cannot read image file '{}': {}", path.string(), std::strerror(errno)));
  input.release();
  const std::unique_ptr<std::FILE, int (*)(std::FILE*)> owned(file, &std::fclose);
  int width = 0, height = 0, channels = 0;
  if (!stbi_info_from_file(file, &width, &height, &channels)) {
    const char* reason = stbi_failure_reason();
    throw InputError(fmt::format("cannot read image file '{}': {}", path.string(), reason ? reason : "unknown format"));
  }
  check_texture_size(path, static_cast<u64>(width), static_cast<u64>(height));
  unsigned char* pixels = stbi_load_from_file(file, &width, &height, &channels, 3);
  if (!pixels) {
    const char* reason = stbi_failure_reason();
    throw InputError(fmt::format("cannot decode image file '{}': {}", path.string(), reason ? reason : "unknown error"));
  }
  TextureImage image;
  image.width = static_cast<u32>(width);
  image.height = static_cast<u32>(height);
  image.srgb.assign(pixels, pixels + static_cast<std::size_t>(width) * height * 3);
  stbi_image_free(pixels);
  return image;
}

std::vector<float> srgb_decode_table() {
  std::vector<float> table(256);
  for (int i = 0; i < 256; ++i) table[i] = srgb_to_linear(static_cast<float>(i) / 255.0f);
  return table;
}

ImageFormat image_format_for(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".png") return ImageFormat::kPng;
  if (ext == ".pfm") return ImageFormat::kPfm;
  if (ext == ".exr") return ImageFormat::kExr;
  throw InputError(fmt::format("{}: unknown image extension '{}' (use .png, .pfm or .exr)", path.string(), ext));
}

namespace {

// PNG, 8-bit sRGB: each band of rows is converted, filtered (the Sub filter: each byte less the one three to its
// left, which suits rendered images about as well as the adaptive choice does) and deflated at zlib's fastest level
// on its own thread. A band ends its compressed part with a sync flush, so the parts joined make one zlib stream
// (as pigz does); the stream's Adler-32 is combined from the bands'. About ten times faster than stb's encoder on
// a 1200x800 render.
std::vector<unsigned char> encode_png(const LinearImage& image) {
  const std::size_t row_bytes = 1 + 3 * static_cast<std::size_t>(image.width);  // the filter byte, then RGB
  constexpr u32 kBandRows = 32;
  const u32 bands = (image.height + kBandRows - 1) / kBandRows;
  struct Band {
    std::vector<unsigned char> deflated;
    uLong adler = 1;
    std::size_t raw_bytes = 0;
    int status = Z_OK;
  };
  std::vector<Band> parts(bands);
  ParallelLoop loop(std::max(1u, std::thread::hardware_concurrency()));
  loop.run(bands, 1, [&](u32 band) {
    const u32 first_row = band * kBandRows, rows = std::min(kBandRows, image.height - first_row);
    std::vector<unsigned char> raw(row_bytes * rows);
    for (u32 r = 0; r < rows; ++r) {
      unsigned char* out = raw.data() + r * row_bytes;
      const float* in = image.rgb.data() + static_cast<std::size_t>(first_row + r) * image.width * 3;
      out[0] = 1;  // Sub
      unsigned char previous[3] = {0, 0, 0};
      for (std::size_t i = 0; i < 3 * static_cast<std::size_t>(image.width); ++i) {
        const float v = in[i];
        const float encoded = std::isfinite(v) ? linear_to_srgb(std::clamp(v, 0.0f, 1.0f)) : 0.0f;
        const auto byte = static_cast<unsigned char>(std::lround(encoded * 255.0f));
        out[1 + i] = static_cast<unsigned char>(byte - previous[i % 3]);
        previous[i % 3] = byte;
      }
    }
    Band& part = parts[band];
    part.raw_bytes = raw.size();
    part.adler = adler32(1, raw.data(), static_cast<uInt>(raw.size()));
    z_stream stream{};
    part.status = deflateInit2(&stream, 1, Z_DEFLATED, -15, 8, Z_DEFAULT_STRATEGY);  // raw deflate: no header per band
    if (part.status != Z_OK) return;
    part.deflated.resize(deflateBound(&stream, raw.size()) + 16);
    stream.next_in = raw.data();
    stream.avail_in = static_cast<uInt>(raw.size());
    stream.next_out = part.deflated.data();
    stream.avail_out = static_cast<uInt>(part.deflated.size());
    part.status = deflate(&stream, band + 1 == bands ? Z_FINISH : Z_SYNC_FLUSH);
    if ((band + 1 == bands && part.status == Z_STREAM_END) || (band + 1 < bands && part.status == Z_OK)) part.status = Z_OK;
    else if (part.status == Z_OK) part.status = Z_BUF_ERROR;
    part.deflated.resize(part.deflated.size() - stream.avail_out);
    deflateEnd(&stream);
  });

  std::vector<unsigned char> idat{0x78, 0x01};  // zlib header: deflate, 32 KiB window, fastest
  uLong adler = 1;
  for (const Band& part : parts) {
    if (part.status != Z_OK) throw std::runtime_error(fmt::format("the PNG encoder failed (zlib error {})", part.status));
    idat.insert(idat.end(), part.deflated.begin(), part.deflated.end());
    adler = adler32_combine(adler, part.adler, static_cast<z_off_t>(part.raw_bytes));
  }
  for (int shift = 24; shift >= 0; shift -= 8) idat.push_back(static_cast<unsigned char>(adler >> shift));

  std::vector<unsigned char> png{0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  auto put32 = [&](u32 v) {
    for (int shift = 24; shift >= 0; shift -= 8) png.push_back(static_cast<unsigned char>(v >> shift));
  };
  auto chunk = [&](const char* type, const unsigned char* data, std::size_t size) {
    put32(static_cast<u32>(size));
    const std::size_t start = png.size();
    png.insert(png.end(), type, type + 4);
    png.insert(png.end(), data, data + size);
    put32(static_cast<u32>(crc32(0, png.data() + start, static_cast<uInt>(png.size() - start))));
  };
  const unsigned char header[13] = {static_cast<unsigned char>(image.width >> 24), static_cast<unsigned char>(image.width >> 16),
                                    static_cast<unsigned char>(image.width >> 8),  static_cast<unsigned char>(image.width),
                                    static_cast<unsigned char>(image.height >> 24), static_cast<unsigned char>(image.height >> 16),
                                    static_cast<unsigned char>(image.height >> 8),  static_cast<unsigned char>(image.height),
                                    8, 2, 0, 0, 0};  // 8 bits, truecolour, deflate, adaptive filtering, no interlace
  chunk("IHDR", header, sizeof(header));
  const unsigned char srgb_intent = 0;  // perceptual: the pixels are sRGB
  chunk("sRGB", &srgb_intent, 1);
  // IDAT chunks of at most 1 MiB, as encoders commonly write them.
  constexpr std::size_t kChunk = 1u << 20;
  for (std::size_t at = 0; at < idat.size(); at += kChunk) chunk("IDAT", idat.data() + at, std::min(kChunk, idat.size() - at));
  chunk("IEND", nullptr, 0);
  return png;
}

void write_png(const std::string& file, const LinearImage& image) {
  const std::vector<unsigned char> png = encode_png(image);
  std::FILE* out = std::fopen(file.c_str(), "wb");
  if (!out) throw std::runtime_error(fmt::format("cannot create the file: {}", std::strerror(errno)));
  const bool written = std::fwrite(png.data(), 1, png.size(), out) == png.size() && std::fflush(out) == 0;
  const int write_error = errno;
  if (std::fclose(out) != 0 || !written) throw std::runtime_error(std::strerror(written ? errno : write_error));
}

// Portable float map: little-endian (negative scale), rows from the bottom.
void write_pfm(const std::string& file, const LinearImage& image) {
  std::ofstream out(file, std::ios::binary);
  if (!out) throw std::runtime_error("cannot create the file");
  out << "PF\n" << image.width << " " << image.height << "\n-1.0\n";
  for (u32 row = image.height; row-- > 0;)
    out.write(reinterpret_cast<const char*>(image.rgb.data() + static_cast<std::size_t>(row) * image.width * 3),
              static_cast<std::streamsize>(image.width * 3 * sizeof(float)));
  out.flush();
  if (!out) throw std::runtime_error("writing failed");
}

void write_exr(const std::string& file, const LinearImage& image) {
  Imf::Header header(static_cast<int>(image.width), static_cast<int>(image.height));
  for (const char* channel : {"R", "G", "B"}) header.channels().insert(channel, Imf::Channel(Imf::FLOAT));
  Imf::OutputFile out(file.c_str(), header);
  Imf::FrameBuffer frame;
  const std::size_t x_stride = 3 * sizeof(float), y_stride = x_stride * image.width;
  char* base = reinterpret_cast<char*>(const_cast<float*>(image.rgb.data()));
  frame.insert("R", Imf::Slice(Imf::FLOAT, base, x_stride, y_stride));
  frame.insert("G", Imf::Slice(Imf::FLOAT, base + sizeof(float), x_stride, y_stride));
  frame.insert("B", Imf::Slice(Imf::FLOAT, base + 2 * sizeof(float), x_stride, y_stride));
  out.setFrameBuffer(frame);
  out.writePixels(static_cast<int>(image.height));
}

}  // namespace

void check_output_path(const std::filesystem::path& path) {
  auto refuse = [&](const std::string& reason) {
    throw InputError(fmt::format("{}: cannot write the image: {}", path.string(), reason));
  };
  std::filesystem::path folder = path.parent_path();
  if (folder.empty()) folder = ".";
  std::error_code error;
  const std::filesystem::file_status folder_status = std::filesystem::status(folder, error);
  if (!std::filesystem::exists(folder_status)) refuse(fmt::format("folder '{}' does not exist", folder.string()));
  if (!std::filesystem::is_directory(folder_status)) refuse(fmt::format("'{}' is a file, not a folder", folder.string()));
  if (std::filesystem::is_directory(path, error)) refuse("it is a folder");
  // A file of our own beside it, created and removed at once: the only sure test of permissions (and of a
  // read-only file system).
  const std::filesystem::path probe = folder / fmt::format(".{}.{}.probe", path.filename().string(), getpid());
  const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0600);
  if (fd < 0) refuse(fmt::format("cannot create a file in '{}': {}", folder.string(), std::strerror(errno)));
  ::close(fd);
  std::filesystem::remove(probe, error);
}

void write_image(const std::filesystem::path& path, const LinearImage& image) {
  const ImageFormat format = image_format_for(path);
  check_output_path(path);  // again: the folder may have changed while the image was rendered
  std::filesystem::path folder = path.parent_path();
  if (folder.empty()) folder = ".";
  std::error_code error;
  // The temporary keeps the final extension (OpenEXR does not care, but viewers of a stray file would) and a
  // name unique to this process.
  std::random_device entropy;
  const std::filesystem::path temporary =
      folder / fmt::format(".{}.{}-{:08x}.tmp{}", path.filename().string(), getpid(), entropy(), path.extension().string());
  try {
    switch (format) {
      case ImageFormat::kPng: write_png(temporary.string(), image); break;
      case ImageFormat::kPfm: write_pfm(temporary.string(), image); break;
      case ImageFormat::kExr: write_exr(temporary.string(), image); break;
    }
    std::filesystem::rename(temporary, path);
  } catch (const std::exception& e) {
    std::filesystem::remove(temporary, error);
    throw InputError(fmt::format("{}: cannot write the image: {}", path.string(), e.what()));
  }
}

}  // namespace pt
