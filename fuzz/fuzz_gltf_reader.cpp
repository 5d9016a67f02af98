// Fuzz target: any bytes read as a glTF model file either give a MeshFile that keeps its promises (every index
// names a vertex, per-vertex arrays as long as the positions, materials and textures where they are referred to,
// counts within the limits) or raise one InputError; they never crash, hang, leak or trip a sanitizer. The bytes go
// through read_gltf_file, the function a scene's model files are read with, from a file (it reads only files). The
// reader tells a .glb from a .gltf by the first bytes, not the extension, so one name covers both. Beside the file
// lie a small buffer and a PNG image that inputs may name ("buffer.bin", "texture.png"), so that external files
// are reached too; fuzz/make_gltf_seeds.py writes seeds that use them.
#include <fcntl.h>
#include <stdlib.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "base/errors.hpp"
#include "meshes/mesh.hpp"

namespace {

std::filesystem::path g_folder;
std::filesystem::path g_file;

void remove_scratch() {
  std::error_code ignored;
  std::filesystem::remove_all(g_folder, ignored);
}

void write_file(const std::filesystem::path& path, const std::uint8_t* data, std::size_t size) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd < 0) std::abort();
  for (std::size_t done = 0; done < size;) {
    const ssize_t n = ::write(fd, data + done, size - done);
    if (n <= 0) std::abort();
    done += static_cast<std::size_t>(n);
  }
  ::close(fd);
}

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
constexpr std::uint8_t kTexturePng[] = {
    0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52, 0x00, 0x00, 0x00,
    0x02, 0x00, 0x00, 0x00, 0x02, 0x08, 0x02, 0x00, 0x00, 0x00, 0xfd, 0xd4, 0x9a, 0x73, 0x00, 0x00, 0x00, 0x12, 0x49,
    0x44, 0x41, 0x54, 0x78, 0xda, 0x63, 0xf8, 0xcf, 0xc0, 0xc0, 0x00, 0xc2, 0x0c, 0xff, 0x81, 0x00, 0x00, 0x1f, 0xee,
    0x05, 0xfb, 0xf1, 0xab, 0xba, 0x77, 0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82};

// What every MeshFile read must hold; a broken promise stops the fuzzer like a crash.
void check(const pt::MeshFile& file) {
  if (file.materials.empty()) __builtin_trap();
  std::uint64_t triangles = 0, vertices = 0;
  for (const pt::TriangleMesh& mesh : file.meshes) {
    const std::size_t n = mesh.positions.size();
    if ((!mesh.normals.empty() && mesh.normals.size() != n) || (!mesh.uvs.empty() && mesh.uvs.size() != n) ||
        (!mesh.materials.empty() && mesh.materials.size() != mesh.triangles.size()))
      __builtin_trap();
    for (const auto& t : mesh.triangles)
      for (const std::uint32_t v : t)
        if (v >= n) __builtin_trap();
    for (const std::uint32_t m : mesh.materials)
      if (m >= file.materials.size()) __builtin_trap();
    for (const pt::Vec3d& p : mesh.positions)
      if (!pt::is_finite(p)) __builtin_trap();
    triangles += mesh.triangles.size();
    vertices += n;
  }
  if (triangles > pt::kMaxMeshTriangles || vertices > pt::kMaxMeshVertices) __builtin_trap();
  for (const pt::MeshPlacement& placement : file.placements)
    if (placement.mesh >= file.meshes.size() || placement.transform.determinant() == 0) __builtin_trap();
  for (const pt::MeshMaterial& material : file.materials)
    if (material.base_color_texture >= static_cast<std::int32_t>(file.textures.size()) ||
        material.emission_texture >= static_cast<std::int32_t>(file.textures.size()))
      __builtin_trap();
  for (const pt::TextureImage& texture : file.textures)
    if (texture.srgb.size() != 3ull * texture.width * texture.height) __builtin_trap();
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  std::string pattern = (std::filesystem::temp_directory_path() / "pt-fuzz-gltf-XXXXXX").string();
  if (!::mkdtemp(pattern.data())) {
    std::perror("mkdtemp");
    std::abort();
  }
  g_folder = pattern;
  g_file = g_folder / "model.gltf";
  std::atexit(remove_scratch);
  const std::vector<std::uint8_t> buffer = companion_buffer();
  write_file(g_folder / "buffer.bin", buffer.data(), buffer.size());
  write_file(g_folder / "texture.png", kTexturePng, sizeof kTexturePng);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  write_file(g_file, data, size);
  try {
    check(pt::read_gltf_file(g_file));
  } catch (const pt::InputError&) {
  }
  return 0;
}
