// Fuzz target: any bytes read as an image texture (PNG, JPEG, BMP, TGA, GIF, PSD, HDR, PIC, PNM through stb_image)
// either give a texture within the documented limits or raise one InputError; they never crash, hang, leak or
// trip a sanitizer. The bytes go through read_texture_image, the function a scene's image textures are loaded
// with, from a file (it reads only files: the size check reads the PNG header from the descriptor).
#include <fcntl.h>
#include <stdlib.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "base/errors.hpp"
#include "image/image_io.hpp"

namespace {

std::filesystem::path g_folder;
std::filesystem::path g_file;

void remove_scratch() {
  std::error_code ignored;
  std::filesystem::remove_all(g_folder, ignored);
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  std::string pattern = (std::filesystem::temp_directory_path() / "pt-fuzz-texture-XXXXXX").string();
  if (!::mkdtemp(pattern.data())) {
    std::perror("mkdtemp");
    std::abort();
  }
  g_folder = pattern;
  g_file = g_folder / "texture";
  std::atexit(remove_scratch);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const int fd = ::open(g_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd < 0) std::abort();
  for (std::size_t done = 0; done < size;) {
    const ssize_t n = ::write(fd, data + done, size - done);
    if (n <= 0) std::abort();
    done += static_cast<std::size_t>(n);
  }
  ::close(fd);
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
