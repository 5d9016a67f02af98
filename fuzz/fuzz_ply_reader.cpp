// Fuzz target: any bytes read as a PLY model file (ASCII or binary) either give meshes that keep MeshFile's promises
// (indices within the vertices, per-vertex arrays of the vertices' length, finite positions and unit normals,
// counts within the limits) or raise one InputError; they never crash, hang, leak or trip a sanitizer. The bytes go
// through read_ply_file, from a file in a temporary folder, as a scene's meshes are read.
#include <fcntl.h>
#include <stdlib.h>
#include <unistd.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

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

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  std::string pattern = (std::filesystem::temp_directory_path() / "pt-fuzz-ply-XXXXXX").string();
  if (!::mkdtemp(pattern.data())) {
    std::perror("mkdtemp");
    std::abort();
  }
  g_folder = pattern;
  g_file = g_folder / "model.ply";
  std::atexit(remove_scratch);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  write_file(g_file, data, size);
  try {
    const pt::MeshFile file = pt::read_ply_file(g_file);
    if (file.meshes.size() != 1 || file.materials.size() != 1 || file.placements.size() != 1) __builtin_trap();
    const pt::TriangleMesh& mesh = file.meshes[0];
    if (mesh.triangles.empty() || mesh.triangles.size() > pt::kMaxMeshTriangles || mesh.positions.size() > pt::kMaxMeshVertices) __builtin_trap();
    if (!mesh.normals.empty() && mesh.normals.size() != mesh.positions.size()) __builtin_trap();
    if (!mesh.uvs.empty() && mesh.uvs.size() != mesh.positions.size()) __builtin_trap();
    for (const auto& triangle : mesh.triangles)
      for (const pt::u32 index : triangle)
        if (index >= mesh.positions.size()) __builtin_trap();
    for (const pt::Vec3d& p : mesh.positions)
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) __builtin_trap();
    for (const pt::Vec3d& n : mesh.normals)
      if (!(std::fabs(pt::length(n) - 1) < 1e-9)) __builtin_trap();
    for (const auto& uv : mesh.uvs)
      if (!std::isfinite(uv[0]) || !std::isfinite(uv[1])) __builtin_trap();
  } catch (const pt::InputError&) {
  }
  return 0;
}
