// Image files: stb reads 8-bit textures (once their data is checked complete: image_data_check.hpp); PNG is written here through zlib, OpenEXR through its library, PFM plainly.
#include "image/image_io.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <zlib.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <fmt/format.h>
#include <stb/stb_image.h>

#include "base/atomic_file.hpp"
#include "base/errors.hpp"
#include "base/input_file.hpp"
#include "base/parallel_loop.hpp"
#include "image/image_data_check.hpp"

namespace pt {

float srgb_to_linear(float c) { return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f); }

float linear_to_srgb(float c) { return c <= 0.0031308f ? 12.92f * c : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f; }

namespace {
u8 srgb_byte_by_power(float linear) {
  const float encoded = std::isfinite(linear) ? linear_to_srgb(std::clamp(linear, 0.0f, 1.0f)) : 0.0f;
  return static_cast<u8>(std::lround(encoded * 255.0f));
}
}  // namespace

// The byte steps up at 255 linear values; each is found once, by bisection over the floats of 0..1 in their bit
// order (which is their numeric order). The floats of 0..1 are then cut into buckets by their top 16 bits (exponent
// and 7 bits of mantissa: each bucket is 1/128 of its value wide, and the curve's slope is such that no bucket
// holds two steps), and each bucket keeps its byte at its start and the step inside it, if any. A byte is then
// two lookups and a comparison, without a branch to mispredict: about twenty times faster than the power, which
// was most of the cost of a PNG (a preview page makes one each pass).
u8 linear_to_srgb_byte(float linear) {
  constexpr u32 kShift = 16;
  struct Table {
    std::vector<u8> base;       // the byte at the bucket's first float
    std::vector<float> next;    // the step inside the bucket (past its end where there is none)
  };
  static const Table table = [] {
    std::array<float, 255> steps{};
    const u32 one = std::bit_cast<u32>(1.0f);
    for (u32 byte = 1; byte <= 255; ++byte) {
      u32 low = 0, high = one;  // srgb_byte_by_power(low) < byte <= srgb_byte_by_power(high)
      while (high - low > 1) {
        const u32 middle = low + (high - low) / 2;
        (srgb_byte_by_power(std::bit_cast<float>(middle)) >= byte ? high : low) = middle;
      }
      steps[byte - 1] = std::bit_cast<float>(high);
    }
    Table t;
    const u32 buckets = (one >> kShift) + 1;
    t.base.resize(buckets);
    t.next.resize(buckets);
    for (u32 k = 0; k < buckets; ++k) {
      const float first = std::bit_cast<float>(k << kShift);
      const float last = std::bit_cast<float>(std::min(((k + 1) << kShift) - 1, one));
      const auto from = std::upper_bound(steps.begin(), steps.end(), first);
      const auto to = std::upper_bound(steps.begin(), steps.end(), last);
      if (to - from > 1) throw std::logic_error("linear_to_srgb_byte: two steps of the sRGB byte in one bucket");
      t.base[k] = static_cast<u8>(from - steps.begin());
      t.next[k] = to > from ? *from : std::numeric_limits<float>::infinity();
    }
    return t;
  }();
  if (!(linear > 0.0f) || !std::isfinite(linear)) return 0;  // negative, zero, NaN, infinite
  if (linear >= 1.0f) return 255;
  const u32 k = std::bit_cast<u32>(linear) >> kShift;
  return static_cast<u8>(table.base[k] + (linear >= table.next[k] ? 1 : 0));
}

