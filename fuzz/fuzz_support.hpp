// What the fuzz targets that read files share: a scratch folder for their inputs, writing an input to a file there,
// and the promises every MeshFile a model reader returns must keep.
#pragma once

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

#include "loading/model_files.hpp"

namespace pt::fuzz {

// A fresh folder under TMPDIR, pt-fuzz-NAME-XXXXXX, removed with what it holds when the process exits.
inline std::filesystem::path make_scratch_folder(const char* name) {
  static std::filesystem::path folder;
  std::string pattern = (std::filesystem::temp_directory_path() / (std::string("pt-fuzz-") + name + "-XXXXXX")).string();
  if (!::mkdtemp(pattern.data())) {
    std::perror("mkdtemp");
    std::abort();
  }
  folder = pattern;
  std::atexit([] {
    std::error_code ignored;
    std::filesystem::remove_all(folder, ignored);
  });
  return folder;
}

// Writes the bytes to the file, replacing it; a target cannot go on without its input, so a failure aborts.
inline void write_input_file(const std::filesystem::path& path, const void* data, std::size_t size) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd < 0) std::abort();
  const auto* bytes = static_cast<const std::uint8_t*>(data);
  for (std::size_t done = 0; done < size;) {
    const ssize_t n = ::write(fd, bytes + done, size - done);
    if (n <= 0) std::abort();
    done += static_cast<std::size_t>(n);
  }
  ::close(fd);
}

// What every MeshFile read must hold (scene/mesh.hpp); a broken promise stops the fuzzer like a crash.
inline void check_mesh_file(const MeshFile& file) {
  if (file.materials.empty()) __builtin_trap();
  std::uint64_t triangles = 0, vertices = 0;
  for (const TriangleMesh& mesh : file.meshes) {
    const std::size_t n = mesh.positions.size();
    if (mesh.triangles.empty()) __builtin_trap();
    if ((!mesh.normals.empty() && mesh.normals.size() != n) || (!mesh.uvs.empty() && mesh.uvs.size() != n) ||
        (!mesh.materials.empty() && mesh.materials.size() != mesh.triangles.size()))
      __builtin_trap();
    for (const auto& triangle : mesh.triangles)
      for (const u32 index : triangle)
        if (index >= n) __builtin_trap();
    for (const u32 material : mesh.materials)
      if (material >= file.materials.size()) __builtin_trap();
    for (const Vec3d& p : mesh.positions)
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) __builtin_trap();
    for (const Vec3d& normal : mesh.normals)
      if (!(std::fabs(length(normal) - 1) < 1e-6)) __builtin_trap();
    for (const auto& uv : mesh.uvs)
      if (!std::isfinite(uv[0]) || !std::isfinite(uv[1])) __builtin_trap();
    triangles += mesh.triangles.size();
    vertices += n;
  }
  if (triangles > kMaxMeshTriangles || vertices > kMaxMeshVertices) __builtin_trap();
  for (const MeshPlacement& placement : file.placements)
    if (placement.mesh >= file.meshes.size() || placement.transform.determinant() == 0) __builtin_trap();
  for (const MeshMaterial& material : file.materials)
    if (material.base_color_texture >= static_cast<i32>(file.textures.size()) || material.base_color_texture < -1 ||
        material.emission_texture >= static_cast<i32>(file.textures.size()) || material.emission_texture < -1)
      __builtin_trap();
  for (const TextureImage& texture : file.textures)
    if (texture.srgb.size() != 3ull * texture.width * texture.height) __builtin_trap();
}

}  // namespace pt::fuzz
