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
