// Fuzz target: any bytes read as an OBJ model file, with an MTL library, either give meshes that keep MeshFile's
// promises (indices within the vertices, per-vertex and per-triangle arrays of the right length, material and
// texture numbers that exist, finite positions and unit normals, counts within the limits) or raise one InputError;
// they never crash, hang, leak or trip a sanitizer. The bytes go through read_obj_file from files in a temporary
// folder: what comes after a line "#mtl" is written to m.mtl beside the OBJ file (which `mtllib m.mtl` reads), and
// the folder holds a small image, t.png, for map_Kd and map_Ke.
#include <fcntl.h>
#include <stdlib.h>
#include <unistd.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string_view>
#include <string>

#include "base/errors.hpp"
#include "image/image_io.hpp"
#include "meshes/mesh.hpp"

namespace {

std::filesystem::path g_folder;
std::filesystem::path g_obj;
std::filesystem::path g_mtl;

void remove_scratch() {
  std::error_code ignored;
  std::filesystem::remove_all(g_folder, ignored);
}

void write_file(const std::filesystem::path& path, std::string_view bytes) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd < 0) std::abort();
  for (std::size_t done = 0; done < bytes.size();) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n <= 0) std::abort();
    done += static_cast<std::size_t>(n);
  }
  ::close(fd);
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  std::string pattern = (std::filesystem::temp_directory_path() / "pt-fuzz-obj-XXXXXX").string();
  if (!::mkdtemp(pattern.data())) {
    std::perror("mkdtemp");
    std::abort();
  }
  g_folder = pattern;
  g_obj = g_folder / "model.obj";
  g_mtl = g_folder / "m.mtl";
  std::atexit(remove_scratch);
  pt::LinearImage image;
  image.width = 2;
  image.height = 2;
  image.rgb = {1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1};
  pt::write_image(g_folder / "t.png", image);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  const std::size_t marker = input.find("\n#mtl\n");
  write_file(g_obj, input.substr(0, marker));
  if (marker != std::string_view::npos) write_file(g_mtl, input.substr(marker + 6));
  else std::filesystem::remove(g_mtl);
  try {
    const pt::MeshFile file = pt::read_obj_file(g_obj);
    if (file.meshes.empty() || file.materials.empty() || file.placements.size() != file.meshes.size()) __builtin_trap();
    pt::u64 triangles = 0, vertices = 0;
    for (const pt::TriangleMesh& mesh : file.meshes) {
      triangles += mesh.triangles.size();
      vertices += mesh.positions.size();
      if (mesh.triangles.empty()) __builtin_trap();
      if (!mesh.normals.empty() && mesh.normals.size() != mesh.positions.size()) __builtin_trap();
      if (!mesh.uvs.empty() && mesh.uvs.size() != mesh.positions.size()) __builtin_trap();
      if (!mesh.materials.empty() && mesh.materials.size() != mesh.triangles.size()) __builtin_trap();
      for (const auto& triangle : mesh.triangles)
        for (const pt::u32 index : triangle)
          if (index >= mesh.positions.size()) __builtin_trap();
      for (const pt::u32 material : mesh.materials)
        if (material >= file.materials.size()) __builtin_trap();
      for (const pt::Vec3d& p : mesh.positions)
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) __builtin_trap();
      for (const pt::Vec3d& n : mesh.normals)
        if (!(std::fabs(pt::length(n) - 1) < 1e-9)) __builtin_trap();
    }
    if (triangles > pt::kMaxMeshTriangles || vertices > pt::kMaxMeshVertices) __builtin_trap();
    for (const pt::MeshMaterial& material : file.materials) {
      if (material.base_color_texture >= static_cast<pt::i32>(file.textures.size()) || material.base_color_texture < -1) __builtin_trap();
      if (material.emission_texture >= static_cast<pt::i32>(file.textures.size()) || material.emission_texture < -1) __builtin_trap();
      if (!(material.base_color.x >= 0 && material.base_color.x <= 1 && material.roughness >= 0 && material.roughness <= 1)) __builtin_trap();
    }
  } catch (const pt::InputError&) {
  }
  return 0;
}
