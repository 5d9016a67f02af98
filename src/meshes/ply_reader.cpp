// PLY model files -> MeshFile (being written).
#include <fmt/format.h>

#include "base/errors.hpp"
#include "meshes/mesh.hpp"

namespace pt {

MeshFile read_ply_file(const std::filesystem::path& path) {
  throw InputError(fmt::format("{}: PLY files are not read yet", path.string()));
}

}  // namespace pt
