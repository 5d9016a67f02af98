// Whether an image file's bytes hold all the pixel data its header promises, checked before stb_image decodes it:
// the system's stb_image (2.27) reads past the end of a truncated file as zeros (TGA, BMP, PNM, PSD, GIF, JPEG,
// Radiance), keeps uninitialised memory for the missing texels of an uncompressed TGA, and loops for ever on a
// Radiance scanline whose run-length data ends early (CVE-2021-42715).
#pragma once

#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "kernel/platform.hpp"

namespace pt {

// What is missing or broken, as the end of a sentence ("truncated: ..."), or nothing when the data is complete or
// the format is one stb refuses by itself when cut short (PNG's compressed stream) or does not know. Reads only
// within `bytes`, never more than once over them.
std::optional<std::string> image_data_problem(std::span<const u8> bytes);

// A PNG's bytes without its empty IDAT chunks, where it has any: they are legal, but stb_image 2.27 copies the first
// one's zero bytes into a buffer it has not yet allocated (memcpy to a null pointer, undefined behaviour; found by
// fuzz/fuzz_texture_image). Nothing for a PNG without them, or another format.
std::optional<std::vector<u8>> png_without_empty_data_chunks(std::span<const u8> bytes);

// How many of a file's first bytes image_header_problem looks at.
inline constexpr std::size_t kImageHeaderBytes = 65536;

// What is wrong with an image's header, from its first bytes (up to kImageHeaderBytes, fewer if the file is
// shorter), before stb_image reads it for the image's size: a PNM's width, height or largest value whose digits
// overflow stb's int. Nothing where the header is sound or the format not one of these.
std::optional<std::string> image_header_problem(std::span<const u8> start);

}  // namespace pt