namespace {

// A PNG's size from its header (the signature, then the IHDR chunk: length, type, width, height, big-endian), read
// here because stb_image's own header check refuses very large PNGs without saying their size. `header` holds the
// first `size` bytes of the image.
bool png_header_size(const unsigned char* header, std::size_t size, u64& width, u64& height) {
  if (size < 24) return false;
  static constexpr unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (std::memcmp(header, kSignature, 8) != 0 || std::memcmp(header + 12, "IHDR", 4) != 0) return false;
  const auto big_endian = [&](int at) { return (u64{header[at]} << 24) | (u64{header[at + 1]} << 16) | (u64{header[at + 2]} << 8) | header[at + 3]; };
  width = big_endian(16);
  height = big_endian(20);
  return true;
}

// The system's stb_image (2.27) writes past its Huffman tables when a JPEG's DHT segment declares more than 256
// codes in one table (it sums the 16 counts but does not check the sum; later versions refuse it). Every place stb
// could take for a DHT marker is a 0xFF byte followed by 0xC4 (fill bytes 0xFF before a marker included, in the
// headers and between scans alike), so each is checked here, tables as stb reads them, before stb sees the image.
// Returns false for such an image. Only images starting with 0xFF, as every JPEG does, need it.
bool jpeg_huffman_tables_fit(std::span<const unsigned char> bytes) {
  const auto at = [&](std::size_t i) -> unsigned { return i < bytes.size() ? bytes[i] : 0u; };  // stb reads 0 past the end
  for (std::size_t marker = 0; marker + 1 < bytes.size(); ++marker) {
    if (bytes[marker] != 0xFF || bytes[marker + 1] != 0xC4) continue;
    std::size_t pos = marker + 2;
    long length = static_cast<long>((at(pos) << 8) | at(pos + 1)) - 2;
    pos += 2;
    while (length > 0 && pos < bytes.size()) {
      ++pos;  // table class and number
      unsigned codes = 0;
      for (int i = 0; i < 16; ++i) codes += at(pos++);
      if (codes > 256) return false;
      pos += codes;
      length -= 17 + static_cast<long>(codes);
    }
  }
  return true;
}

// `subject` names the image in messages: "image file 'PATH'" or "image 'NAME'".
void check_texture_size(const std::string& subject, u64 width, u64 height) {
  if (width == 0 || height == 0) throw InputError(fmt::format("{} is {}x{} texels: it has no texels", subject, width, height));
  if (width > kMaxTextureSide || height > kMaxTextureSide || width * height > kMaxTextureTexels)
    throw InputError(
        fmt::format("{} is {}x{} texels, larger than a texture may be (at most {} per side and {} texels in all; "
                    "see docs/scene-format.md)",
                    subject, width, height, kMaxTextureSide, kMaxTextureTexels));
}

// Where an image's bytes come from: a file, whose header stb reads through its FILE interface (so that only the
// header is read before the size is checked), or memory. decode_texture takes the same steps for both.
class TextureSource {
 public:
  virtual ~TextureSource() = default;
  // Up to `size` bytes from the start; returns how many there were.
  virtual std::size_t header(unsigned char* out, std::size_t size) = 0;
  // All the bytes, read once the header's size is checked; they are what stb decodes.
  virtual std::span<const unsigned char> all() = 0;
  virtual bool stb_info(int* width, int* height, int* channels) = 0;
};

// Refuses an image whose data ends before its header says, or whose structure would make stb_image loop
// (image_data_check.hpp), and one too large for stb_image's int lengths.
void check_image_data(std::span<const unsigned char> bytes, const std::string& subject) {
  if (bytes.size() > static_cast<std::size_t>(std::numeric_limits<int>::max()))
    throw InputError(fmt::format("cannot read {}: {} bytes, more than an image may have", subject, bytes.size()));
  if (const std::optional<std::string> problem = image_data_problem(bytes)) throw InputError(fmt::format("cannot read {}: {}", subject, *problem));
}

// A whole file's bytes, as many as there are.
std::vector<unsigned char> read_all(int fd) {
  struct stat status {};
  if (::fstat(fd, &status) != 0 || status.st_size <= 0) return {};
  std::vector<unsigned char> bytes(static_cast<std::size_t>(status.st_size));
  std::size_t got = 0;
  while (got < bytes.size()) {
    const ssize_t n = ::pread(fd, bytes.data() + got, bytes.size() - got, static_cast<off_t>(got));
    if (n <= 0) break;
    got += static_cast<std::size_t>(n);
  }
  bytes.resize(got);
  return bytes;
}

class FileTextureSource final : public TextureSource {
 public:
  FileTextureSource(int fd, std::FILE* file) : fd_(fd), file_(file) {}
  std::size_t header(unsigned char* out, std::size_t size) override {
    const ssize_t got = ::pread(fd_, out, size, 0);
    return got > 0 ? static_cast<std::size_t>(got) : 0;
  }
  std::span<const unsigned char> all() override {
    if (bytes_.empty()) bytes_ = read_all(fd_);
    return bytes_;
  }
  bool stb_info(int* width, int* height, int* channels) override { return stbi_info_from_file(file_, width, height, channels) != 0; }

