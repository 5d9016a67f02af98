// Times flattening a scene of one large triangle mesh (a displaced sphere of N triangles, made in memory) and
// reports the flat scene's bytes per triangle and the peak memory: the mesh figures of BENCHMARKS.md.
//
// Usage: pt_mesh_flatten [MILLIONS_OF_TRIANGLES=2] [INSTANCES=1]
#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>

#include "flat/flat_scene.hpp"
#include "loading/scene_loader.hpp"
#include "scene/mesh.hpp"

namespace {

// A sphere of rings x segments quads (two triangles each) with a bumpy radius, normals and uvs.
std::shared_ptr<pt::MeshFile> bumpy_sphere(pt::u32 rings, pt::u32 segments) {
  auto file = std::make_shared<pt::MeshFile>();
  file->path = "generated.ply";
  pt::TriangleMesh mesh;
  mesh.name = "bumpy sphere";
  const double pi = 3.14159265358979323846;
  for (pt::u32 r = 0; r <= rings; ++r)
    for (pt::u32 s = 0; s <= segments; ++s) {
      const double theta = pi * r / rings, phi = 2 * pi * s / segments;
      const pt::Vec3d n{std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi)};
      const double radius = 1 + 0.02 * std::sin(40 * theta) * std::sin(40 * phi);
      mesh.positions.push_back(n * radius);
      mesh.normals.push_back(n);
      mesh.uvs.push_back({static_cast<double>(s) / segments, 1 - static_cast<double>(r) / rings});
    }
  for (pt::u32 r = 0; r < rings; ++r)
    for (pt::u32 s = 0; s < segments; ++s) {
      const pt::u32 a = r * (segments + 1) + s, b = a + segments + 1;
      mesh.triangles.push_back({a, b, a + 1});
      mesh.triangles.push_back({a + 1, b, b + 1});
    }
  file->meshes.push_back(std::move(mesh));
  file->materials.push_back(pt::MeshMaterial{});
  file->placements.push_back(pt::MeshPlacement{0, pt::AffineTransform{}});
  return file;
}

}  // namespace

int main(int argc, char** argv) {
  const double millions = argc > 1 ? std::atof(argv[1]) : 2.0;
  const int instances = argc > 2 ? std::atoi(argv[2]) : 1;
  const pt::u32 rings = static_cast<pt::u32>(std::sqrt(millions * 1e6 / 4));
  pt::SceneDescription scene;
  scene.source = "generated";
  scene.camera.look_from = {0, 0, 4};
  scene.camera.look_at = {0, 0, 0};
  scene.camera.focus_distance = 4;
  const pt::u32 file = pt::add_mesh_file(scene, bumpy_sphere(rings, 2 * rings), "/objects");
  for (int i = 0; i < instances; ++i) {
    pt::SceneObject object;
    object.shape = pt::MeshSettings{file, pt::AffineTransform::scaling({1, 1, 1}).then(
                                              pt::AffineTransform::from_rigid(pt::RigidTransform::from_euler_degrees({0, 0, 0}, {3.0 * i, 0, 0})))};
    object.material = pt::kMeshMaterials;
    scene.objects.push_back(object);
  }
  const std::size_t triangles = scene.mesh_files[0].file->meshes[0].triangles.size();
  pt::RenderSettings settings;
  const auto start = std::chrono::steady_clock::now();
  const pt::FlatScene<float> flat = pt::flatten_scene<float>(scene, settings);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  const double mesh_bytes = flat.mesh_positions.size() * sizeof(flat.mesh_positions[0]) + flat.mesh_normals.size() * sizeof(flat.mesh_normals[0]) +
                            flat.mesh_uvs.size() * sizeof(flat.mesh_uvs[0]) + flat.mesh_triangles.size() * sizeof(pt::MeshTriangle);
  const double bvh_bytes = flat.mesh_nodes.size() * sizeof(flat.mesh_nodes[0]) + flat.mesh_wide_nodes.size() * sizeof(flat.mesh_wide_nodes[0]);
  std::printf(
      "%zu triangles, %d instance(s): flatten %.3f s (BVH %.3f s), %.1f B/triangle vertex data + triangles, %.1f B/triangle BVH "
      "(binary %.1f, wide %.1f), flat scene %.0f MB, peak RSS %.0f MB\n",
      triangles, instances, seconds, flat.bvh_seconds, mesh_bytes / triangles, bvh_bytes / triangles,
      flat.mesh_nodes.size() * sizeof(flat.mesh_nodes[0]) / static_cast<double>(triangles),
      flat.mesh_wide_nodes.size() * sizeof(flat.mesh_wide_nodes[0]) / static_cast<double>(triangles), flat.bytes() / 1e6, usage.ru_maxrss / 1024.0);
  return 0;
}
