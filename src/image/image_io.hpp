// Image files: textures in (8-bit, sRGB decoded to linear) and rendered images out (PNG, PFM, OpenEXR).
#pragma once

#include <filesystem>
#include <vector>

#include "kernel/platform.hpp"

namespace pt {

// Linear RGB, three floats per pixel, rows from the top.
struct LinearImage {
  u32 width = 0, height = 0;
  std::vector<float> rgb;
};

// Reads an 8-bit image (PNG, JPEG, BMP, TGA, ...) and decodes sRGB to linear. Throws InputError.
LinearImage read_texture_image(const std::filesystem::path& path);

// The output formats, chosen by the file's extension.
enum class ImageFormat { kPng, kPfm, kExr };

// The format for a path's extension; throws InputError for an unknown one.
ImageFormat image_format_for(const std::filesystem::path& path);

// Writes the image to a temporary file beside `path` and renames it into place, so a failure never leaves a
// half-written file under the final name. PNG is 8-bit sRGB (values clamped); PFM and OpenEXR keep linear floats.
// Throws InputError when the file cannot be written.
void write_image(const std::filesystem::path& path, const LinearImage& image);

// The sRGB transfer functions.
float srgb_to_linear(float encoded);
float linear_to_srgb(float linear);

}  // namespace pt