 private:
  int fd_;
  std::FILE* file_;
  std::vector<unsigned char> bytes_;
};

class MemoryTextureSource final : public TextureSource {
 public:
  explicit MemoryTextureSource(std::span<const unsigned char> bytes) : bytes_(bytes) {}
  std::size_t header(unsigned char* out, std::size_t size) override {
    const std::size_t n = std::min(size, bytes_.size());
    if (n > 0) std::memcpy(out, bytes_.data(), n);
    return n;
  }
  std::span<const unsigned char> all() override { return bytes_; }
  bool stb_info(int* width, int* height, int* channels) override {
    return stbi_info_from_memory(bytes_.data(), static_cast<int>(bytes_.size()), width, height, channels) != 0;
  }

 private:
  std::span<const unsigned char> bytes_;
};

// The size an image's header gives, checked against the limits before anything is decoded: a small file can claim
// an image of gigabytes.
TextureSize texture_size(TextureSource& source, const std::string& subject) {
  unsigned char header[24];
  const std::size_t header_size = source.header(header, sizeof header);
  u64 png_width = 0, png_height = 0;
  if (png_header_size(header, header_size, png_width, png_height)) check_texture_size(subject, png_width, png_height);
  if (header_size > 0 && header[0] == 0xFF && !jpeg_huffman_tables_fit(source.all()))
    throw InputError(fmt::format("cannot read {}: corrupt JPEG (a Huffman table of more than 256 codes)", subject));
  {
    std::vector<unsigned char> start(kImageHeaderBytes);
    start.resize(source.header(start.data(), start.size()));
    if (const std::optional<std::string> problem = image_header_problem(start))
      throw InputError(fmt::format("cannot read {}: {}", subject, *problem));
  }
  int width = 0, height = 0, channels = 0;
  if (!source.stb_info(&width, &height, &channels)) {
    const char* reason = stbi_failure_reason();
    throw InputError(fmt::format("cannot read {}: {}", subject, reason ? reason : "unknown format"));
  }
  check_texture_size(subject, static_cast<u64>(width), static_cast<u64>(height));
  return TextureSize{static_cast<u32>(width), static_cast<u32>(height)};
}

TextureImage decode_texture(TextureSource& source, const std::string& subject) {
  const TextureSize size = texture_size(source, subject);
  int width = 0, height = 0, channels = 0;
  std::span<const unsigned char> bytes = source.all();
  check_image_data(bytes, subject);
  const std::optional<std::vector<u8>> cleaned = png_without_empty_data_chunks(bytes);
  if (cleaned) bytes = *cleaned;
  // Decoded with the image's own channels and expanded to RGB here, as stb_image would (grey repeated, alpha
  // dropped): the system's stb_image (2.27) converts a 16-bit grey PGM to RGB as if it had 8-bit samples and then
  // reads past the converted buffer.
  unsigned char* pixels = stbi_load_from_memory(bytes.data(), static_cast<int>(bytes.size()), &width, &height, &channels, 0);
  if (!pixels) {
    const char* reason = stbi_failure_reason();
    throw InputError(fmt::format("cannot decode {}: {}", subject, reason ? reason : "unknown error"));
  }
  const std::unique_ptr<unsigned char, void (*)(void*)> owned_pixels(pixels, &stbi_image_free);
  if (channels < 1 || channels > 4) throw InputError(fmt::format("cannot decode {}: {} channels", subject, channels));
  if (static_cast<u32>(width) != size.width || static_cast<u32>(height) != size.height)
    throw InputError(fmt::format("cannot decode {}: its header says {}x{} texels, its data {}x{}", subject, size.width, size.height, width, height));
  TextureImage image;
  image.width = static_cast<u32>(width);
  image.height = static_cast<u32>(height);
  const std::size_t texels = static_cast<std::size_t>(width) * height;
  image.srgb.resize(3 * texels);
  const int colour = channels >= 3 ? 3 : 1;  // grey (and alpha) or RGB (and alpha)
  for (std::size_t i = 0; i < texels; ++i)
    for (int c = 0; c < 3; ++c) image.srgb[3 * i + c] = pixels[channels * i + (colour == 3 ? c : 0)];
  return image;
}

// Opens an image file, or throws InputError saying why it cannot be read (missing, a folder, not a regular file).
InputFile open_image_file(const std::filesystem::path& path) {
  InputFile input = InputFile::open(path);
  switch (input.problem()) {
    case InputFile::Problem::kNone: break;
    case InputFile::Problem::kMissing: throw InputError(fmt::format("image file '{}' does not exist", path.string()));
    case InputFile::Problem::kFolder: throw InputError(fmt::format("cannot read image file '{}': it is a folder, not a file", path.string()));
    case InputFile::Problem::kNotRegular:
      throw InputError(fmt::format("cannot read image file '{}': it is {}, not a regular file", path.string(), input.reason()));
    case InputFile::Problem::kCannotOpen: throw InputError(fmt::format("cannot read image file '{}': {}", path.string(), input.reason()));
  }
  return input;
}

}  // namespace

