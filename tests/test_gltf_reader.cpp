// The glTF 2.0 reader: real files from Debian's assimp-testmodels (skipped where it is not installed), good and
// broken, and small files written here for what those do not cover. Counts and bounds of the real files come from
// tests/gltf_reference.py, which reads the JSON and buffers on its own.
#include <sys/stat.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <initializer_list>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "base/errors.hpp"
#include "loading/model_files.hpp"
#include "test_support.hpp"

namespace pt {
namespace {

using test::all_warnings;
using test::expect_consistent;
using test::expect_near;
using test::expect_refused;
using test::has_warning;
using test::placed_bounds;
using test::triangle_count;
using test::vertex_count;

namespace fs = std::filesystem;
using json = nlohmann::json;

const fs::path kAssets = "/usr/share/assimp/models/glTF2";

#define REQUIRE_ASSETS()                                                                                  \
  do {                                                                                                    \
    if (!fs::is_directory(kAssets)) GTEST_SKIP() << kAssets << " is absent (Debian's assimp-testmodels)"; \
  } while (false)

// --- Small glTF files written by the tests -------------------------------------------------------------------

template <class T>
std::string bytes_of(const std::vector<T>& values) {
  std::string out(values.size() * sizeof(T), '\0');
  std::memcpy(out.data(), values.data(), out.size());  // the machines the suite runs on are little-endian, as glTF is
  return out;
}

std::string base64(const std::string& bytes) {
  static constexpr char kDigits[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (std::size_t i = 0; i < bytes.size(); i += 3) {
    const u32 n = (u32{static_cast<unsigned char>(bytes[i])} << 16) |
                  (i + 1 < bytes.size() ? u32{static_cast<unsigned char>(bytes[i + 1])} << 8 : 0) |
                  (i + 2 < bytes.size() ? u32{static_cast<unsigned char>(bytes[i + 2])} : 0);
    out += kDigits[(n >> 18) & 63];
    out += kDigits[(n >> 12) & 63];
    out += i + 1 < bytes.size() ? kDigits[(n >> 6) & 63] : '=';
    out += i + 2 < bytes.size() ? kDigits[n & 63] : '=';
  }
  return out;
}

// A glTF document with one buffer, given as a data URI when written, or as a file beside it.
struct Document {
  json doc = {{"asset", {{"version", "2.0"}}}};
  std::string bin;

  int view(const std::string& data) {
    while (bin.size() % 4 != 0) bin += '\0';
    doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", data.size()}});
    bin += data;
    return static_cast<int>(doc["bufferViews"].size()) - 1;
  }
  int accessor(int view, int component_type, std::size_t count, const char* type, bool normalized = false) {
    json a = {{"bufferView", view}, {"componentType", component_type}, {"count", count}, {"type", type}};
    if (normalized) a["normalized"] = true;
    doc["accessors"].push_back(a);
    return static_cast<int>(doc["accessors"].size()) - 1;
  }
  int vec3(const std::vector<float>& v) { return accessor(view(bytes_of(v)), 5126, v.size() / 3, "VEC3"); }
  int indices(const std::vector<std::uint16_t>& v) { return accessor(view(bytes_of(v)), 5123, v.size(), "SCALAR"); }
  fs::path write(const test::TempDir& dir, const std::string& name, bool external_buffer = false) {
    if (!bin.empty()) {
      if (external_buffer) {
        test::write_text_file(dir / (name + ".bin"), bin);
        doc["buffers"] = json::array({{{"byteLength", bin.size()}, {"uri", name + ".bin"}}});
      } else {
        doc["buffers"] = json::array({{{"byteLength", bin.size()}, {"uri", "data:application/octet-stream;base64," + base64(bin)}}});
      }
    }
    test::write_text_file(dir / name, doc.dump(1));
    return dir / name;
  }
};

// One triangle in the z = 0 plane facing +z, as a document with mesh 0 (no node yet).
Document one_triangle() {
  Document d;
  const int p = d.vec3({0, 0, 0, 1, 0, 0, 0, 1, 0});
  d.doc["meshes"] = json::array({{{"primitives", json::array({{{"attributes", {{"POSITION", p}}}}})}}});
  return d;
}

// --- Real files ---------------------------------------------------------------------------------------------

TEST(GltfSampleFiles, TwoCylinderEngineCountsBoundsAndCamera) {
  REQUIRE_ASSETS();
  const MeshFile file = read_gltf_file(kAssets / "2CylinderEngine-glTF-Binary/2CylinderEngine.glb");
  expect_consistent(file);
  // tests/gltf_reference.py: 67 placements of 29 meshes, 75,730 triangles, 55,843 vertices, bounds
  // min (-371.692263, -180.971558, -139.999993) max (371.692169, 92.0415617, 127.999996).
  EXPECT_EQ(file.placements.size(), 67u);
  EXPECT_EQ(file.meshes.size(), 29u);
  EXPECT_EQ(triangle_count(file), 75730u);
  EXPECT_EQ(vertex_count(file), 55843u);
  const auto [lo, hi] = placed_bounds(file);
  expect_near(lo, {-371.692263, -180.971558, -139.999993}, 1e-4);
  expect_near(hi, {371.692169, 92.0415617, 127.999996}, 1e-4);
  // Every mesh has normals; 34 materials, all used.
  for (const TriangleMesh& mesh : file.meshes) EXPECT_EQ(mesh.normals.size(), mesh.positions.size()) << mesh.name;
  EXPECT_EQ(file.materials.size(), 34u);
  EXPECT_EQ(file.materials[1].name, "Material_21");
  expect_near(file.materials[0].base_color, {0.85, 0.85, 0.85}, 1e-6);
  EXPECT_EQ(file.materials[0].metallic, 0);
  EXPECT_EQ(file.materials[0].roughness, 1);
  // Node 81 places camera 0 by a matrix: its translation, its -z and +y axes, yfov 0.3143463730812073 rad.
  ASSERT_TRUE(file.camera);
  expect_near(file.camera->look_from, {1005.9874267578125, 766.3170776367188, 953.3455810546875}, 1e-9);
  expect_near(file.camera->look_at - file.camera->look_from, {-0.6246951818466187, -0.4685211479663849, -0.6246950030326843}, 1e-6);
  expect_near(file.camera->up, {-0.33129435777664185, 0.883452296257019, -0.33129459619522095}, 1e-6);
  EXPECT_NEAR(file.camera->vertical_fov, 0.3143463730812073 * 180 / std::numbers::pi, 1e-9);
  EXPECT_TRUE(file.warnings.empty()) << all_warnings(file);
}

TEST(GltfSampleFiles, BoxTexturedSeparateBinaryAndEmbeddedGiveTheSameMeshes) {
  REQUIRE_ASSETS();
  // External .bin and .png; a .glb with the image in a buffer view; one .gltf with data URIs for both.
  const MeshFile separate = read_gltf_file(kAssets / "BoxTextured-glTF/BoxTextured.gltf");
  const MeshFile binary = read_gltf_file(kAssets / "BoxTextured-glTF-Binary/BoxTextured.glb");
  const MeshFile embedded = read_gltf_file(kAssets / "BoxTextured-glTF-Embedded/BoxTextured.gltf");
  for (const MeshFile* file : {&separate, &binary, &embedded}) {
    SCOPED_TRACE(file->path.string());
    expect_consistent(*file);
    // tests/gltf_reference.py: one placement, 12 triangles, 24 vertices, bounds +-0.5.
    ASSERT_EQ(file->meshes.size(), 1u);
    ASSERT_EQ(file->placements.size(), 1u);
    const TriangleMesh& mesh = file->meshes[0];
    EXPECT_EQ(mesh.triangles.size(), 12u);
    EXPECT_EQ(mesh.positions.size(), 24u);
    EXPECT_EQ(mesh.normals.size(), 24u);
    EXPECT_EQ(mesh.uvs.size(), 24u);
    const auto [lo, hi] = placed_bounds(*file);
    expect_near(lo, {-0.5, -0.5, -0.5}, 1e-7);
    expect_near(hi, {0.5, 0.5, 0.5}, 1e-7);
    // CesiumLogoFlat.png, 211x211, the base colour of the one material.
    ASSERT_EQ(file->textures.size(), 1u);
    EXPECT_EQ(file->textures[0].width, 211u);
    EXPECT_EQ(file->textures[0].height, 211u);
    ASSERT_EQ(file->materials.size(), 1u);
    EXPECT_EQ(file->materials[0].base_color_texture, 0);
    EXPECT_EQ(file->materials[0].metallic, 0);
    // The separate file's sampler mirrors and clamps (drawn as REPEAT, said once); the others' repeat.
    if (file == &separate) {
      EXPECT_TRUE(has_warning(*file, "texture wrap modes other than REPEAT are drawn as REPEAT")) << all_warnings(*file);
      EXPECT_EQ(file->warnings.size(), 1u) << all_warnings(*file);
    } else {
      EXPECT_TRUE(file->warnings.empty()) << all_warnings(*file);
    }
  }
  for (const MeshFile* file : {&binary, &embedded}) {
    const TriangleMesh &a = separate.meshes[0], &b = file->meshes[0];
    EXPECT_EQ(a.triangles, b.triangles);
    for (std::size_t i = 0; i < a.positions.size(); ++i) {
      EXPECT_EQ(a.positions[i].x, b.positions[i].x);
      EXPECT_EQ(a.positions[i].y, b.positions[i].y);
      EXPECT_EQ(a.positions[i].z, b.positions[i].z);
      EXPECT_EQ(a.uvs[i], b.uvs[i]);
    }
    EXPECT_EQ(separate.textures[0].srgb, file->textures[0].srgb);
    EXPECT_TRUE(separate.placements[0].transform.apply_point({1, 2, 3}).y == file->placements[0].transform.apply_point({1, 2, 3}).y);
  }
  // Node 0's matrix (columns (1, 0, 0), (0, 0, -1), (0, 1, 0)) turns z up into y up: (x, y, z) -> (x, z, -y).
  const Vec3d p = separate.placements[0].transform.apply_point({1, 2, 3});
  expect_near(p, {1, 3, -2}, 1e-12);
}

TEST(GltfSampleFiles, AssetGeneratorPrimitiveModes) {
  REQUIRE_ASSETS();
  // Mesh_PrimitiveMode_NN: one quad of four vertices in z = 0, facing +z, as points (00, 07), lines (01-03,
  // 08-10), a strip (04, 11), a fan (05, 12) and triangles (06 unindexed, 13-15 indexed by uint, ubyte, ushort).
  const char* kModes[] = {"POINTS", "LINES", "LINE_LOOP", "LINE_STRIP"};
  for (int n = 0; n <= 15; ++n) {
    const fs::path path = kAssets / fmt::format("glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_{:02}.gltf", n);
    SCOPED_TRACE(path.string());
    const MeshFile file = read_gltf_file(path);
    expect_consistent(file);
    const int mode = n <= 6 ? n : std::min(n - 7, 6);
    if (mode <= 3) {
      // A mesh of points or lines alone draws nothing: it is left out, with its placement.
      EXPECT_TRUE(file.meshes.empty());
      EXPECT_TRUE(file.placements.empty());
      EXPECT_TRUE(has_warning(file, std::string("points and lines are not rendered: 1 primitives of mode ") + kModes[mode])) << all_warnings(file);
      continue;
    }
    ASSERT_EQ(file.meshes.size(), 1u);
    const TriangleMesh& mesh = file.meshes[0];
    EXPECT_TRUE(file.warnings.empty()) << all_warnings(file);
    // tests/gltf_reference.py: 2 triangles; 4 vertices, but 6 for the unindexed triangles.
    ASSERT_EQ(mesh.triangles.size(), 2u);
    EXPECT_EQ(mesh.positions.size(), n == 6 ? 6u : 4u);
    // Both triangles face +z (strips turn every other triangle back; fans go round vertex 0), and together they
    // cover the quad: areas of 1/2 each.
    for (const auto& t : mesh.triangles) {
      const Vec3d normal = cross(mesh.positions[t[1]] - mesh.positions[t[0]], mesh.positions[t[2]] - mesh.positions[t[0]]);
      EXPECT_NEAR(normal.z, 1.0, 1e-6);
    }
    // A primitive without a material has glTF's default one: white, metallic, rough.
    ASSERT_EQ(file.materials.size(), 1u);
    expect_near(file.materials[0].base_color, {1, 1, 1}, 0);
    EXPECT_EQ(file.materials[0].metallic, 1);
    EXPECT_EQ(file.materials[0].roughness, 1);
  }
}

TEST(GltfSampleFiles, CamerasTakeTheFirstPerspectiveCameraAndWarnOfOrthographicOnes) {
  REQUIRE_ASSETS();
  const MeshFile file = read_gltf_file(kAssets / "cameras/Cameras.gltf");
  expect_consistent(file);
  // tests/gltf_reference.py: one square of 2 triangles and 4 vertices, turned about x by its node.
  EXPECT_EQ(triangle_count(file), 2u);
  EXPECT_EQ(vertex_count(file), 4u);
  const auto [lo, hi] = placed_bounds(file);
  expect_near(lo, {0, 0, -0.707590333}, 1e-6);
  expect_near(hi, {1, 0.706622898, 0}, 1e-6);
  // Node 1 places camera 0 (perspective, yfov 0.7) at (0.5, 0.5, 3), looking down -z; node 2's orthographic camera
  // is not read.
  ASSERT_TRUE(file.camera);
  expect_near(file.camera->look_from, {0.5, 0.5, 3}, 0);
  expect_near(file.camera->look_at, {0.5, 0.5, 2}, 0);
  expect_near(file.camera->up, {0, 1, 0}, 0);
  EXPECT_NEAR(file.camera->vertical_fov, 0.7 * 180 / std::numbers::pi, 1e-12);
  EXPECT_TRUE(has_warning(file, "orthographic cameras are not read")) << all_warnings(file);
}

TEST(GltfSampleFiles, SkinsAnimationsAndMorphTargetsWarnAndDrawTheBaseMesh) {
  REQUIRE_ASSETS();
  const MeshFile skin = read_gltf_file(kAssets / "simple_skin/simple_skin.gltf");
  expect_consistent(skin);
  // tests/gltf_reference.py: 8 triangles, 10 vertices, bounds (0, 0, 0) to (1, 2, 0) unskinned.
  EXPECT_EQ(triangle_count(skin), 8u);
  EXPECT_EQ(vertex_count(skin), 10u);
  const auto [lo, hi] = placed_bounds(skin);
  expect_near(lo, {0, 0, 0}, 1e-7);
  expect_near(hi, {1, 2, 0}, 1e-7);
  EXPECT_TRUE(has_warning(skin, "skins are not applied")) << all_warnings(skin);
  EXPECT_TRUE(has_warning(skin, "animations are not played")) << all_warnings(skin);
  EXPECT_EQ(skin.warnings.size(), 2u) << all_warnings(skin);

  const MeshFile morph = read_gltf_file(kAssets / "glTF-Sample-Models/AnimatedMorphCube-glTF/AnimatedMorphCube.gltf");
  expect_consistent(morph);
  EXPECT_EQ(triangle_count(morph), 12u);
  EXPECT_EQ(vertex_count(morph), 24u);
  EXPECT_TRUE(has_warning(morph, "morph targets are not applied")) << all_warnings(morph);
  EXPECT_TRUE(has_warning(morph, "animations are not played")) << all_warnings(morph);
}

TEST(GltfSampleFiles, ExtensionsThatAreNotReadWarnOrAreRefused) {
  REQUIRE_ASSETS();
  // Used, not required: read without them, each named.
  const MeshFile transform = read_gltf_file(kAssets / "textureTransform/TextureTransformTest.gltf");
  EXPECT_TRUE(has_warning(transform, "extension KHR_texture_transform is not read")) << all_warnings(transform);
  const MeshFile clearcoat = read_gltf_file(kAssets / "ClearCoat-glTF/ClearCoatTest.gltf");
  EXPECT_TRUE(has_warning(clearcoat, "extension KHR_materials_clearcoat is not read")) << all_warnings(clearcoat);
  const MeshFile gloss = read_gltf_file(kAssets / "BoxTextured-glTF-pbrSpecularGlossiness/BoxTextured.gltf");
  EXPECT_TRUE(has_warning(gloss, "extension KHR_materials_pbrSpecularGlossiness is not read")) << all_warnings(gloss);
  // Required: refused, named.
  expect_refused(kAssets / "draco/2CylinderEngine.gltf",
                 {"2CylinderEngine.gltf: /extensionsRequired/0: the file requires the extension KHR_draco_mesh_compression", "Draco"});
  expect_refused(kAssets / "BoxTextured-glTF-techniqueWebGL/BoxTextured.gltf", {"/extensionsRequired/0", "KHR_technique_webgl"});
}

TEST(GltfSampleFiles, ZeroNormalsGiveFlatNormalsWithAWarning) {
  REQUIRE_ASSETS();
  // Four of its normals are (0, 0, 0), four more are 0.1 long: the ones that cannot be made unit length make the
  // primitive flat-shaded (its mesh then has no normals at all), and say so.
  const MeshFile file = read_gltf_file(kAssets / "BoxBadNormals-glTF-Binary/BoxBadNormals.glb");
  expect_consistent(file);
  ASSERT_EQ(file.meshes.size(), 1u);
  EXPECT_EQ(file.meshes[0].triangles.size(), 12u);
  EXPECT_TRUE(file.meshes[0].normals.empty());
  EXPECT_TRUE(has_warning(file, "/meshes/0/primitives/0/attributes/NORMAL: 4 of the 24 normals of accessor 1 are zero")) << all_warnings(file);
}

TEST(GltfSampleFiles, SceneWithoutNodesIsEmpty) {
  REQUIRE_ASSETS();
  // A scene of no nodes is valid and places nothing.
  const MeshFile file = read_gltf_file(kAssets / "TestNoRootNode/SceneWithoutNodes.gltf");
  EXPECT_TRUE(file.meshes.empty());
  EXPECT_TRUE(file.placements.empty());
  EXPECT_EQ(file.materials.size(), 1u);
}

// --- Broken real files: one InputError each, naming the file and the fault ----------------------------------

TEST(GltfBrokenFiles, IndexOutOfRange) {
  REQUIRE_ASSETS();
  // Its first index is 255 for a box of 24 vertices; in the other file all 36 are 65535.
  expect_refused(kAssets / "IndexOutOfRange/IndexOutOfRange.gltf",
                 {"IndexOutOfRange.gltf: /meshes/0/primitives/0/indices: index 255 out of range (the primitive has 24 vertices)"});
  expect_refused(kAssets / "IndexOutOfRange/AllIndicesOutOfRange.gltf",
                 {"AllIndicesOutOfRange.gltf: /meshes/0/primitives/0/indices: index 65535 out of range (the primitive has 24 vertices)"});
}

TEST(GltfBrokenFiles, MissingBin) {
  REQUIRE_ASSETS();
  expect_refused(kAssets / "MissingBin/BoxTextured.gltf", {"BoxTextured.gltf: /buffers/0/uri: buffer file '", "BoxTextured0.bin' does not exist"});
}

TEST(GltfBrokenFiles, RecursiveNodes) {
  REQUIRE_ASSETS();
  // Node 0's child is node 1, whose child is node 0.
  expect_refused(kAssets / "RecursiveNodes/RecursiveNodes.gltf",
                 {"RecursiveNodes.gltf: /nodes/1/children/0: node 0 is its own ancestor: the hierarchy loops (0 -> 1 -> 0)"});
}

TEST(GltfBrokenFiles, WrongTypes) {
  REQUIRE_ASSETS();
  const fs::path dir = kAssets / "wrongTypes";
  expect_refused(dir / "badArray.gltf", {"badArray.gltf: /meshes/0/primitives: expected an array, found an object"});
  expect_refused(
      dir / "badExtension.gltf",
      {"badExtension.gltf: /materials/0/pbrMetallicRoughness/baseColorTexture/extensions/KHR_texture_transform: expected an object, found a string"});
  // Its normalTexture has no index (and a scale that is not a number).
  expect_refused(dir / "badNumber.gltf", {"badNumber.gltf: /materials/0/normalTexture: 'index' is missing"});
  expect_refused(dir / "badObject.gltf", {"badObject.gltf: /materials/0/pbrMetallicRoughness: expected an object, found an array"});
  expect_refused(dir / "badString.gltf", {"badString.gltf: /scenes/0/name: expected a string, found an integer"});
  expect_refused(dir / "badUint.gltf", {"badUint.gltf: /materials/0/pbrMetallicRoughness/baseColorTexture/index: -1 is negative"});
}

TEST(GltfBrokenFiles, SchemaFailures) {
  REQUIRE_ASSETS();
  // "scene": "hello" (and a buffer file that is not there, which is not reached).
  expect_refused(kAssets / "SchemaFailures/sceneWrongType.gltf", {"sceneWrongType.gltf: /scene: expected a non-negative integer, found a string"});
  // "scene": 0 with no scenes at all.
  expect_refused(kAssets / "TestNoRootNode/NoScene.gltf", {"NoScene.gltf: /scene: index 0 is out of range (/scenes has 0 entries)"});
}

TEST(GltfBrokenFiles, BoxWithInfinites) {
  REQUIRE_ASSETS();
  expect_refused(kAssets / "BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb",
                 {"BoxWithInfinites.glb: /meshes/0/primitives/0/attributes/POSITION: position 0 of accessor 2 is not finite (-inf, -0.5, 0.5)"});
}

TEST(GltfBrokenFiles, IncorrectVertexArrays) {
  REQUIRE_ASSETS();
  // Its buffer has 514 bytes; buffer views 2 to 4 lie past them (as do the truncated accessors' meshes).
  expect_refused(kAssets / "IncorrectVertexArrays/Cube.gltf",
                 {"Cube.gltf: /bufferViews/2: its 432 bytes from byte 504 reach beyond the end of buffer 0 (514 bytes)"});
}

TEST(GltfBrokenFiles, TextureCoordinateSetThePrimitiveLacks) {
  REQUIRE_ASSETS();
  // Mesh 0's material reads its texture with TEXCOORD_0, but the primitive has only TEXCOORD_1.
  expect_refused(kAssets / "issue_3269/texcoord_crash.gltf",
                 {"texcoord_crash.gltf: /meshes/0/primitives/0: material 4 reads its textures with TEXCOORD_0, which the primitive does not have"});
}

// --- Small files --------------------------------------------------------------------------------------------

TEST(GltfWrittenFiles, NodeHierarchyComposesTranslationRotationScale) {
  test::TempDir dir;
  Document d = one_triangle();
  const double s = std::sin(std::numbers::pi / 4), c = std::cos(std::numbers::pi / 4);
  // Node 0: translate (1, 2, 3), turn 90 degrees about z, scale 2; its child node 1 moves (1, 0, 0) and places the
  // mesh; node 2 does the same by a matrix (column-major), as a root.
  d.doc["nodes"] = json::array({{{"translation", {1, 2, 3}}, {"rotation", {0, 0, s, c}}, {"scale", {2, 2, 2}}, {"children", {1}}},
                                {{"translation", {1, 0, 0}}, {"mesh", 0}},
                                {{"matrix", {0, 2, 0, 0, -2, 0, 0, 0, 0, 0, 2, 0, 1, 4, 3, 1}}, {"mesh", 0}}});
  d.doc["scenes"] = json::array({{{"nodes", {0, 2}}}});
  const MeshFile file = read_gltf_file(d.write(dir, "tree.gltf"));
  expect_consistent(file);
  ASSERT_EQ(file.placements.size(), 2u);
  // The mesh's origin: (1, 0, 0) by node 1, (2, 0, 0) scaled, (0, 2, 0) turned, (1, 4, 3) moved.
  for (const MeshPlacement& placement : file.placements) {
    expect_near(placement.transform.apply_point({0, 0, 0}), {1, 4, 3}, 1e-12);
    expect_near(placement.transform.apply_vector({1, 0, 0}), {0, 2, 0}, 1e-12);
    expect_near(placement.transform.apply_vector({0, 0, 1}), {0, 0, 2}, 1e-12);
  }
}

TEST(GltfWrittenFiles, MeshPlacedTwiceIsPlacedTwiceNotCopied) {
  test::TempDir dir;
  Document d = one_triangle();
  d.doc["nodes"] = json::array({{{"mesh", 0}}, {{"mesh", 0}, {"translation", {5, 0, 0}}}});
  // No scene: every root node.
  const MeshFile file = read_gltf_file(d.write(dir, "twice.gltf"));
  expect_consistent(file);
  ASSERT_EQ(file.meshes.size(), 1u);
  ASSERT_EQ(file.placements.size(), 2u);
  EXPECT_EQ(file.placements[0].mesh, 0u);
  EXPECT_EQ(file.placements[1].mesh, 0u);
  EXPECT_TRUE(file.placements[0].transform.is_identity());
  expect_near(file.placements[1].transform.translation, {5, 0, 0}, 0);
}

TEST(GltfWrittenFiles, TriangleStripAndFanBecomeTriangles) {
  test::TempDir dir;
  Document d;
  const int p = d.vec3({0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 2, 0});
  const int strip = d.indices({0, 1, 2, 3, 4});
  d.doc["meshes"] = json::array({{{"primitives", json::array({{{"attributes", {{"POSITION", p}}}, {"indices", strip}, {"mode", 5}},
                                                              {{"attributes", {{"POSITION", p}}}, {"mode", 6}}})}}});
  d.doc["nodes"] = json::array({{{"mesh", 0}}});
  const MeshFile file = read_gltf_file(d.write(dir, "strip.gltf"));
  expect_consistent(file);
  ASSERT_EQ(file.meshes.size(), 1u);
  // The two primitives share their positions: 5 vertices. The strip's second triangle is turned back to keep its
  // winding; the fan's triangles are (v1, v2, v0), (v2, v3, v0), (v3, v4, v0), as glTF lists them.
  EXPECT_EQ(file.meshes[0].positions.size(), 5u);
  const std::vector<std::array<u32, 3>> expected = {{0, 1, 2}, {1, 3, 2}, {2, 3, 4}, {1, 2, 0}, {2, 3, 0}, {3, 4, 0}};
  EXPECT_EQ(file.meshes[0].triangles, expected);
}

TEST(GltfWrittenFiles, HugeAccessorCountInATinyFileIsRefusedBeforeAnythingIsRead) {
  test::TempDir dir;
  Document d = one_triangle();
  d.doc["accessors"][0]["count"] = 1000000000000ull;
  d.doc["nodes"] = json::array({{{"mesh", 0}}});
  expect_refused(
      d.write(dir, "huge.gltf"),
      {"huge.gltf: /accessors/0: its 1000000000000 elements of 12 bytes (from byte 0, 12 bytes apart) need more than the 36 bytes of buffer view 0"});
  // The same with the buffer in a file beside the model, and a buffer claiming more than its file holds.
  Document e = one_triangle();
  e.doc["nodes"] = json::array({{{"mesh", 0}}});
  const fs::path path = e.write(dir, "claims.gltf", true);
  e.doc["buffers"][0]["byteLength"] = 1u << 30;
  test::write_text_file(path, e.doc.dump());
  expect_refused(path, {"claims.gltf: /buffers/0: buffer file '", "claims.gltf.bin' holds 36 bytes, but byteLength is 1073741824"});
}

TEST(GltfWrittenFiles, IndexOutOfRangeIsRefused) {
  test::TempDir dir;
  Document d;
  const int p = d.vec3({0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 2, 0, 1, 2, 0, 0, 3, 0, 1, 3, 0});
  const int i = d.indices({0, 1, 2, 3, 4, 9});
  d.doc["meshes"] = json::array({{{"primitives", json::array({{{"attributes", {{"POSITION", p}}}, {"indices", i}}})}}});
  d.doc["nodes"] = json::array({{{"mesh", 0}}});
  expect_refused(d.write(dir, "model.gltf"), {"model.gltf: /meshes/0/primitives/0/indices: index 9 out of range (the primitive has 8 vertices)"});
}

TEST(GltfWrittenFiles, NodeWithTwoParentsAndLongLoopsAreRefused) {
  test::TempDir dir;
  Document d = one_triangle();
  d.doc["nodes"] = json::array({{{"children", {2}}}, {{"children", {2}}}, {{"mesh", 0}}});
  expect_refused(d.write(dir, "parents.gltf"), {"parents.gltf: /nodes/1/children/0: node 2 is already a child of node 0"});
  Document e = one_triangle();
  e.doc["nodes"] = json::array({{{"children", {1}}}, {{"children", {2}}}, {{"children", {0}}, {"mesh", 0}}});
  e.doc["scenes"] = json::array({{{"nodes", json::array()}}});
  expect_refused(e.write(dir, "loop.gltf"), {"loop.gltf: /nodes/2/children/0: node 0 is its own ancestor: the hierarchy loops (0 -> 1 -> 2 -> 0)"});
}

TEST(GltfWrittenFiles, TextureCoordinatesOfFloatsAndNormalizedIntegers) {
  test::TempDir dir;
  for (const int component_type : {5126, 5121, 5123}) {
    SCOPED_TRACE(component_type);
    Document d = one_triangle();
    // (0, 0), (1, 0), (0, 1) in glTF's convention (v down the image), stored v up.
    std::string data;
    if (component_type == 5126)
      data = bytes_of(std::vector<float>{0, 0, 1, 0, 0, 1});
    else if (component_type == 5121)
      data = bytes_of(std::vector<u8>{0, 0, 255, 0, 0, 255});
    else
      data = bytes_of(std::vector<std::uint16_t>{0, 0, 65535, 0, 0, 65535});
    const int uv = d.accessor(d.view(data), component_type, 3, "VEC2", component_type != 5126);
    d.doc["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = uv;
    d.doc["meshes"][0]["primitives"][0]["material"] = 0;
    d.doc["materials"] = json::array({{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}}});
    d.doc["textures"] = json::array({{{"source", 0}}});
    // A 1x1 PNG beside the model.
    d.doc["images"] = json::array({{{"uri", "texture.png"}}});
    LinearImage pixel{1, 1, {0.5f, 0.25f, 1.0f}};
    write_image(dir / "texture.png", pixel);
    d.doc["nodes"] = json::array({{{"mesh", 0}}});
    const MeshFile file = read_gltf_file(d.write(dir, "uv.gltf"));
    expect_consistent(file);
    ASSERT_EQ(file.meshes[0].uvs.size(), 3u);
    const std::vector<std::array<double, 2>> expected = {{0, 1}, {1, 1}, {0, 0}};
    EXPECT_EQ(file.meshes[0].uvs, expected);
    ASSERT_EQ(file.textures.size(), 1u);
    EXPECT_EQ(file.textures[0].width, 1u);
  }
  // Integers that are not normalized are refused.
  Document d = one_triangle();
  const int uv = d.accessor(d.view(bytes_of(std::vector<u8>{0, 0, 1, 0, 0, 1})), 5121, 3, "VEC2", false);
  d.doc["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = uv;
  d.doc["meshes"][0]["primitives"][0]["material"] = 0;
  d.doc["materials"] = json::array({{{"emissiveTexture", {{"index", 0}}}}});
  d.doc["textures"] = json::array({{{"source", 0}}});
  d.doc["images"] = json::array({{{"uri", "texture.png"}}});
  d.doc["nodes"] = json::array({{{"mesh", 0}}});
  expect_refused(d.write(dir, "bytes.gltf"),
                 {"bytes.gltf: /meshes/0/primitives/0/attributes/TEXCOORD_0: TEXCOORD_0 needs a VEC2 accessor of floats or "
                  "unsigned bytes or unsigned shorts (integers normalized); accessor 1 is VEC2 of unsigned bytes"});
}

// A glTF buffer or image named with '..' (escaped or not), or by an absolute path, was followed out of the model's
// folder; it is refused unless the user allows it.
TEST(GltfWrittenFiles, FilesOutsideTheModelsFolderAreRefused) {
  test::TempDir dir;
  fs::create_directories(dir / "model");
  LinearImage pixel{1, 1, {0.5f, 0.25f, 1.0f}};
  write_image(dir / "outside.png", pixel);
  const auto with_buffer = [&](const std::string& name, const std::string& uri) {
    Document d = one_triangle();
    d.doc["nodes"] = json::array({{{"mesh", 0}}});
    test::write_text_file(dir / "outside.bin", d.bin);
    d.doc["buffers"] = json::array({{{"byteLength", d.bin.size()}, {"uri", uri}}});
    d.bin.clear();
    return d.write(dir, "model/" + name);
  };
  expect_refused(with_buffer("up.gltf", "../outside.bin"), {"/buffers/0/uri: '../outside.bin' lies outside the model's folder"});
  expect_refused(with_buffer("escaped.gltf", "%2E%2E/outside.bin"), {"/buffers/0/uri:", "outside the model's folder"});
  expect_refused(with_buffer("absolute.gltf", (dir / "outside.bin").string()), {"/buffers/0/uri:", "is an absolute path"});
  EXPECT_EQ(triangle_count(read_gltf_file(dir / "model/up.gltf", ModelReferences::kAnywhere)), 1u);

  Document d = one_triangle();
  d.doc["nodes"] = json::array({{{"mesh", 0}}});
  d.doc["images"] = json::array({{{"uri", "../outside.png"}}});
  const fs::path image = d.write(dir, "model/image.gltf");
  expect_refused(image, {"/images/0/uri: '../outside.png' lies outside the model's folder"});
  EXPECT_EQ(triangle_count(read_gltf_file(image, ModelReferences::kAnywhere)), 1u);
}

// A number beyond a double's range ("1e999") is named by its line, column and JSON path, as in a scene file: the
// JSON parser's own message said only that a number overflowed.
TEST(GltfWrittenFiles, NumberBeyondADoublesRangeIsNamedByItsPlace) {
  test::TempDir dir;
  Document d = one_triangle();
  d.doc["nodes"] = json::array({{{"mesh", 0}, {"translation", {12345, 0, 0}}}});
  const fs::path path = d.write(dir, "huge.gltf");
  std::string text = test::read_text_file(path);
  const std::size_t offset = text.find("12345");
  text.replace(offset, 5, "1e999");
  test::write_text_file(path, text);
  const std::size_t line_start = text.rfind('\n', offset) + 1;
  const auto line = 1 + std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(offset), '\n');
  const std::string message = expect_refused(path, {"/nodes/0/translation/0: the number 1e999 is beyond the range of a double"});
  EXPECT_TRUE(message.starts_with(fmt::format("{}:{}:{}: ", path.string(), line, offset - line_start + 1))) << message;
}

// A node whose transform (with its parents') scales volumes beyond a double's range is refused naming the node: it
// was dropped as if singular, and a model of one such node became "the model has no triangles to render".
TEST(GltfWrittenFiles, TransformTooLargeToBeFiniteIsRefusedNamingTheNode) {
  test::TempDir dir;
  Document d = one_triangle();
  d.doc["nodes"] = json::array({{{"children", {1}}, {"scale", {1e300, 1e300, 1e300}}}, {{"mesh", 0}}});
  expect_refused(d.write(dir, "scale.gltf"), {"scale.gltf: /nodes/1: its transform, with its parents', is too large to be finite"});
  // A scale of 0 hides a mesh, as animations do: skipped with a warning.
  d.doc["nodes"] = json::array({{{"mesh", 0}, {"scale", {0, 1, 1}}}, {{"mesh", 0}}});
  const MeshFile hidden = read_gltf_file(d.write(dir, "hidden.gltf"));
  EXPECT_EQ(hidden.placements.size(), 1u);
  EXPECT_TRUE(test::has_warning(hidden, "singular (a scale of 0)")) << all_warnings(hidden);
  // A finite transform can still place a vertex beyond a double's range: named when the model is the scene.
  d.doc["nodes"] = json::array({{{"mesh", 0}, {"scale", {1e308, 1, 1}}, {"translation", {1.7e308, 0, 0}}}});
  const fs::path far = d.write(dir, "far.gltf");
  try {
    load_scene_file(far);
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), far.string() + ": vertex 1 of mesh 'mesh 0' is placed beyond a double's range (about 1.8e308)");
  }
}

TEST(GltfWrittenFiles, MaterialFactorsEmissiveStrengthAndDefaultMaterial) {
  test::TempDir dir;
  Document d;
  const int p = d.vec3({0, 0, 0, 1, 0, 0, 0, 1, 0});
  // Three primitives on the same positions: material 1, no material, material 0 (material 2 is not used).
  d.doc["meshes"] = json::array({{{"primitives", json::array({{{"attributes", {{"POSITION", p}}}, {"material", 1}},
                                                              {{"attributes", {{"POSITION", p}}}},
                                                              {{"attributes", {{"POSITION", p}}}, {"material", 0}}})}}});
  d.doc["materials"] = json::array(
      {{{"name", "glow"}, {"emissiveFactor", {1, 0.5, 0.25}}, {"extensions", {{"KHR_materials_emissive_strength", {{"emissiveStrength", 4}}}}}},
       {{"pbrMetallicRoughness", {{"baseColorFactor", {0.2, 0.4, 0.6, 0.5}}, {"metallicFactor", 0.25}, {"roughnessFactor", 0.75}}},
        {"alphaMode", "BLEND"}},
       {{"name", "unused"}}});
  d.doc["extensionsUsed"] = {"KHR_materials_emissive_strength"};
  d.doc["extensionsRequired"] = {"KHR_materials_emissive_strength"};
  d.doc["nodes"] = json::array({{{"mesh", 0}}});
  const MeshFile file = read_gltf_file(d.write(dir, "materials.gltf"));
  expect_consistent(file);
  // The materials used, in the file's order, then glTF's default one.
  ASSERT_EQ(file.materials.size(), 3u);
  EXPECT_EQ(file.materials[0].name, "glow");
  expect_near(file.materials[0].emission, {4, 2, 1}, 0);
  expect_near(file.materials[0].base_color, {1, 1, 1}, 0);
  EXPECT_EQ(file.materials[1].name, "material 1");
  expect_near(file.materials[1].base_color, {0.2, 0.4, 0.6}, 0);
  EXPECT_EQ(file.materials[1].metallic, 0.25);
  EXPECT_EQ(file.materials[1].roughness, 0.75);
  expect_near(file.materials[2].base_color, {1, 1, 1}, 0);
  EXPECT_EQ(file.materials[2].metallic, 1);
  EXPECT_EQ(file.materials[2].roughness, 1);
  // One mesh of three triangles on three shared vertices, a material each.
  ASSERT_EQ(file.meshes.size(), 1u);
  EXPECT_EQ(file.meshes[0].positions.size(), 3u);
  EXPECT_EQ(file.meshes[0].materials, (std::vector<u32>{1, 2, 0}));
  // Alpha 0.5 in BLEND mode is drawn opaque, said; the extension read is not warned of.
  EXPECT_TRUE(has_warning(file, "transparency is not rendered")) << all_warnings(file);
  EXPECT_EQ(file.warnings.size(), 1u) << all_warnings(file);
}

TEST(GltfWrittenFiles, SkinWithoutInverseBindMatricesIsRead) {
  // glTF allows a skin without inverseBindMatrices; tinygltf complains of it (and still reads the file).
  test::TempDir dir;
  Document d = one_triangle();
  d.doc["nodes"] = json::array({{{"mesh", 0}, {"skin", 0}, {"children", {1}}}, json::object()});
  d.doc["skins"] = json::array({{{"joints", {1}}}});
  const MeshFile file = read_gltf_file(d.write(dir, "skin.gltf"));
  EXPECT_EQ(triangle_count(file), 1u);
  EXPECT_TRUE(has_warning(file, "skins are not applied")) << all_warnings(file);
}

TEST(GltfWrittenFiles, WarningsQuotingTheFileAreOneLine) {
  test::TempDir dir;
  Document d = one_triangle();
  d.doc["extensionsUsed"] = {"EXT_\x1b[2Jnew\nline"};
  const MeshFile file = read_gltf_file(d.write(dir, "escape.gltf"));
  ASSERT_EQ(file.warnings.size(), 1u);
  EXPECT_EQ(file.warnings[0], "extension EXT_\\x1b[2Jnew\\nline is not read: its effect is not rendered");
}

TEST(GltfWrittenFiles, PrimitiveWithoutNormalsBesideOneWithGetsFlatNormals) {
  test::TempDir dir;
  Document d;
  const int p = d.vec3({0, 0, 0, 1, 0, 0, 0, 1, 0});
  const int n = d.vec3({0, 0, 1, 0, 0, 1, 0, 0, 1});
  const int q = d.vec3({0, 0, 0, 0, 1, 0, 1, 0, 0});  // facing -z
  d.doc["meshes"] =
      json::array({{{"primitives", json::array({{{"attributes", {{"POSITION", p}, {"NORMAL", n}}}}, {{"attributes", {{"POSITION", q}}}}})}}});
  d.doc["nodes"] = json::array({{{"mesh", 0}}});
  const MeshFile file = read_gltf_file(d.write(dir, "flat.gltf"));
  expect_consistent(file);
  const TriangleMesh& mesh = file.meshes.at(0);
  ASSERT_EQ(mesh.positions.size(), 6u);
  ASSERT_EQ(mesh.normals.size(), 6u);
  for (int i = 3; i < 6; ++i) expect_near(mesh.normals[i], {0, 0, -1}, 0);
  EXPECT_TRUE(file.warnings.empty()) << all_warnings(file);
}

// A triangle in z = 0 with normals, uvs and tangents (along -y, bitangent sign -1), its material's normal texture
// read with TEXCOORD_`normal_set`.
Document normal_mapped_triangle(const test::TempDir& dir, int normal_set = 0) {
  Document d = one_triangle();
  auto& attributes = d.doc["meshes"][0]["primitives"][0]["attributes"];
  attributes["NORMAL"] = d.vec3({0, 0, 1, 0, 0, 1, 0, 0, 1});
  attributes["TEXCOORD_0"] = d.accessor(d.view(bytes_of(std::vector<float>{0, 0, 1, 0, 0, 1})), 5126, 3, "VEC2");
  attributes["TANGENT"] = d.accessor(d.view(bytes_of(std::vector<float>{0, -2, 0, -1, 0, -1, 0, -1, 0, -0.5f, 0, -1})), 5126, 3, "VEC4");
  d.doc["meshes"][0]["primitives"][0]["material"] = 0;
  d.doc["materials"] = json::array({{{"normalTexture", {{"index", 0}, {"scale", 0.5}, {"texCoord", normal_set}}}}});
  d.doc["textures"] = json::array({{{"source", 0}}});
  d.doc["images"] = json::array({{{"uri", "normals.png"}}});
  write_image(dir / "normals.png", LinearImage{1, 1, {0.5f, 0.5f, 1.0f}});
  d.doc["nodes"] = json::array({{{"mesh", 0}}});
  return d;
}

TEST(GltfWrittenFiles, TangentsAndNormalTextureAreRead) {
  test::TempDir dir;
  const MeshFile file = read_gltf_file(normal_mapped_triangle(dir).write(dir, "normals.gltf"));
  expect_consistent(file);
  EXPECT_TRUE(file.warnings.empty()) << all_warnings(file);
  ASSERT_EQ(file.materials.size(), 1u);
  EXPECT_GE(file.materials[0].normal_texture, 0);
  EXPECT_EQ(file.materials[0].normal_scale, 0.5);
  const TriangleMesh& mesh = file.meshes.at(0);
  // Normalised, and w kept as a sign.
  const std::vector<std::array<double, 4>> expected = {{0, -1, 0, -1}, {0, -1, 0, -1}, {0, -1, 0, -1}};
  EXPECT_EQ(mesh.tangents, expected);

  // Flattened, the tangents are kept (the material has a normal map), and the map is read as linear data.
  SceneDescription scene = test::generated_scene({0, 0, 3});
  const u32 index = add_mesh_file(scene, std::make_shared<MeshFile>(file), "/objects/0/file");
  test::place_mesh(scene, index, {1, 1, 1}, {0, 0, 0}, {0, 0, 0});
  const FlatScene<float> flat = test::flatten<float>(scene);
  ASSERT_EQ(flat.mesh_tangents.size(), 3u);
  EXPECT_EQ(flat.meshes.at(0).first_tangent, 0u);
  EXPECT_EQ(flat.mesh_tangents[1].sign, -1.0f);
  const auto& material = std::get<MetallicRoughness<float>>(flat.materials.at(0));
  EXPECT_EQ(material.normal_scale, 0.5f);
  EXPECT_EQ(std::get<ImageTexture<float>>(flat.textures.at(material.normal_map)).linear, 1u);
  // A hit reads them: the tangent (0, -1, 0), the bitangent -normal x tangent = (-1, 0, 0).
  const SceneView<float> view = flat.view();
  const Ray<float> ray{{0.2f, 0.2f, 2}, {0, 0, -1}, 0};
  Hit<float> hit{};
  ASSERT_TRUE(closest_hit(view, ray, IntersectContext<float>{view.boundaries, nullptr, 0}, hit));
  const SurfacePoint<float> at = describe_hit(view.primitives[hit.primitive], view.triangle_attributes, view.meshes, ray, hit, true, true);
  EXPECT_NEAR(at.tangent.y, -1.0f, 1e-6f);
  EXPECT_EQ(at.handedness, -1.0f);

  // Without a normal texture the tangents are not read at all; with one on another uv set it is not applied.
  Document plain = normal_mapped_triangle(dir);
  plain.doc["materials"] = json::array({json::object()});
  EXPECT_TRUE(read_gltf_file(plain.write(dir, "plain.gltf")).meshes.at(0).tangents.empty());
  const MeshFile other_set = read_gltf_file(normal_mapped_triangle(dir, 1).write(dir, "set1.gltf"));
  EXPECT_EQ(other_set.materials.at(0).normal_texture, -1);
  EXPECT_TRUE(has_warning(other_set, "/materials/0/normalTexture: normal textures read with a texture coordinate set other than TEXCOORD_0"))
      << all_warnings(other_set);
}

TEST(GltfWrittenFiles, VertexTangentsAreStoredOnlyForMeshesWithANormalMap) {
  // The same mesh with tangents, its material with and without a normal map: only the first pays for them.
  test::TempDir dir;
  const MeshFile file = read_gltf_file(normal_mapped_triangle(dir).write(dir, "normals.gltf"));
  auto without = std::make_shared<MeshFile>(file);
  without->materials[0].normal_texture = -1;
  SceneDescription scene = test::generated_scene({0, 0, 3});
  test::place_mesh(scene, add_mesh_file(scene, without, "/objects/0/file"), {1, 1, 1}, {0, 0, 0}, {0, 0, 0});
  const FlatScene<float> flat = test::flatten<float>(scene);
  EXPECT_TRUE(flat.mesh_tangents.empty());
  EXPECT_EQ(flat.meshes.at(0).first_tangent, kNoAttributes);
}

TEST(GltfWrittenFiles, UnsupportedThingsAreRefusedWithTheirPath) {
  test::TempDir dir;
  {
    Document d = one_triangle();
    d.doc["accessors"][0]["sparse"] = {{"count", 1}, {"indices", {{"bufferView", 0}, {"componentType", 5121}}}, {"values", {{"bufferView", 0}}}};
    d.doc["nodes"] = json::array({{{"mesh", 0}}});
    expect_refused(d.write(dir, "sparse.gltf"),
                   {"sparse.gltf: /meshes/0/primitives/0/attributes/POSITION: accessor 0 is sparse; sparse accessors are not read"});
  }
  {
    Document d = one_triangle();
    d.doc["extensionsUsed"] = {"KHR_texture_transform"};
    d.doc["extensionsRequired"] = {"KHR_texture_transform"};
    expect_refused(d.write(dir, "required.gltf"), {"required.gltf: /extensionsRequired/0: the file requires the extension KHR_texture_transform"});
  }
  {
    Document d = one_triangle();
    d.doc["meshes"][0]["primitives"][0]["mode"] = 7;
    expect_refused(d.write(dir, "mode.gltf"), {"mode.gltf: /meshes/0/primitives/0/mode: 7 is out of range (0 to 6)"});
  }
  {
    Document d = one_triangle();
    d.doc["accessors"][0]["count"] = 2;
    d.doc["nodes"] = json::array({{{"mesh", 0}}});
    expect_refused(d.write(dir, "partial.gltf"), {"partial.gltf: /meshes/0/primitives/0: 2 vertices do not make whole triangles"});
  }
  {
    Document d = one_triangle();
    d.doc["asset"]["version"] = "1.0";
    expect_refused(d.write(dir, "old.gltf"), {"old.gltf: /asset/version: glTF 1.0 is not read"});
  }
  {
    Document d = one_triangle();
    d.doc["nodes"] = json::array({{{"mesh", 0}, {"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}}, {"translation", {1, 0, 0}}}});
    expect_refused(d.write(dir, "both.gltf"), {"both.gltf: /nodes/0: it has both 'matrix' and translation"});
  }
  {
    // Integers beyond an int are not cut to one.
    Document d = one_triangle();
    d.doc["nodes"] = json::array({{{"mesh", 4294967296ull}}});
    expect_refused(d.write(dir, "wide.gltf"), {"wide.gltf: /nodes/0/mesh: index 4294967296 is out of range (/meshes has 1 entries)"});
  }
  test::write_text_file(dir / "syntax.gltf", "{\"asset\": {\"version\": \"2.0\"},}");
  expect_refused(dir / "syntax.gltf", {"syntax.gltf: not valid JSON: parse error at line 1"});
  test::write_text_file(dir / "deep.gltf", std::string(100000, '[') + std::string(100000, ']'));
  expect_refused(dir / "deep.gltf", {"deep.gltf: JSON nesting deeper than 64 levels"});
  test::write_text_file(dir / "short.glb", std::string("glTF\x02\0\0\0", 8));
  expect_refused(dir / "short.glb", {"short.glb: not a valid .glb: 8 bytes are too few"});
}

// tinygltf 2.7.0 checks the BIN chunk's length against the file's without the chunk's 8-byte header, and then
// copies the buffer from up to 8 bytes past the end (AddressSanitizer: heap-buffer-overflow in ParseBuffer). The
// reader refuses such a file before tinygltf sees it.
TEST(GltfWrittenFiles, GlbWhoseBinChunkRunsPastTheFileIsRefused) {
  test::TempDir dir;
  std::string json_text = R"({"asset":{"version":"2.0"},"buffers":[{"byteLength":12}]})";
  while ((20 + json_text.size()) % 4 != 0) json_text += ' ';
  std::string glb;
  const auto u32 = [&](std::size_t v) {
    for (int i = 0; i < 4; ++i) glb += static_cast<char>((v >> (8 * i)) & 255);
  };
  glb += "glTF";
  u32(2);
  u32(20 + json_text.size() + 12);
  u32(json_text.size());
  glb += "JSON" + json_text;
  u32(12);  // a BIN chunk that says 12 bytes and holds 4
  glb += std::string("BIN\0", 4) + "abcd";
  test::write_text_file(dir / "short-bin.glb", glb);
  expect_refused(dir / "short-bin.glb", {"short-bin.glb: not a valid .glb: its BIN chunk of 12 bytes does not fit in the file's"});
}

TEST(GltfWrittenFiles, SpecialFilesAreNotRead) {
  test::TempDir dir;
  // A FIFO as the model and as its buffer: refused at once, without blocking on them.
  ASSERT_EQ(::mkfifo((dir / "fifo.gltf").c_str(), 0600), 0);
  expect_refused(dir / "fifo.gltf", {"fifo.gltf: is a FIFO (named pipe), not a model file"});
  Document d = one_triangle();
  d.doc["nodes"] = json::array({{{"mesh", 0}}});
  const fs::path path = d.write(dir, "model.gltf", true);
  fs::remove(dir / "model.gltf.bin");
  ASSERT_EQ(::mkfifo((dir / "model.gltf.bin").c_str(), 0600), 0);
  expect_refused(path, {"model.gltf: /buffers/0/uri: buffer file '", "model.gltf.bin' is not a regular file"});
  expect_refused(dir / "absent.glb", {"absent.glb: cannot open the model file: it does not exist"});
}

}  // namespace
}  // namespace pt
