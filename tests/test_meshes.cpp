// Triangle meshes in the kernels: a mesh's triangles are found where the same triangles written one by one are,
// instances that share a mesh render like world-space copies of it, and materials go to the right triangles.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "test_support.hpp"

namespace pt {
namespace {

using test::TestRandom;

SceneDescription sky_scene() {
  SceneDescription scene = test::generated_scene({0, 2, 12});
  scene.camera.vertical_fov = 50;
  scene.render.width = 64;
  scene.render.height = 48;
  scene.render.max_depth = 8;
  return scene;
}

struct Placement {
  Vec3d scale, degrees, at;
};

AffineTransform map_of(const Placement& p) {
  return AffineTransform::scaling(p.scale).then(AffineTransform::from_rigid(RigidTransform::from_euler_degrees(p.degrees, p.at)));
}

// The triangles of a mesh placed by `map`, written as triangle objects (positions, normals and uvs mapped by hand).
void add_as_triangles(SceneDescription& scene, const TriangleMesh& mesh, const AffineTransform& map, u32 material) {
  for (const std::array<u32, 3>& t : mesh.triangles) {
    TriangleSettings triangle;
    std::array<Vec3d, 3> normals;
    std::array<std::array<double, 2>, 3> uvs;
    for (int k = 0; k < 3; ++k) {
      triangle.vertices[k] = map.apply_point(mesh.positions[t[k]]);
      normals[k] = normalize(map.apply_normal(mesh.normals[t[k]]));
      uvs[k] = mesh.uvs[t[k]];
    }
    triangle.normals = normals;
    triangle.uvs = uvs;
    SceneObject o;
    o.shape = triangle;
    o.material = material;
    scene.objects.push_back(o);
  }
}

template <class T>
class MeshHits : public ::testing::Test {};
using ScalarTypes = ::testing::Types<float, double>;
TYPED_TEST_SUITE(MeshHits, ScalarTypes);

TYPED_TEST(MeshHits, MatchTheSameTrianglesWrittenOneByOne) {
  // One file placed twice (instances sharing its mesh, rays taken into its space) and a copy placed once (stored in
  // world space), against the same triangles mapped by hand into triangle objects: every ray finds the same surface
  // (point, shading normal, side and texture coordinates) up to the rounding of the two ways of computing it.
  using T = TypeParam;
  TestRandom rng(2024);
  const std::shared_ptr<MeshFile> soup = test::triangle_soup(rng, 300);
  const std::vector<Placement> placements = {
      {{1, 1, 1}, {0, 0, 0}, {-3, 0, 0}}, {{1.5, 0.7, 1.2}, {20, 45, -30}, {3, 1, -1}}, {{0.8, 0.8, 0.8}, {-60, 10, 5}, {0, -2, 3}}};
  SceneDescription meshes = sky_scene(), triangles = sky_scene();
  const u32 shared = add_mesh_file(meshes, soup, "/objects");
  const u32 single = add_mesh_file(meshes, std::make_shared<MeshFile>(*soup), "/objects");
  test::place_mesh(meshes, shared, placements[0].scale, placements[0].degrees, placements[0].at);
  test::place_mesh(meshes, shared, placements[1].scale, placements[1].degrees, placements[1].at);
  test::place_mesh(meshes, single, placements[2].scale, placements[2].degrees, placements[2].at);
  triangles.textures.push_back(SolidTexture<double>{{0.5, 0.5, 0.5}});
  triangles.materials.push_back(Lambertian<double>{0});
  for (const Placement& p : placements) add_as_triangles(triangles, soup->meshes[0], map_of(p), 0);

  const FlatScene<T> a = test::flatten<T>(meshes), b = test::flatten<T>(triangles);
  ASSERT_EQ(a.instance_transforms.size(), 2u);  // the shared mesh's two instances; the single one is in world space
  const SceneView<T> va = a.view(), vb = b.view();
  const double tolerance = std::is_same_v<T, float> ? 2e-4 : 1e-9;
  int rays = 0, hits = 0, differ = 0;
  for (int i = 0; i < 20000; ++i) {
    const Vec3d origin = rng.vec3(-7, 7);
    const Vec3d target = rng.vec3(-4, 4);
    const Ray<T> ray{test::to<T>(origin), test::to<T>(normalize(target - origin)), T(0)};
    const SampleRandom random = SampleRandom::make(1, static_cast<u32>(i), 0);
    Hit<T> ha{}, hb{};
    const bool fa = closest_hit(va, ray, IntersectContext<T>{va.boundaries, &random, 0}, ha);
    const bool fb = closest_hit(vb, ray, IntersectContext<T>{vb.boundaries, &random, 0}, hb);
    ++rays;
    if (fa != fb) {
      ++differ;  // a ray through an edge, where the two ways round differently
      continue;
    }
    if (!fa) continue;
    ++hits;
    const SurfacePoint<T> sa = describe_hit(a.primitives[ha.primitive], va.triangle_attributes, va.meshes, ray, ha);
    const SurfacePoint<T> sb = describe_hit(b.primitives[hb.primitive], vb.triangle_attributes, vb.meshes, ray, hb);
    const double scale = 1 + std::abs(static_cast<double>(sb.p.x)) + std::abs(static_cast<double>(sb.p.y)) + std::abs(static_cast<double>(sb.p.z));
    const bool same = std::abs(static_cast<double>(ha.t - hb.t)) <= tolerance * scale &&
                      static_cast<double>(length(sa.p - sb.p)) <= tolerance * scale &&
                      static_cast<double>(dot(sa.normal, sb.normal)) >= 1 - 10 * tolerance && sa.front_face == sb.front_face &&
                      std::abs(static_cast<double>(sa.u - sb.u)) <= 10 * tolerance && std::abs(static_cast<double>(sa.v - sb.v)) <= 10 * tolerance;
    if (!same) {
      // Overlapping triangles of the soup at the same distance may be found in either order.
      if (std::abs(static_cast<double>(ha.t - hb.t)) <= tolerance * scale) continue;
      ++differ;
      ADD_FAILURE() << "ray " << i << ": t " << static_cast<double>(ha.t) << " vs " << static_cast<double>(hb.t);
      if (differ > 5) break;
    }
  }
  EXPECT_GT(hits, rays / 5);
  EXPECT_LE(differ, rays / 1000) << differ << " of " << rays << " rays found different surfaces";
}

TEST(MeshMaterials, TrianglesKeepTheFileMaterialsUnlessTheObjectGivesOne) {
  TestRandom rng(7);
  auto file = test::triangle_soup(rng, 20);
  file->materials = {MeshMaterial{}, MeshMaterial{}};
  file->materials[0].base_color = {0.9, 0.1, 0.1};
  file->materials[1].emission = {4, 4, 4};  // a light
  for (std::size_t t = 0; t < file->meshes[0].triangles.size(); ++t) file->meshes[0].materials.push_back(static_cast<u32>(t % 2));
  SceneDescription scene = sky_scene();
  const u32 index = add_mesh_file(scene, file, "/objects");
  ASSERT_EQ(scene.mesh_files[index].materials.size(), 2u);
  const u32 red = scene.mesh_files[index].materials[0], light = scene.mesh_files[index].materials[1];
  EXPECT_TRUE(std::holds_alternative<Lambertian<double>>(scene.materials[red]));
  EXPECT_TRUE(std::holds_alternative<DiffuseLight<double>>(scene.materials[light]));
  {
    // A metallic-roughness material: its base colour, and its factors as a solid (0, roughness, metallic), or as
    // the factor of its map, which is read as linear bytes.
    auto pbr = test::triangle_soup(rng, 2);
    pbr->materials = {MeshMaterial{}, MeshMaterial{}};
    for (MeshMaterial& m : pbr->materials) {
      m.metallic_roughness_model = true;
      m.metallic = 0.75;
      m.roughness = 0.5;
    }
    pbr->textures.push_back(TextureImage{1, 1, {10, 20, 30}});
    pbr->materials[1].metallic_roughness_texture = 0;
    SceneDescription with_pbr = sky_scene();
    const u32 file_index = add_mesh_file(with_pbr, pbr, "/objects");
    const auto* plain = std::get_if<MetallicRoughness<double>>(&with_pbr.materials[with_pbr.mesh_files[file_index].materials[0]]);
    const auto* mapped = std::get_if<MetallicRoughness<double>>(&with_pbr.materials[with_pbr.mesh_files[file_index].materials[1]]);
    ASSERT_TRUE(plain && mapped);
    const auto* factors = std::get_if<SolidTexture<double>>(&with_pbr.textures[plain->metallic_roughness]);
    ASSERT_TRUE(factors);
    EXPECT_EQ(factors->color.y, 0.5);
    EXPECT_EQ(factors->color.z, 0.75);
    const auto* map = std::get_if<ImageTexture<double>>(&with_pbr.textures[mapped->metallic_roughness]);
    ASSERT_TRUE(map);
    EXPECT_EQ(map->linear, 1u);
    EXPECT_EQ(map->factor.y, 0.5);
    EXPECT_EQ(map->factor.z, 0.75);
  }
  scene.textures.push_back(SolidTexture<double>{{0.2, 0.2, 0.9}});
  scene.materials.push_back(Metal<double>{{0.9, 0.9, 0.9}, 0.1});
  const u32 metal = static_cast<u32>(scene.materials.size() - 1);
  test::place_mesh(scene, index, {1, 1, 1}, {0, 0, 0}, {-3, 0, 0});
  test::place_mesh(scene, index, {1, 1, 1}, {0, 0, 0}, {3, 0, 0}, metal);
  const FlatScene<double> flat = test::flatten<double>(scene);
  const SceneView<double> view = flat.view();
  std::vector<int> seen(scene.materials.size(), 0);
  for (u32 p = 0; p < flat.primitives.size(); ++p) {
    const auto& instance = std::get<MeshInstance<double>>(flat.primitives[p].shape);
    const MeshRecord& mesh = flat.meshes[instance.mesh];
    for (u32 t = mesh.first_triangle; t < mesh.first_triangle + mesh.triangle_count; ++t) {
      Hit<double> hit{1, 0.2, 0.2, p, t};
      const u32 m = material_of_hit(flat.primitives[p], view.meshes, hit);
      ++seen[m];
      if (flat.primitives[p].material == kMeshMaterials)
        EXPECT_TRUE(m == red || m == light);
      else
        EXPECT_EQ(m, metal);
    }
  }
  EXPECT_EQ(seen[red], 10);
  EXPECT_EQ(seen[light], 10);
  EXPECT_EQ(seen[metal], 20);
}

TEST(MeshInstances, RenderLikeWorldSpaceCopiesOfTheirMesh) {
  // The same picture two ways: one file placed three times (one placement mirrors it), so the kernels take rays into
  // the mesh's space and bring normals and spawn offsets back; and three copies of the file placed once each, stored
  // in world space. The sampling differs (the rays are computed differently), so block means are compared within
  // their noise (5.5 sigma, as the float-against-double tests).
  TestRandom rng(99);
  const std::shared_ptr<MeshFile> soup = test::triangle_soup(rng, 250, 0.6);
  const std::vector<Placement> placements = {
      {{1, 1, 1}, {0, 0, 0}, {-3, 0, 0}}, {{1.5, 0.7, 1.2}, {20, 45, -30}, {3, 1, -1}}, {{-1, 1, 1}, {0, 30, 0}, {0, -1, 2}}};
  SceneDescription instanced = sky_scene(), copies = sky_scene();
  const u32 shared = add_mesh_file(instanced, soup, "/objects");
  for (const Placement& p : placements) test::place_mesh(instanced, shared, p.scale, p.degrees, p.at);
  for (const Placement& p : placements)
    test::place_mesh(copies, add_mesh_file(copies, std::make_shared<MeshFile>(*soup), "/objects"), p.scale, p.degrees, p.at);
  const FlatScene<float> a = test::flatten<float>(instanced), b = test::flatten<float>(copies);
  ASSERT_EQ(a.instance_transforms.size(), 3u);
  ASSERT_EQ(b.instance_transforms.size(), 0u);
  const test::PixelStatistics sa = test::sample_statistics(a, 256), sb = test::sample_statistics(b, 256);
  EXPECT_EQ(sa.non_finite, 0u);
  const std::vector<test::BlockDifference> blocks = test::compare_block_means(sa, sb, 16, 5.5, 1e-6, 1e-5);
  std::size_t outside = 0;
  for (const test::BlockDifference& d : blocks) outside += !d.within;
  EXPECT_EQ(outside, 0u) << test::describe_blocks(blocks, 8, "instanced", "copies");
  // The picture is not the sky alone: the meshes cover part of it, darker than the sky.
  double darkest = 1e9;
  for (const test::BlockDifference& d : blocks) darkest = std::min(darkest, d.mean_a);
  EXPECT_LT(darkest, 0.6);
}

TEST(LargeMeshes, TessellatedSphereIsHitWhereTheSphereIs) {
  // A unit sphere of 200,000 triangles (a UV sphere with its vertices on the sphere), seen from 4 units away: a
  // pinhole's ray meets it where the ray passes within 1 of the centre, less the tessellation's sag, which keeps the
  // surface within [1 - D^2, 1] of the centre for an angular step D = pi / rings. So every ray passing within
  // 1 - D^2 hits it, at a distance between the exact sphere's and that of the inner shell; every ray passing
  // farther than 1 misses; and the share of rays that hit is the sphere's, within the shell's.
  constexpr u32 rings = 224, segments = 2 * rings;
  auto file = std::make_shared<MeshFile>();
  file->path = "generated.ply";
  TriangleMesh mesh;
  mesh.name = "sphere";
  const double pi = 3.14159265358979323846;
  for (u32 r = 0; r <= rings; ++r)
    for (u32 s = 0; s <= segments; ++s) {
      const double theta = pi * r / rings, phi = 2 * pi * s / segments;
      mesh.positions.push_back({std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi)});
    }
  for (u32 r = 0; r < rings; ++r)
    for (u32 s = 0; s < segments; ++s) {
      const u32 a = r * (segments + 1) + s, b = a + segments + 1;
      mesh.triangles.push_back({a, b, a + 1});
      mesh.triangles.push_back({a + 1, b, b + 1});
    }
  file->meshes.push_back(std::move(mesh));
  file->materials.push_back(MeshMaterial{});
  file->placements.push_back(MeshPlacement{0, AffineTransform{}});
  SceneDescription scene = sky_scene();
  scene.camera.look_from = {0, 0, 4};
  scene.camera.look_at = {0, 0, 0};
  scene.camera.focus_distance = 4;
  scene.camera.vertical_fov = 40;
  test::place_mesh(scene, add_mesh_file(scene, file, "/objects"), {1, 1, 1}, {0, 0, 0}, {0, 0, 0});
  const FlatScene<float> flat = test::flatten<float>(scene);
  // The top pole's triangles have no area and are dropped (the bottom pole's vertices differ by rounding).
  ASSERT_GE(flat.mesh_triangles.size(), 2u * rings * segments - 2 * segments);
  ASSERT_LE(flat.mesh_triangles.size(), 2u * rings * segments - segments);
  const SceneView<float> view = flat.view();
  const double sag = (pi / rings) * (pi / rings);
  u32 rays = 0, hits = 0, inside = 0, shell = 0, wrong = 0;
  for (u32 y = 0; y < 300; ++y)
    for (u32 x = 0; x < 400; ++x) {
      const Vec3d direction = normalize(Vec3d{(x + 0.5) / 400 * 2 - 1, (y + 0.5) / 300 * 1.5 - 0.75, -2.0});
      const Vec3d origin{0, 0, 4};
      const double along = -dot(origin, direction);            // to the point nearest the centre
      const double miss = length(origin + along * direction);  // the ray's distance from the centre
      const SampleRandom random = SampleRandom::make(1, x, y);
      Hit<float> hit{};
      const bool found = closest_hit(view, Ray<float>{test::to<float>(origin), test::to<float>(direction), 0.0f},
                                     IntersectContext<float>{view.boundaries, &random, 0}, hit);
      ++rays;
      hits += found;
      inside += miss < 1;
      shell += miss >= 1 - sag && miss < 1;
      if (miss < 1 - sag) {
        const double outer = along - std::sqrt(1 - miss * miss), inner = along - std::sqrt(std::max(0.0, (1 - sag) * (1 - sag) - miss * miss));
        wrong += !found || hit.t < outer - 1e-4 || hit.t > inner + 1e-4;
      } else if (miss > 1 + 1e-6) {
        wrong += found;
      }
    }
  EXPECT_EQ(wrong, 0u);
  EXPECT_GT(inside, rays / 10);
  EXPECT_LE(std::abs(static_cast<double>(hits) - inside), shell + 1.0) << hits << " hits, " << inside << " rays within the sphere";
}

TEST(ModelFiles, RenderDirectlyWithTheirOwnCameraOrOneThatFramesThem) {
  // `pathtracer render MODEL`: a glTF file's camera (which sets no focus distance: the image plane lies at look_at)
  // and, for a file without one, a camera that frames the model. Every sample finite, and the model in the picture.
  std::vector<std::filesystem::path> models = {test::scene_path("models/knot.ply"), test::scene_path("models/pedestal.gltf")};
  const std::filesystem::path engine = "/usr/share/assimp/models/glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb";
  if (std::filesystem::exists(engine)) models.push_back(engine);
  for (const std::filesystem::path& model : models) {
    SceneDescription scene = load_scene_file(model);
    scene.render.width = 48;
    scene.render.height = 36;
    scene.render.max_depth = 4;
    const FlatScene<float> flat = test::flatten<float>(scene);
    const test::PixelStatistics stats = test::sample_statistics(flat, 4);
    EXPECT_EQ(stats.non_finite, 0u) << model;
    // The model covers a good part of the picture: against the same camera's empty sky, many pixels differ.
    SceneDescription sky = scene;
    sky.objects = ObjectList{};
    const test::PixelStatistics empty = test::sample_statistics(test::flatten<float>(sky), 1);
    std::size_t covered = 0;
    for (std::size_t i = 0; i < stats.mean.size(); i += 3)
      covered += std::abs(stats.mean[i] + stats.mean[i + 1] + stats.mean[i + 2] - empty.mean[i] - empty.mean[i + 1] - empty.mean[i + 2]) > 0.05;
    EXPECT_GT(covered, stats.mean.size() / 3 / 20) << model;
  }
}

TEST(RealModels, RenderToTheirStoredMeans) {
  // Models made by others (Debian's assimp-testmodels), each rendered directly at 40x30: the image mean must match
  // the one stored here, from `pathtracer render MODEL --width 40 --height 30 --spp 8192` (float, CPU), within
  // 5 standard deviations of the difference of the two means (from the per-pixel sample variances). A reader
  // that loses or misplaces triangles, normals, materials or textures moves the mean.
  const std::filesystem::path root = "/usr/share/assimp/models";
  if (!std::filesystem::exists(root)) GTEST_SKIP() << "assimp-testmodels is not installed";
  const struct {
    const char* file;
    double mean;
  } models[] = {
      // The glTF models with their materials as the metallic-roughness material (before it, diffuse: 0.759821 and
      // 0.775709).
      {"glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb", 0.743314},
      {"glTF2/BoxTextured-glTF/BoxTextured.gltf", 0.769075},
      {"OBJ/spider.obj", 0.862249},
      {"OBJ/WusonOBJ.obj", 0.897392},
      {"PLY/Wuson.ply", 0.897650},
      {"PLY/cube.ply", 0.844042},
  };
  constexpr u32 kSamples = 64, kStoredSamples = 8192;
  for (const auto& model : models) {
    SceneDescription scene = load_scene_file(root / model.file);
    scene.render.width = 40;
    scene.render.height = 30;
    const test::PixelStatistics stats = test::sample_statistics(test::flatten<float>(scene), kSamples);
    double sum = 0, variance = 0;
    for (std::size_t i = 0; i < stats.mean.size(); ++i) {
      sum += stats.mean[i];
      variance += stats.variance[i];
    }
    const double n = static_cast<double>(stats.mean.size());
    const double mean = sum / n;
    // var(image mean) = sum of per-sample variances / (samples n^2), for this render and (fewer) for the stored one.
    const double sigma = std::sqrt(variance / (n * n) * (1.0 / kSamples + 1.0 / kStoredSamples));
    EXPECT_EQ(stats.non_finite, 0u) << model.file;
    EXPECT_LE(std::abs(mean - model.mean), 5 * sigma + 1e-5) << model.file << ": mean " << mean << ", stored " << model.mean << ", sigma " << sigma;
  }
}

}  // namespace
}  // namespace pt