TextureSize read_texture_image_size(const std::filesystem::path& path) {
  InputFile input = open_image_file(path);
  const std::string subject = fmt::format("image file '{}'", path.string());
  std::FILE* file = ::fdopen(input.descriptor(), "rb");
  if (!file) throw InputError(fmt::format("cannot read {}: {}", subject, std::strerror(errno)));
  const int fd = input.release();
  const std::unique_ptr<std::FILE, int (*)(std::FILE*)> owned(file, &std::fclose);
  FileTextureSource source(fd, file);
  return texture_size(source, subject);
}

TextureImage read_texture_image(const std::filesystem::path& path) {
  InputFile input = open_image_file(path);
  const std::string subject = fmt::format("image file '{}'", path.string());
  std::FILE* file = ::fdopen(input.descriptor(), "rb");
  if (!file) throw InputError(fmt::format("cannot read {}: {}", subject, std::strerror(errno)));
  const int fd = input.release();
  const std::unique_ptr<std::FILE, int (*)(std::FILE*)> owned(file, &std::fclose);
  FileTextureSource source(fd, file);
  return decode_texture(source, subject);
}

TextureImage read_texture_image_from_memory(std::span<const u8> bytes, const std::string& name_for_messages) {
  const std::string subject = fmt::format("image '{}'", name_for_messages);
  if (bytes.empty()) throw InputError(fmt::format("cannot read {}: it is empty", subject));
  // stb_image takes the length as an int.
  if (bytes.size() > static_cast<std::size_t>(std::numeric_limits<int>::max()))
    throw InputError(fmt::format("cannot read {}: {} bytes, more than an image may have", subject, bytes.size()));
  MemoryTextureSource source(bytes);
  return decode_texture(source, subject);
}

