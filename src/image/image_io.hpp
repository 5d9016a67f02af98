// Image files: textures in (8-bit, sRGB decoded to linear) and rendered images out (PNG, PFM, OpenEXR).
#pragma once

#include <filesystem>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "base/atomic_file.hpp"
#include "kernel/platform.hpp"

namespace pt {

// Linear RGB, three floats per pixel, rows from the top.
struct LinearImage {
  u32 width = 0, height = 0;
  std::vector<float> rgb;
};

// An image handed to a writer a band of rows at a time: fill(first_row, row_count, rgb) puts rows
// [first_row, first_row + row_count) into `rgb` as linear RGB, three floats per pixel. A render's film is written
// this way, converted band by band, so that no full-size float copy of it is ever made. fill may be called from
// several threads at once, for different rows.
// Channels written beside R, G and B where the format holds more (OpenEXR: render layers, named "albedo.R" and so
// on): `values` is one float a pixel, row-major, rows from the top, alive while the image is written.
struct ImageChannel {
  std::string name;
  const float* values;
};
struct ImageRows {
  u32 width = 0, height = 0;
  std::function<void(u32 first_row, u32 row_count, float* rgb)> fill;
  std::vector<ImageChannel> channels;
};

// The rows of an image held whole.
ImageRows rows_of(const LinearImage& image);

// An 8-bit texture as stored: three sRGB-encoded bytes per texel, rows from the top. Kernels decode a byte through
// a 256-entry table (srgb_decode_table), which gives the same linear value as decoding at load time in a quarter
// of the memory: bilinear lookups land all over an image, so its size decides how often they miss the caches.
struct TextureImage {
  u32 width = 0, height = 0;
  std::vector<u8> srgb;
};

// The largest texture: its size is checked from the file's header before it is decoded, so that a small file
// claiming a huge image costs nothing. 2^26 texels are 192 MiB as stored (three bytes each), an 8192x8192 image.
inline constexpr u64 kMaxTextureSide = 16384;
inline constexpr u64 kMaxTextureTexels = u64{1} << 26;

// An image's size in texels, as its header gives it.
struct TextureSize {
  u32 width = 0, height = 0;
};

// The size of the image read_texture_image would read, from the file's header alone (the data is neither read
// nor decoded), checked against the limits below. Throws InputError as read_texture_image does.
TextureSize read_texture_image_size(const std::filesystem::path& path);

// Reads an 8-bit image (PNG, JPEG, BMP, TGA, ...) from a regular file, at most kMaxTextureSide on a side and
// kMaxTextureTexels in all. Throws InputError.
TextureImage read_texture_image(const std::filesystem::path& path);

// The same for an image held in memory (one embedded in a model file), with the same checks and limits; messages
// name it "image 'NAME'" where read_texture_image says "image file 'PATH'". Throws InputError.
TextureImage read_texture_image_from_memory(std::span<const u8> bytes, const std::string& name_for_messages);

// The largest environment image: 2^25 texels (an 8192x4096 map), 12 bytes each as linear floats, plus its sampling
// distribution (about 8 bytes a texel); at most kMaxTextureSide on a side.
inline constexpr u64 kMaxEnvironmentTexels = u64{1} << 25;

// Reads an environment image as linear RGB: OpenEXR (its R, G and B channels, or Y for a grey image; the data
// window), Radiance .hdr (through stb_image), or an 8-bit image as read_texture_image reads it, sRGB decoded. The
// size is checked before the pixels are decoded; a texel that is not finite or is negative is refused, by its
// position. Throws InputError ("image file 'PATH' ..." or "cannot read image file 'PATH': ...", one line).
LinearImage read_environment_image(const std::filesystem::path& path);

// The linear value of each sRGB byte: srgb_to_linear(i / 255).
std::vector<float> srgb_decode_table();

// The output formats, chosen by the file's extension.
enum class ImageFormat { kPng, kPfm, kExr };

// The format for a path's extension; throws InputError for an unknown one.
ImageFormat image_format_for(const std::filesystem::path& path);

// Checks, before any work is spent, that an image can be written at `path` (through its symbolic links, where the
// write lands: base/atomic_file.hpp): its folder exists and is a folder, the path itself is not a folder nor a
// file that may not be written, and a new file can be created beside it. Throws InputError
// ("PATH: cannot write the image: REASON").
void check_output_path(const std::filesystem::path& path);

// Writes the image through an AtomicFile (base/atomic_file.hpp): a failure, a full disk included, never leaves a
// half-written file under the final name nor replaces the file that was there. PNG is 8-bit sRGB (values clamped);
// PFM and OpenEXR keep linear floats; only OpenEXR takes an image's other channels (ImageRows::channels). Throws
// InputError ("PATH: cannot write the image: REASON").
void write_image(const std::filesystem::path& path, const ImageRows& image);
void write_image(const std::filesystem::path& path, const LinearImage& image);

// write_image but for the rename: the image is complete and synced under its temporary name, and takes its place
// when the caller publishes it (with other files, all or nothing).
AtomicFile write_image_unpublished(const std::filesystem::path& path, const ImageRows& image);

// The PNG file write_image writes, in memory, at zlib's `compression_level` (write_image's is 1, the fastest that
// compresses; 0 stores the rows as they are, for a preview page on this machine: no time spent making it smaller).
std::vector<u8> encode_png(const ImageRows& image, int compression_level = 1);

// The sRGB transfer functions.
float srgb_to_linear(float encoded);
float linear_to_srgb(float linear);
// The 8-bit sRGB value of a linear one as PNGs are written: lround(linear_to_srgb(clamp(linear, 0, 1)) * 255), and 0
// where it is not finite; the same bytes, found without a power.
u8 linear_to_srgb_byte(float linear);

}  // namespace pt
