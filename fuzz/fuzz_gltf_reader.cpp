// Fuzz target: any bytes read as a glTF model file either give a MeshFile that keeps its promises (every index
// names a vertex, per-vertex arrays as long as the positions, materials and textures where they are referred to,
// counts within the limits) or raise one InputError; they never crash, hang, leak or trip a sanitizer. The bytes go
// through read_gltf_file, the function a scene's model files are read with, from a file (it reads only files). The
// reader tells a .glb from a .gltf by the first bytes, not the extension, so one name covers both. Beside the file
// lie a small buffer and a PNG image that inputs may name ("buffer.bin", "texture.png"), so that external files
// are reached too; fuzz/make_gltf_seeds.py writes seeds that use them.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <vector>

#include "base/errors.hpp"
#include "fuzz_support.hpp"

namespace {

std::filesystem::path g_file;

// buffer.bin: a triangle's positions (36 bytes), its texture coordinates (24) and its indices as unsigned shorts
// (6, and 2 of padding): 68 bytes, as fuzz/make_gltf_seeds.py describes it.
std::vector<std::uint8_t> companion_buffer() {
  const float positions[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  const float uvs[6] = {0, 0, 1, 0, 0, 1};
  const std::uint16_t indices[4] = {0, 1, 2, 0};
  std::vector<std::uint8_t> bytes(sizeof positions + sizeof uvs + sizeof indices);
  std::memcpy(bytes.data(), positions, sizeof positions);
  std::memcpy(bytes.data() + sizeof positions, uvs, sizeof uvs);
  std::memcpy(bytes.data() + sizeof positions + sizeof uvs, indices, sizeof indices);
  return bytes;
}

// texture.png: 2x2 RGB.
constexpr std::uint8_t kTexturePng[] = {0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44,
                                        0x52, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x02, 0x08, 0x02, 0x00, 0x00, 0x00, 0xfd,
                                        0xd4, 0x9a, 0x73, 0x00, 0x00, 0x00, 0x12, 0x49, 0x44, 0x41, 0x54, 0x78, 0xda, 0x63, 0xf8,
                                        0xcf, 0xc0, 0xc0, 0x00, 0xc2, 0x0c, 0xff, 0x81, 0x00, 0x00, 0x1f, 0xee, 0x05, 0xfb, 0xf1,
                                        0xab, 0xba, 0x77, 0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82};

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  const std::filesystem::path folder = pt::fuzz::make_scratch_folder("gltf");
  g_file = folder / "model.gltf";
  const std::vector<std::uint8_t> buffer = companion_buffer();
  pt::fuzz::write_input_file(folder / "buffer.bin", buffer.data(), buffer.size());
  pt::fuzz::write_input_file(folder / "texture.png", kTexturePng, sizeof kTexturePng);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  pt::fuzz::write_input_file(g_file, data, size);
  try {
    pt::fuzz::check_mesh_file(pt::read_gltf_file(g_file));
  } catch (const pt::InputError&) {
  }
  return 0;
}
