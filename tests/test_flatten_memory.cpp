// The memory flattening a large mesh takes, measured as the growth of the process's resident memory: its own
// executable, so that no other test's allocations stand in the way, and one test. The bound is the flat scene's own
// arrays plus the transient arrays the layout of the build names (docs/meshes.md, "Bytes per triangle").
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>

#include "flat/bvh_builder.hpp"
#include "flat/flat_scene.hpp"
#include "loading/scene_loader.hpp"
#include "scene/mesh.hpp"

namespace pt {
namespace {

std::size_t resident_bytes() {
  std::FILE* statm = std::fopen("/proc/self/statm", "r");
  unsigned long pages = 0, resident = 0;
  if (!statm || std::fscanf(statm, "%lu %lu", &pages, &resident) != 2) ADD_FAILURE() << "cannot read /proc/self/statm";
  if (statm) std::fclose(statm);
  return resident * static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
}

std::size_t peak_resident_bytes() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<std::size_t>(usage.ru_maxrss) * 1024;
}

// A closed sphere of rings x 2 rings quads (two triangles each), bumpy, with normals and uvs; its arrays made at
// their final size, so that making it leaves no freed memory behind for the flattening to reuse unseen.
std::shared_ptr<MeshFile> bumpy_sphere(u32 rings) {
  const u32 segments = 2 * rings;
  auto file = std::make_shared<MeshFile>();
  file->path = "generated.ply";
  TriangleMesh mesh;
  mesh.name = "bumpy sphere";
  const std::size_t vertices = static_cast<std::size_t>(rings + 1) * (segments + 1);
  mesh.positions.reserve(vertices);
  mesh.normals.reserve(vertices);
  mesh.uvs.reserve(vertices);
  const double pi = 3.14159265358979323846;
  for (u32 r = 0; r <= rings; ++r)
    for (u32 s = 0; s <= segments; ++s) {
      const double theta = pi * r / rings, phi = 2 * pi * s / segments;
      const Vec3d n{std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi)};
      const double radius = 1 + 0.02 * std::sin(40 * theta) * std::sin(40 * phi);
      const Vec3d p = n * radius;
      mesh.positions.push_back(Vec3d{static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z)});  // as a PLY file's floats
      mesh.normals.push_back(n);
      mesh.uvs.push_back({static_cast<double>(s) / segments, 1 - static_cast<double>(r) / rings});
    }
  mesh.triangles.reserve(2 * static_cast<std::size_t>(rings) * segments);
  for (u32 r = 0; r < rings; ++r)
    for (u32 s = 0; s < segments; ++s) {
      const u32 a = r * (segments + 1) + s, b = a + segments + 1;
      mesh.triangles.push_back({a, b, a + 1});
      mesh.triangles.push_back({a + 1, b, b + 1});
    }
  file->meshes.push_back(std::move(mesh));
  file->materials.push_back(MeshMaterial{});
  file->placements.push_back(MeshPlacement{0, AffineTransform{}});
  return file;
}

TEST(FlattenMemory, AMeshTakesItsFlatArraysAndTheBuildsTransientArraysAtMost) {
#if PT_TEST_SANITIZED
  GTEST_SKIP() << "a sanitizer's allocator adds red zones and keeps freed memory in quarantine: resident memory says nothing of the program's own";
#endif
  SceneDescription scene;
  scene.source = "generated";
  scene.camera.look_from = {0, 0, 4};
  scene.camera.look_at = {0, 0, 0};
  scene.camera.focus_distance = 4;
  const u32 file = add_mesh_file(scene, bumpy_sphere(316), "/objects");  // 399,424 triangles
  SceneObject object;
  object.shape = MeshSettings{file, AffineTransform{}};
  object.material = kMeshMaterials;
  scene.objects.push_back(object);
  const RenderSettings settings;

  const std::size_t before = resident_bytes();
  const FlatScene<float> flat = flatten_scene<float>(scene, settings);
  const std::size_t grown = peak_resident_bytes() - before;

  const std::size_t triangles = flat.mesh_triangles.size(), nodes = flat.mesh_nodes.size();
  ASSERT_GT(triangles, 390000u);  // less the poles' triangles of zero area, dropped
  // While the binary tree is built: a float box and a place in the order for each triangle, and the nodes of the
  // tree's second half, built into a list of their own and then copied (at most all of them). The triangles and
  // the nodes themselves become flat arrays (converted in place).
  const std::size_t build = triangles * (sizeof(FloatBox) + sizeof(u32)) + nodes * sizeof(BvhNode<float>);
  // While the wide tree is folded: one byte per binary node and number of children.
  const std::size_t fold = nodes * kWideBvhWidth;
  // Thread stacks, the allocator's rounding to pages, the scene's few other arrays.
  const std::size_t slack = std::size_t{8} << 20;
  const std::size_t bound = flat.bytes() + std::max(build, fold) + slack;
  EXPECT_LE(grown, bound) << "flat arrays " << flat.bytes() / triangles << " B/triangle, transient bound " << std::max(build, fold) / triangles
                          << " B/triangle, grown " << grown / triangles << " B/triangle";
  std::printf("%zu triangles: flat arrays %.1f B/triangle, resident memory grown by %.1f B/triangle (bound %.1f)\n", triangles,
              static_cast<double>(flat.bytes()) / triangles, static_cast<double>(grown) / triangles, static_cast<double>(bound) / triangles);
}

TEST(SceneLoading, ALargeFilesTextIsNotHeldWhileItIsRead) {
#if PT_TEST_SANITIZED
  GTEST_SKIP() << "a sanitizer's allocator adds red zones and keeps freed memory in quarantine: resident memory says nothing of the program's own";
#endif
  // 64 MB of text that describes little: 2,000 spheres, each followed by 32 KB of spaces. Read into memory, the
  // text alone would raise the peak by 64 MB; mapped, with the pages the reader has passed let go, by a few steps.
  const std::filesystem::path file = std::filesystem::temp_directory_path() / ("pathtracer-spaced-" + std::to_string(getpid()) + ".json");
  {
    std::ofstream out(file, std::ios::binary);
    out << R"({"camera": {"look_from": [0, 0, 5], "look_at": [0, 0, 0], "vertical_fov": 40},)" << "\n"
        << R"("materials": {"grey": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}}, "objects": [)" << "\n";
    const std::string spaces(32 << 10, ' ');
    for (int i = 0; i < 2000; ++i)
      out << (i ? "," : "") << R"({"type": "sphere", "center": [)" << i << R"(, 0, 0], "radius": 0.5, "material": "grey"})" << spaces;
    out << "]}\n";
  }
  ASSERT_GT(std::filesystem::file_size(file), std::size_t{62} << 20);
  const std::size_t before = resident_bytes();
  const std::size_t peak_before = peak_resident_bytes();
  const SceneDescription scene = load_scene_file(file);
  const std::size_t peak_after = peak_resident_bytes();
  std::filesystem::remove(file);
  ASSERT_EQ(scene.objects.size(), 2000u);
  // The peak can only have grown from where it was; measured from the resident memory before the load.
  const std::size_t grown = peak_after > std::max(before, peak_before) ? peak_after - before : 0;
  EXPECT_LE(grown, std::size_t{24} << 20) << "loading a 64 MB file of 2,000 spheres raised the peak by " << (grown >> 20) << " MB";
  std::printf("64 MB scene file of 2,000 objects: peak resident memory grown by %.1f MB while loading\n", static_cast<double>(grown) / (1 << 20));
}

}  // namespace
}  // namespace pt
