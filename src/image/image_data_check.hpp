// Whether an image file's bytes hold all the pixel data its header promises, checked before stb_image decodes it:
// the system's stb_image (2.27) reads past the end of a truncated file as zeros (TGA, BMP, PNM, PSD, GIF, JPEG,
// Radiance), keeps uninitialised memory for the missing texels of an uncompressed TGA, and loops for ever on a
// Radiance scanline whose run-length data ends early (CVE-2021-42715).
#pragma once

#include <optional>
#include <span>
#include <string>

#include "kernel/platform.hpp"

namespace pt {

// What is missing or broken, as the end of a sentence ("truncated: ..."), or nothing when the data is complete or
// the format is one stb refuses by itself when cut short (PNG's compressed stream) or does not know. Reads only
// within `bytes`, never more than once over them.
std::optional<std::string> image_data_problem(std::span<const u8> bytes);

}  // namespace pt
