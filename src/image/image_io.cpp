// Image files: stb for 8-bit images, OpenEXR for half/float images, and a plain writer for PFM.
#include "image/image_io.hpp"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <string>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfOutputFile.h>
#include <fmt/format.h>
#include <stb/stb_image.h>
#include <stb/stb_image_write.h>

#include "base/errors.hpp"

namespace pt {

float srgb_to_linear(float c) {
  return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

float linear_to_srgb(float c) {
  return c <= 0.0031308f ? 12.92f * c : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f;
}

TextureImage read_texture_image(const std::filesystem::path& path) {
  int width = 0, height = 0, channels = 0;
  if (!stbi_info(path.c_str(), &width, &height, &channels)) {
    std::error_code error;
    if (!std::filesystem::exists(path, error)) throw InputError(fmt::format("image file '{}' does not exist", path.string()));
    const char* reason = stbi_failure_reason();
    throw InputError(fmt::format("cannot read image file '{}': {}", path.string(), reason ? reason : "unknown format"));
  }
  if (width <= 0 || height <= 0 || width > 65536 || height > 65536 || static_cast<u64>(width) * height > (1ull << 28))
    throw InputError(fmt::format("image file '{}' has an unsupported size {}x{}", path.string(), width, height));
  unsigned char* pixels = stbi_load(path.c_str(), &width, &height, &channels, 3);
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

void write_png(const std::string& file, const LinearImage& image) {
  std::vector<unsigned char> bytes(image.rgb.size());
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    const float v = image.rgb[i];
    const float encoded = std::isfinite(v) ? linear_to_srgb(std::clamp(v, 0.0f, 1.0f)) : 0.0f;
    bytes[i] = static_cast<unsigned char>(std::lround(encoded * 255.0f));
  }
  if (!stbi_write_png(file.c_str(), static_cast<int>(image.width), static_cast<int>(image.height), 3, bytes.data(),
                      static_cast<int>(image.width * 3)))
    throw std::runtime_error("the PNG encoder failed");
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

void write_image(const std::filesystem::path& path, const LinearImage& image) {
  const ImageFormat format = image_format_for(path);
  std::filesystem::path folder = path.parent_path();
  if (folder.empty()) folder = ".";
  std::error_code error;
  if (!std::filesystem::is_directory(folder, error))
    throw InputError(fmt::format("{}: cannot write the image: folder '{}' does not exist", path.string(), folder.string()));
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