namespace {

// `subject` names the image in messages, as decode_texture's do.
void check_environment_size(const std::string& subject, u64 width, u64 height) {
  if (width == 0 || height == 0 || width > kMaxTextureSide || height > kMaxTextureSide || width * height > kMaxEnvironmentTexels)
    throw InputError(
        fmt::format("{} is {}x{} texels, larger than an environment image may be (at most {} per side and {} texels in "
                    "all; see docs/scene-format.md)",
                    subject, width, height, kMaxTextureSide, kMaxEnvironmentTexels));
}

// One line, whatever the library's message holds.
std::string one_line(std::string text) {
  std::replace(text.begin(), text.end(), '\n', ' ');
  return text;
}

LinearImage read_exr_environment(const std::filesystem::path& path, const std::string& subject) {
  try {
    // The header is read here; the pixels only by readPixels, after the size is checked.
    Imf::InputFile file(path.c_str());
    const Imath::Box2i window = file.header().dataWindow();
    const std::int64_t width = std::int64_t{window.max.x} - window.min.x + 1, height = std::int64_t{window.max.y} - window.min.y + 1;
    if (width <= 0 || height <= 0) throw InputError(fmt::format("cannot read {}: its data window is empty", subject));
    check_environment_size(subject, static_cast<u64>(width), static_cast<u64>(height));
    const Imf::ChannelList& channels = file.header().channels();
    const bool rgb = channels.findChannel("R") && channels.findChannel("G") && channels.findChannel("B");
    if (!rgb && !channels.findChannel("Y"))
      throw InputError(fmt::format("cannot read {}: it has neither R, G and B channels nor a Y channel", subject));
    LinearImage image;
    image.width = static_cast<u32>(width);
    image.height = static_cast<u32>(height);
    image.rgb.resize(3 * static_cast<std::size_t>(width) * static_cast<std::size_t>(height));
    Imf::FrameBuffer frame;
    const std::size_t x_stride = 3 * sizeof(float), y_stride = x_stride * static_cast<std::size_t>(width);
    const char* names[3] = {"R", "G", "B"};
    // A grey image's Y is read once, into the red channel, and copied below.
    for (int c = 0; c < (rgb ? 3 : 1); ++c)
      frame.insert(rgb ? names[c] : "Y", Imf::Slice::Make(Imf::FLOAT, image.rgb.data() + c, window, x_stride, y_stride));
    file.setFrameBuffer(frame);
    file.readPixels(window.min.y, window.max.y);
    if (!rgb)
      for (std::size_t i = 0; i < image.rgb.size(); i += 3) image.rgb[i + 1] = image.rgb[i + 2] = image.rgb[i];
    return image;
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {
    throw InputError(fmt::format("cannot read {}: {}", subject, one_line(e.what())));
  }
}

LinearImage read_hdr_environment(std::FILE* file, int fd, const std::string& subject) {
  {
    std::vector<unsigned char> start(kImageHeaderBytes);
    const ssize_t got = ::pread(fd, start.data(), start.size(), 0);
    start.resize(got > 0 ? static_cast<std::size_t>(got) : 0);
    if (const std::optional<std::string> problem = image_header_problem(start))
      throw InputError(fmt::format("cannot read {}: {}", subject, *problem));
  }
  int width = 0, height = 0, channels = 0;
  if (!stbi_info_from_file(file, &width, &height, &channels)) {
    const char* reason = stbi_failure_reason();
    throw InputError(fmt::format("cannot read {}: {}", subject, reason ? reason : "unknown format"));
  }
  check_environment_size(subject, static_cast<u64>(width), static_cast<u64>(height));
  std::vector<unsigned char> bytes = read_all(fd);
  check_image_data(bytes, subject);
  if (std::optional<std::vector<u8>> cleaned = png_without_empty_data_chunks(bytes)) bytes = std::move(*cleaned);
  float* pixels = stbi_loadf_from_memory(bytes.data(), static_cast<int>(bytes.size()), &width, &height, &channels, 3);
  if (!pixels) {
    const char* reason = stbi_failure_reason();
    throw InputError(fmt::format("cannot decode {}: {}", subject, reason ? reason : "unknown error"));
  }
  const std::unique_ptr<float, void (*)(void*)> owned(pixels, &stbi_image_free);
  LinearImage image;
  image.width = static_cast<u32>(width);
  image.height = static_cast<u32>(height);
  image.rgb.assign(pixels, pixels + 3 * static_cast<std::size_t>(width) * static_cast<std::size_t>(height));
  return image;
}

}  // namespace

LinearImage read_environment_image(const std::filesystem::path& path) {
  const std::string subject = fmt::format("image file '{}'", path.string());
  InputFile input = open_image_file(path);
  // The format by its first bytes, not its name.
  unsigned char magic[4] = {};
  const bool exr = ::pread(input.descriptor(), magic, 4, 0) == 4 && magic[0] == 0x76 && magic[1] == 0x2f && magic[2] == 0x31 && magic[3] == 0x01;
  LinearImage image;
  if (exr) {
    image = read_exr_environment(path, subject);
  } else {
    std::FILE* file = ::fdopen(input.descriptor(), "rb");
    if (!file) throw InputError(fmt::format("cannot read {}: {}", subject, std::strerror(errno)));
    const int fd = input.release();
    const std::unique_ptr<std::FILE, int (*)(std::FILE*)> owned(file, &std::fclose);
    if (stbi_is_hdr_from_file(file)) {
      image = read_hdr_environment(file, fd, subject);
    } else {
      const TextureImage bytes = read_texture_image(path);
      check_environment_size(subject, bytes.width, bytes.height);
      const std::vector<float> decode = srgb_decode_table();
      image.width = bytes.width;
      image.height = bytes.height;
      image.rgb.resize(bytes.srgb.size());
      for (std::size_t i = 0; i < bytes.srgb.size(); ++i) image.rgb[i] = decode[bytes.srgb[i]];
    }
  }
  // Radiance is finite and not negative: anything else would make every sample that sees it, and the sampling
  // distribution built from it, meaningless.
  for (std::size_t i = 0; i < image.rgb.size(); ++i) {
    const float value = image.rgb[i];
    if (std::isfinite(value) && value >= 0.0f) continue;
    const std::size_t texel = i / 3;
    throw InputError(
        fmt::format("{}: texel ({}, {}) (column, row from the top left) has {} {}; an environment image needs finite values of at "
                    "least 0",
                    subject, texel % image.width, texel / image.width,
                    "RGB"[i % 3] == 'R'   ? "red"
                    : "RGB"[i % 3] == 'G' ? "green"
                                          : "blue",
                    value));
  }
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

ImageRows rows_of(const LinearImage& image) {
  return ImageRows{image.width,
                   image.height,
                   [&image](u32 first_row, u32 row_count, float* rgb) {
                     const std::size_t row_floats = 3 * static_cast<std::size_t>(image.width);
                     std::copy_n(image.rgb.data() + first_row * row_floats, row_count * row_floats, rgb);
                   },
                   {}};
}

namespace {

void store_be32(unsigned char* out, u32 v) {
  for (int i = 0; i < 4; ++i) out[i] = static_cast<unsigned char>(v >> (24 - 8 * i));
}

// Where an encoded image's bytes go: a file being written, or memory.
using ByteSink = std::function<void(const void* data, std::size_t size)>;

// One PNG chunk: length, type, data, CRC of type and data.
void write_png_chunk(const ByteSink& file, const char* type, const unsigned char* data, std::size_t size) {
  unsigned char head[8], crc[4];
  store_be32(head, static_cast<u32>(size));
  std::memcpy(head + 4, type, 4);
  uLong sum = crc32(0, head + 4, 4);
  if (size > 0) sum = crc32(sum, data, static_cast<uInt>(size));  // a null buffer would reset the sum to its start
  store_be32(crc, static_cast<u32>(sum));
  file(head, sizeof(head));
  if (size > 0) file(data, size);
  file(crc, sizeof(crc));
}

// PNG, 8-bit sRGB: each band of rows is converted, filtered (the Sub filter: each byte less the one three to its
// left, which suits rendered images about as well as the adaptive choice does) and deflated at zlib's fastest level
// on its own thread. A band ends its compressed part with a sync flush, so the parts joined make one zlib stream
// (as pigz does); the stream's Adler-32 is combined from the bands'. About ten times faster than stb's encoder on
// a 1200x800 render. Bands go a group at a time, each group written out before the next is made, so the memory
// held is a few bands' worth whatever the image's size.
void write_png(const ByteSink& file, const ImageRows& image, int level = 1) {
  const std::size_t row_bytes = 1 + 3 * static_cast<std::size_t>(image.width);  // the filter byte, then RGB
  constexpr u32 kBandRows = 32;
  const u32 bands = (image.height + kBandRows - 1) / kBandRows;
  struct Band {
    std::vector<unsigned char> deflated;
    uLong adler = 1;
    std::size_t raw_bytes = 0;
    int status = Z_OK;
  };
  ParallelLoop loop(std::max(1u, std::thread::hardware_concurrency()));
  const u32 group_bands = 4 * loop.threads();
  std::vector<Band> parts(std::min(bands, group_bands));
  auto encode_band = [&](u32 band, Band& part) {
    const u32 first_row = band * kBandRows, rows = std::min(kBandRows, image.height - first_row);
    std::vector<float> linear(3 * static_cast<std::size_t>(image.width) * rows);
    image.fill(first_row, rows, linear.data());
    std::vector<unsigned char> raw(row_bytes * rows);
    for (u32 r = 0; r < rows; ++r) {
      unsigned char* out = raw.data() + r * row_bytes;
      const float* in = linear.data() + static_cast<std::size_t>(r) * image.width * 3;
      out[0] = 1;  // Sub
      unsigned char previous[3] = {0, 0, 0};
      for (std::size_t i = 0; i < 3 * static_cast<std::size_t>(image.width); ++i) {
        const unsigned char byte = linear_to_srgb_byte(in[i]);
        out[1 + i] = static_cast<unsigned char>(byte - previous[i % 3]);
        previous[i % 3] = byte;
      }
    }
    part.raw_bytes = raw.size();
    part.adler = adler32(1, raw.data(), static_cast<uInt>(raw.size()));
    z_stream stream{};
    part.status = deflateInit2(&stream, level, Z_DEFLATED, -15, 8, Z_DEFAULT_STRATEGY);  // raw deflate: no header per band
    if (part.status != Z_OK) return;
    part.deflated.resize(deflateBound(&stream, raw.size()) + 16);
    stream.next_in = raw.data();
    stream.avail_in = static_cast<uInt>(raw.size());
    stream.next_out = part.deflated.data();
    stream.avail_out = static_cast<uInt>(part.deflated.size());
    part.status = deflate(&stream, band + 1 == bands ? Z_FINISH : Z_SYNC_FLUSH);
    if ((band + 1 == bands && part.status == Z_STREAM_END) || (band + 1 < bands && part.status == Z_OK))
      part.status = Z_OK;
    else if (part.status == Z_OK)
      part.status = Z_BUF_ERROR;
    part.deflated.resize(part.deflated.size() - stream.avail_out);
    deflateEnd(&stream);
  };

  file("\x89PNG\r\n\x1a\n", 8);
  unsigned char header[13] = {0, 0, 0, 0, 0, 0, 0, 0, 8, 2, 0, 0, 0};  // 8 bits, truecolour, deflate, adaptive filtering, no interlace
  store_be32(header, image.width);
  store_be32(header + 4, image.height);
  write_png_chunk(file, "IHDR", header, sizeof(header));
  const unsigned char srgb_intent = 0;  // perceptual: the pixels are sRGB
  write_png_chunk(file, "sRGB", &srgb_intent, 1);
  // The zlib stream goes out in IDAT chunks of 1 MiB, as encoders commonly write them; the rest waits in `idat`.
  constexpr std::size_t kChunk = 1u << 20;
  std::vector<unsigned char> idat{0x78, 0x01};  // zlib header: deflate, 32 KiB window, fastest
  uLong adler = 1;
  for (u32 group = 0; group < bands; group += group_bands) {
    const u32 count = std::min(group_bands, bands - group);
    loop.run(count, 1, [&](u32 i) { encode_band(group + i, parts[i]); });
    for (u32 i = 0; i < count; ++i) {
      Band& part = parts[i];
      if (part.status != Z_OK) throw std::runtime_error(fmt::format("the PNG encoder failed (zlib error {})", part.status));
      idat.insert(idat.end(), part.deflated.begin(), part.deflated.end());
      adler = adler32_combine(adler, part.adler, static_cast<z_off_t>(part.raw_bytes));
      part = Band{};
    }
    std::size_t written = 0;
    for (; idat.size() - written >= kChunk; written += kChunk) write_png_chunk(file, "IDAT", idat.data() + written, kChunk);
    idat.erase(idat.begin(), idat.begin() + static_cast<std::ptrdiff_t>(written));
  }
  idat.resize(idat.size() + 4);
  store_be32(idat.data() + idat.size() - 4, static_cast<u32>(adler));
  for (std::size_t at = 0; at < idat.size(); at += kChunk) write_png_chunk(file, "IDAT", idat.data() + at, std::min(kChunk, idat.size() - at));
  write_png_chunk(file, "IEND", nullptr, 0);
}

// Rows for the float formats are asked for in bands of about this many bytes.
constexpr std::size_t kFloatBandBytes = 8u << 20;

u32 float_band_rows(const ImageRows& image) {
  return static_cast<u32>(std::max<std::size_t>(1, kFloatBandBytes / (3 * sizeof(float) * std::max<std::size_t>(1, image.width))));
}

// Portable float map: little-endian (negative scale), rows from the bottom.
void write_pfm(AtomicFile& file, const ImageRows& image) {
  file.write(fmt::format("PF\n{} {}\n-1.0\n", image.width, image.height));
  const std::size_t row_floats = 3 * static_cast<std::size_t>(image.width);
  const u32 band_rows = float_band_rows(image);
  std::vector<float> band(row_floats * std::min(band_rows, image.height));
  for (u32 end = image.height; end > 0;) {
    const u32 first = end > band_rows ? end - band_rows : 0;
    image.fill(first, end - first, band.data());
    for (u32 row = end; row-- > first;) file.write(band.data() + (row - first) * row_floats, row_floats * sizeof(float));
    end = first;
  }
}

// OpenEXR writes through this stream into the AtomicFile, so its writes are checked like every other format's.
class ExrStream final : public Imf::OStream {
 public:
  explicit ExrStream(AtomicFile& file) : Imf::OStream(file.target().c_str()), file_(file) {}
  void write(const char data[], int bytes) override { file_.write(data, static_cast<std::size_t>(bytes)); }
  uint64_t tellp() override { return file_.position(); }
  void seekp(uint64_t position) override { file_.seek(position); }

 private:
  AtomicFile& file_;
};

// OpenEXR, float RGB, given a band of scan lines at a time (the library copies each band as it is given).
void write_exr(AtomicFile& file, const ImageRows& image) {
  Imf::Header header(static_cast<int>(image.width), static_cast<int>(image.height));
  for (const char* channel : {"R", "G", "B"}) header.channels().insert(channel, Imf::Channel(Imf::FLOAT));
  for (const ImageChannel& channel : image.channels) header.channels().insert(channel.name, Imf::Channel(Imf::FLOAT));
  ExrStream stream(file);
  // The file's line-offset table is written when `out` is destroyed, where OpenEXR swallows errors: a failure
  // there is still recorded by the AtomicFile, which then refuses to publish.
  Imf::OutputFile out(stream, header);
  const std::size_t x_stride = 3 * sizeof(float), y_stride = x_stride * image.width;
  const u32 band_rows = float_band_rows(image);
  std::vector<float> band(3 * static_cast<std::size_t>(image.width) * std::min(band_rows, image.height));
  for (u32 first = 0; first < image.height; first += band_rows) {
    const u32 rows = std::min(band_rows, image.height - first);
    image.fill(first, rows, band.data());
    // OpenEXR addresses a slice by absolute scan line: the base is where row 0 would be (never dereferenced).
    const std::uintptr_t base = reinterpret_cast<std::uintptr_t>(band.data()) - first * y_stride;
    Imf::FrameBuffer frame;
    frame.insert("R", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(base), x_stride, y_stride));
    frame.insert("G", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(base + sizeof(float)), x_stride, y_stride));
    frame.insert("B", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(base + 2 * sizeof(float)), x_stride, y_stride));
    // Other channels are whole planes in memory: addressed from their own row 0.
    for (const ImageChannel& channel : image.channels)
      frame.insert(channel.name, Imf::Slice(Imf::FLOAT, const_cast<char*>(reinterpret_cast<const char*>(channel.values)), sizeof(float),
                                            sizeof(float) * image.width));
    out.setFrameBuffer(frame);
    out.writePixels(static_cast<int>(rows));
  }
}

}  // namespace

