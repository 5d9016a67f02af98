// The limit on an image's pixel count, applied to sizes given on the command line (the scene loader applies the
// same limit to sizes in scene files).
#pragma once

#include <string>

#include <fmt/format.h>

#include "base/errors.hpp"
#include "loading/scene_loader.hpp"

namespace pt {

// Throws InputError naming `given_by` (the options that set the size) when width x height exceeds kMaxImagePixels.
inline void check_image_size(u32 width, u32 height, const std::string& given_by) {
  if (static_cast<u64>(width) * height > kMaxImagePixels)
    throw InputError(fmt::format("{}: {}x{} pixels is too large (at most {} pixels, e.g. 8192x8192)", given_by, width, height, kMaxImagePixels));
}

}  // namespace pt
