// Checks that every shipped scene in scenes/ loads, flattens and renders a few samples with finite results.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <string>
#include <vector>

#include "test_support.hpp"

namespace pt {
namespace {

std::vector<std::string> shipped_scenes() {
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(test::scenes_dir()))
    if (entry.path().extension() == ".json") names.push_back(entry.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

// "book1-final.json" -> "book1_final": test names allow letters, digits and underscores only.
std::string test_name(const std::string& file) {
  std::string name = std::filesystem::path(file).stem().string();
  for (char& c : name)
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  return name;
}

class ShippedScene : public ::testing::TestWithParam<std::string> {};

template <class T>
void load_flatten_render(const std::string& file) {
  const SceneDescription scene = load_scene_file(test::scene_path(file));
  ASSERT_FALSE(scene.objects.empty());
  // The file's own settings, shrunk as --width, --height and --spp would.
  RenderSettings settings = scene.render;
  settings.width = 24;
  settings.height = 16;
  settings.samples_per_pixel = 2;
  const FlatScene<T> flat = flatten_scene<T>(scene, settings);
  EXPECT_GE(flat.primitives.size(), scene.objects.size());
  EXPECT_LE(flat.bvh_depth, kBvhMaxDepth);
  const RenderResult result = test::render(flat, 2);
  EXPECT_EQ(result.stats.dropped_samples, 0u) << "non-finite samples";
  EXPECT_EQ(result.stats.samples, 24u * 16u * 2u);
  double sum = 0;
  for (float v : result.image.rgb) {
    ASSERT_TRUE(std::isfinite(v));
    ASSERT_GE(v, 0.0f);
    sum += v;
  }
  EXPECT_GT(sum, 0.0) << "an all-black image";
}

TEST_P(ShippedScene, LoadsFlattensAndRendersInFloat) { load_flatten_render<float>(GetParam()); }
TEST_P(ShippedScene, LoadsFlattensAndRendersInDouble) { load_flatten_render<double>(GetParam()); }

INSTANTIATE_TEST_SUITE_P(Scenes, ShippedScene, ::testing::ValuesIn(shipped_scenes()),
                         [](const ::testing::TestParamInfo<std::string>& info) { return test_name(info.param); });

TEST(ShippedScenes, AllDocumentedScenesArePresent) {
  const std::vector<std::string> names = shipped_scenes();
  for (const char* expected : {"book1-final.json", "book2-final.json", "cornell-box.json", "cornell-smoke.json", "seed-default.json", "tiny.json"})
    EXPECT_NE(std::find(names.begin(), names.end(), expected), names.end()) << expected;
}

TEST(ShippedScenes, TinySceneUsesEveryObjectMaterialAndTextureType) {
  // scenes/README.md promises this; the other tests rely on it to cover every kind.
  const SceneDescription scene = load_scene_file(test::scene_path("tiny.json"));
  std::set<std::size_t> shapes, materials, textures;
  for (const SceneObject& o : scene.objects) shapes.insert(o.shape.index());
  for (const Material<double>& m : scene.materials) materials.insert(m.index());
  for (const Texture<double>& t : scene.textures) textures.insert(t.index());
  EXPECT_EQ(shapes.size(), std::variant_size_v<ObjectShape>);
  // Every material type but the metallic-roughness one, which meshes.json has through its glTF model (the tiny
  // scene's stored reference image predates it).
  const SceneDescription meshes = load_scene_file(test::scene_path("meshes.json"));
  for (const Material<double>& m : meshes.materials)
    if (std::holds_alternative<MetallicRoughness<double>>(m)) materials.insert(m.index());
  EXPECT_EQ(materials.size(), std::variant_size_v<Material<double>>);
  EXPECT_EQ(textures.size(), std::variant_size_v<Texture<double>>);
  // Both medium boundaries, and triangles with per-vertex attributes.
  bool triangle_attributes = false;
  for (const SceneObject& o : scene.objects)
    if (const auto* t = std::get_if<TriangleSettings>(&o.shape)) triangle_attributes |= t->normals.has_value() && t->uvs.has_value();
  EXPECT_TRUE(triangle_attributes);
}

TEST(ShippedScenes, SeedDefaultSceneHasTheDocumentedObjectCount) {
  // scenes/README.md: 496 objects, object for object the seed implementation's default scene.
  EXPECT_EQ(load_scene_file(test::scene_path("seed-default.json")).objects.size(), 496u);
}

}  // namespace
}  // namespace pt

namespace pt {
namespace {

// Every number of a shape, in a fixed order, with the kind first and 0/1 for an absent/present optional part.
std::vector<double> shape_numbers(const ObjectShape& shape) {
  std::vector<double> out{static_cast<double>(shape.index())};
  auto add = [&](const Vec3d& v) { out.insert(out.end(), {v.x, v.y, v.z}); };
  struct Collect {
    std::vector<double>& out;
    decltype(add)& vec;
    void operator()(const Sphere<double>& s) const { vec(s.center), out.push_back(s.radius); }
    void operator()(const MovingSphereSettings& s) const { vec(s.center0), vec(s.center1), out.insert(out.end(), {s.radius, s.time0, s.time1}); }
    void operator()(const TriangleSettings& t) const {
      for (const Vec3d& v : t.vertices) vec(v);
      out.push_back(t.normals.has_value());
      if (t.normals)
        for (const Vec3d& n : *t.normals) vec(n);
      out.push_back(t.uvs.has_value());
      if (t.uvs)
        for (const auto& uv : *t.uvs) out.insert(out.end(), {uv[0], uv[1]});
    }
    void operator()(const QuadSettings& q) const { vec(q.corner), vec(q.u), vec(q.v); }
    void operator()(const BoxSettings& b) const { vec(b.min), vec(b.max); }
    void operator()(const MediumSettings& m) const {
      out.push_back(static_cast<double>(m.boundary.index()));
      std::visit(*this, m.boundary);
      for (const auto& row : m.boundary_transform.rotation) out.insert(out.end(), {row[0], row[1], row[2]});
      vec(m.boundary_transform.translation);
      out.push_back(m.density);
    }
    void operator()(const MeshSettings& m) const {
      out.push_back(m.file);
      for (const auto& row : m.transform.linear) out.insert(out.end(), {row[0], row[1], row[2]});
      vec(m.transform.translation);
    }
  };
  std::visit(Collect{out, add}, shape);
  return out;
}

bool same_transform(const RigidTransform& a, const RigidTransform& b) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (a.rotation[i][j] != b.rotation[i][j]) return false;
  return a.translation.x == b.translation.x && a.translation.y == b.translation.y && a.translation.z == b.translation.z;
}

}  // namespace

TEST(ObjectList, ReturnsEveryObjectAsStoredInOrder) {
  // The compact store splits objects by shape kind and keeps transforms apart: reading back must give each object's
  // own shape, transform and material, in the order they were added, for every kind and with or without a transform.
  std::vector<SceneObject> written;
  const RigidTransform turned = RigidTransform::from_euler_degrees({10, 20, 30}, {1, 2, 3});
  for (int k = 0; k < 3; ++k) {  // three of each kind, each different
    const double d = k + 1;
    TriangleSettings with_attributes{{Vec3d{d, 0, 0}, Vec3d{0, d, 0}, Vec3d{0, 0, d}}, {}, {}};
    with_attributes.normals = std::array<Vec3d, 3>{Vec3d{1, 0, 0}, Vec3d{0, d, 0}, Vec3d{0, 0, 1}};
    with_attributes.uvs = std::array<std::array<double, 2>, 3>{{{0, d}, {1, 0}, {0.5, 0.25}}};
    const ObjectShape shapes[] = {
        Sphere<double>{{d, 2 * d, 3 * d}, d},
        MovingSphereSettings{{d, 0, 0}, {0, d, 0}, 0.5 * d, 0, d},
        TriangleSettings{{Vec3d{d, 0, 0}, Vec3d{0, d, 0}, Vec3d{0, 0, d}}, {}, {}},
        with_attributes,
        QuadSettings{{d, d, d}, {d, 0, 0}, {0, 0, d}},
        BoxSettings{{-d, -d, -d}, {d, 2 * d, 3 * d}},
        MediumSettings{Sphere<double>{{0, d, 0}, d}, turned, 0.1 * d},
        MediumSettings{BoxSettings{{0, 0, 0}, {d, d, d}}, RigidTransform{}, d},
        MeshSettings{static_cast<u32>(k), AffineTransform::scaling({d, 2 * d, 3 * d})},
    };
    for (const ObjectShape& shape : shapes) {
      SceneObject o;
      o.shape = shape;
      o.material = static_cast<u32>(written.size());
      written.push_back(o);
      o.transform = turned;
      o.material += 1000;
      written.push_back(o);
    }
  }
  ObjectList list;
  for (const SceneObject& o : written) list.push_back(o);
  ASSERT_EQ(list.size(), written.size());
  std::size_t i = 0;
  for (const SceneObject& o : list) {
    EXPECT_EQ(shape_numbers(o.shape), shape_numbers(written[i].shape)) << i;
    EXPECT_TRUE(same_transform(o.transform, written[i].transform)) << i;
    EXPECT_EQ(o.material, written[i].material) << i;
    ++i;
  }
  // set() replaces one object, whatever its kind was.
  list.set(1, written[0]);
  EXPECT_EQ(list[1].material, written[0].material);
  EXPECT_TRUE(list[1].transform.is_identity());
  EXPECT_EQ(list[2].material, written[2].material);
}

TEST(JsonPathList, ReturnsEveryPathAsWritten) {
  // Paths are kept as a shared pattern and a number: every path must come back character for character, whatever
  // its numbers, leading zeros, empty parts, escapes or keys that look like numbers.
  const std::vector<std::string> written = {
      "/objects/0/material", "/objects/1/material", "/objects/123456789/material/albedo", "/objects/1234567890/material",
      "/objects/007/material", "/materials/m1/albedo", "/materials/12/albedo", "/textures/a~1b/color", "", "/", "//", "/a//1",
      "/a/1/", "/a/1/2/3", "/objects/4294967295", "/objects/0", "/camera", "(model)", "no/slash/9", "/x/-1", "/x/1e3", "/\u0000/5"};
  JsonPathList list;
  for (const std::string& path : written) list.push_back(path);
  for (int i = 0; i < 100000; ++i) list.push_back("/objects/" + std::to_string(i) + "/material");
  ASSERT_EQ(list.size(), written.size() + 100000);
  for (std::size_t i = 0; i < written.size(); ++i) EXPECT_EQ(list[i], written[i]) << i;
  for (int i = 0; i < 100000; i += 997) EXPECT_EQ(list[written.size() + i], "/objects/" + std::to_string(i) + "/material");
}

}  // namespace pt
