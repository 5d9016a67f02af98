// Fuzz target: any bytes read as an OBJ model file, with an MTL library, either give meshes that keep MeshFile's
// promises (indices within the vertices, per-vertex and per-triangle arrays of the right length, material and
// texture numbers that exist, finite positions and unit normals, counts within the limits) or raise one InputError;
// they never crash, hang, leak or trip a sanitizer. The bytes go through read_obj_file from files in a temporary
// folder: what comes after a line "#mtl" is written to m.mtl beside the OBJ file (which `mtllib m.mtl` reads), and
// the folder holds a small image, t.png, for map_Kd and map_Ke.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string_view>

#include "base/errors.hpp"
#include "fuzz_support.hpp"
#include "image/image_io.hpp"

namespace {

std::filesystem::path g_obj, g_mtl;

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  const std::filesystem::path folder = pt::fuzz::make_scratch_folder("obj");
  g_obj = folder / "model.obj";
  g_mtl = folder / "m.mtl";
  pt::LinearImage image;
  image.width = 2;
  image.height = 2;
  image.rgb = {1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1};
  pt::write_image(folder / "t.png", image);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  const std::size_t marker = input.find("\n#mtl\n");
  const std::string_view obj = input.substr(0, marker);
  pt::fuzz::write_input_file(g_obj, obj.data(), obj.size());
  if (marker != std::string_view::npos) {
    const std::string_view mtl = input.substr(marker + 6);
    pt::fuzz::write_input_file(g_mtl, mtl.data(), mtl.size());
  } else {
    std::filesystem::remove(g_mtl);
  }
  try {
    const pt::MeshFile file = pt::read_obj_file(g_obj);
    pt::fuzz::check_mesh_file(file);
    if (file.meshes.empty() || file.placements.size() != file.meshes.size()) __builtin_trap();
    for (const pt::MeshMaterial& material : file.materials)
      if (!(material.base_color.x >= 0 && material.base_color.x <= 1 && material.roughness >= 0 && material.roughness <= 1)) __builtin_trap();
  } catch (const pt::InputError&) {
  }
  return 0;
}
