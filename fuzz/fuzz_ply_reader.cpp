// Fuzz target: any bytes read as a PLY model file (ASCII or binary) either give meshes that keep MeshFile's promises
// (indices within the vertices, per-vertex arrays of the vertices' length, finite positions and unit normals,
// counts within the limits) or raise one InputError; they never crash, hang, leak or trip a sanitizer. The bytes go
// through read_ply_file, from a file in a temporary folder, as a scene's meshes are read.
#include <cstddef>
#include <cstdint>
#include <filesystem>

#include "base/errors.hpp"
#include "fuzz_support.hpp"

namespace {

std::filesystem::path g_file;

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  g_file = pt::fuzz::make_scratch_folder("ply") / "model.ply";
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  pt::fuzz::write_input_file(g_file, data, size);
  try {
    const pt::MeshFile file = pt::read_ply_file(g_file);
    pt::fuzz::check_mesh_file(file);
    if (file.meshes.size() != 1 || file.materials.size() != 1 || file.placements.size() != 1) __builtin_trap();
  } catch (const pt::InputError&) {
  }
  return 0;
}