void check_output_path(const std::filesystem::path& named) {
  auto refuse = [&](const std::string& reason) { throw InputError(fmt::format("{}: cannot write the image: {}", named.string(), reason)); };
  const std::filesystem::path path = written_path(named);
  // A file that exists and may not be written is refused, as cp refuses it (the write itself would replace it).
  if (std::filesystem::exists(path) && ::access(path.c_str(), W_OK) != 0) refuse(fmt::format("it is read-only ({})", std::strerror(errno)));
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

AtomicFile write_image_unpublished(const std::filesystem::path& path, const ImageRows& image) {
  const ImageFormat format = image_format_for(path);
  check_output_path(path);  // again: the folder may have changed while the image was rendered
  if (!image.channels.empty() && format != ImageFormat::kExr)
    throw InputError(fmt::format("{}: cannot write the image: only OpenEXR (.exr) holds render layers", path.string()));
  AtomicFile file(path, "the image");
  try {
    switch (format) {
      case ImageFormat::kPng: write_png([&](const void* data, std::size_t size) { file.write(data, size); }, image); break;
      case ImageFormat::kPfm: write_pfm(file, image); break;
      case ImageFormat::kExr: write_exr(file, image); break;
    }
  } catch (const std::exception& e) {
    file.fail(e.what());  // the file's own error where it failed first (OpenEXR wraps it in a message of its own)
  }
  file.finish();
  return file;
}

void write_image(const std::filesystem::path& path, const ImageRows& image) { write_image_unpublished(path, image).publish(); }

void write_image(const std::filesystem::path& path, const LinearImage& image) { write_image(path, rows_of(image)); }

std::vector<u8> encode_png(const ImageRows& image, int compression_level) {
  std::vector<u8> bytes;
  write_png([&](const void* data, std::size_t size) { bytes.insert(bytes.end(), static_cast<const u8*>(data), static_cast<const u8*>(data) + size); },
            image, compression_level);
  return bytes;
}

}  // namespace pt
