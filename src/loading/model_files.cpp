// Model files: the reader chosen by the file's extension.
#include <algorithm>
#include <cctype>

#include <fmt/format.h>

#include "base/errors.hpp"
#include "loading/model_files.hpp"

namespace pt {

MeshFile read_mesh_file(const std::filesystem::path& path, ModelReferences references) {
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (extension == ".obj") return read_obj_file(path, references);
  if (extension == ".ply") return read_ply_file(path);
  if (extension == ".gltf" || extension == ".glb") return read_gltf_file(path, references);
  throw InputError(fmt::format("{}: unknown model file type '{}' (expected .obj, .ply, .gltf or .glb)", path.string(), extension));
}

}  // namespace pt
