// Fuzz target: any bytes read as an image texture (PNG, JPEG, BMP, TGA, GIF, PSD, HDR, PIC, PNM through stb_image)
// either give a texture within the documented limits or raise one InputError; they never crash, hang, leak or
// trip a sanitizer. The bytes go through read_texture_image, the function a scene's image textures are loaded
// with, from a file (it reads only files: the size check reads the PNG header from the descriptor).
#include <cstddef>
#include <cstdint>
#include <filesystem>

#include "base/errors.hpp"
#include "fuzz_support.hpp"
#include "image/image_io.hpp"

namespace {

std::filesystem::path g_file;

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  g_file = pt::fuzz::make_scratch_folder("texture") / "texture";
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  pt::fuzz::write_input_file(g_file, data, size);
  try {
    const pt::TextureImage image = pt::read_texture_image(g_file);
    const std::uint64_t texels = std::uint64_t{image.width} * image.height;
    if (image.width == 0 || image.height == 0 || image.width > pt::kMaxTextureSide || image.height > pt::kMaxTextureSide ||
        texels > pt::kMaxTextureTexels || image.srgb.size() != 3 * texels)
      __builtin_trap();
  } catch (const pt::InputError&) {
  }
  return 0;
}
