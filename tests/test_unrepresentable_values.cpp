// Values the chosen number format cannot hold, or that its intersection and shading arithmetic would overflow, are
// refused when the scene is flattened, with one line naming the file, line:column, JSON path, value and format;
// values just inside each limit are accepted (docs/scene-format.md, "Supported range of values").
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "base/number_formats.hpp"
#include "kernel/fixed_point.hpp"
#include "scene/json_positions.hpp"
#include "test_support.hpp"

namespace pt {
namespace {

const std::string kValuesSource = "values.json";

// A valid scene whose second object (index 1), camera or lamp material each case replaces.
const std::string kValuesBase = R"({
  "render": {"width": 8, "height": 6, "samples_per_pixel": 1, "max_depth": 4},
  "camera": {"look_from": LOOK_FROM, "look_at": [0, 0, 0], "vertical_fov": 40},
  "materials": {
    "white": {"type": "lambertian", "albedo": [0.8, 0.8, 0.8]},
    "lamp": {"type": "diffuse_light", "emission": LAMP}
  },
  "objects": [
    {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "white"},
    OBJECT
  ]
}
)";

struct Parts {
  std::string object = R"({"type": "quad", "corner": [-2, -2, -1], "u": [4, 0, 0], "v": [0, 4, 0], "material": "lamp"})";
  std::string look_from = "[0, 0, 3]";
  std::string lamp = "[4, 4, 4]";
};

std::string scene_text(const Parts& parts) {
  return test::replaced(test::replaced(test::replaced(kValuesBase, "OBJECT", parts.object), "LOOK_FROM", parts.look_from), "LAMP", parts.lamp);
}
std::string with_value_object(const std::string& object) {
  Parts parts;
  parts.object = object;
  return scene_text(parts);
}

// "FILE:LINE:COLUMN: " of the first character of `marker`, which must occur once in the text.
std::string place_of(const std::string& text, const std::string& marker) {
  const std::size_t found = text.find(marker);
  if (found == std::string::npos || text.find(marker, found + 1) != std::string::npos)
    throw std::logic_error("marker '" + marker + "' is not unique in the scene text");
  const TextPosition at = JsonPositions::position_of_offset(text, found);
  return kValuesSource + ":" + std::to_string(at.line) + ":" + std::to_string(at.column) + ": ";
}

// Flattening the text in format T fails with one line that starts with the place of `marker` and the JSON path
// `pointer`, and contains every one of `parts` (the value, the format, ...).
template <class T>
void expect_refused(const std::string& text, const std::string& marker, const std::string& pointer, const std::vector<std::string>& parts) {
  const SceneDescription scene = test::parse(text, kValuesSource);  // the parser accepts it: the value is finite
  try {
    test::flatten<T>(scene);
    FAIL() << "accepted in " << number_format_name<T>() << ":\n" << text;
  } catch (const InputError& e) {
    const std::string message = e.what();
    const std::string prefix = place_of(text, marker) + pointer + ": ";
    EXPECT_EQ(message.rfind(prefix, 0), 0u) << message << "\nexpected it to start with: " << prefix;
    for (const std::string& part : parts) EXPECT_NE(message.find(part), std::string::npos) << message << "\nmissing: " << part;
    EXPECT_EQ(message.find('\n'), std::string::npos) << "one line: " << message;
  }
}

template <class T>
void expect_accepted(const std::string& text) {
  const SceneDescription scene = test::parse(text, kValuesSource);
  EXPECT_NO_THROW(test::flatten<T>(scene)) << number_format_name<T>() << ":\n" << text;
}

const std::string kFloatLengths = "is beyond float's supported range for lengths and coordinates (|x| <= 7.21e+16; see docs/scene-format.md)";
const std::string kFloatColours = "is beyond float's supported range for colours and emission (|x| <= 7.21e+16; see docs/scene-format.md)";
const std::string kDoubleColours = "is beyond double's supported range for colours and emission (|x| <= 5.24e+151; see docs/scene-format.md)";

TEST(UnrepresentableValues, BaseSceneFlattensInEveryFormat) {
  expect_accepted<float>(scene_text(Parts{}));
  expect_accepted<double>(scene_text(Parts{}));
  expect_accepted<Fixed<16, 16>>(scene_text(Parts{}));
}

TEST(UnrepresentableValues, SphereRadiusBeyondFloat) {
  expect_refused<float>(with_value_object(R"({"type": "sphere", "center": [2, 0, 0], "radius": 1e30, "material": "white"})"), "1e30",
                        "/objects/1/radius", {"1e+30 " + kFloatLengths});
  // The limit is 2^56, about 7.2e16: just inside it renders in float; double takes the large radius.
  expect_accepted<float>(with_value_object(R"({"type": "sphere", "center": [2, 0, 0], "radius": 7e16, "material": "white"})"));
  expect_accepted<double>(with_value_object(R"({"type": "sphere", "center": [2, 0, 0], "radius": 1e30, "material": "white"})"));
}

TEST(UnrepresentableValues, CoordinateBeyondFloat) {
  // As written: the component is named.
  expect_refused<float>(with_value_object(R"({"type": "quad", "corner": [1e25, 0, 0], "u": [1, 0, 0], "v": [0, 1, 0], "material": "white"})"), "1e25",
                        "/objects/1/corner/0", {"1e+25 " + kFloatLengths});
  // Moved there by a translation: the position written is named, and the value after the transform.
  expect_refused<float>(
      with_value_object(R"({"type": "sphere", "center": [2, 0, 0], "radius": 1, "transform": {"translate": [0, 1e17, 0]}, "material": "white"})"),
      R"([2, 0, 0])", "/objects/1/center", {"1e+17 (after the object's transform) " + kFloatLengths});
  // A box's corner, as written.
  expect_refused<float>(with_value_object(R"({"type": "box", "min": [0, 0, 0], "max": [1, 1e17, 1], "material": "white"})"), "1e17",
                        "/objects/1/max/1", {"1e+17 " + kFloatLengths});
  // Just inside the limit.
  expect_accepted<float>(with_value_object(R"({"type": "quad", "corner": [7e16, 0, 0], "u": [1, 0, 0], "v": [0, 1, 0], "material": "white"})"));
  expect_accepted<float>(
      with_value_object(R"({"type": "sphere", "center": [2, 0, 0], "radius": 1, "transform": {"translate": [0, 7e16, 0]}, "material": "white"})"));
  expect_accepted<double>(with_value_object(R"({"type": "quad", "corner": [1e25, 0, 0], "u": [1, 0, 0], "v": [0, 1, 0], "material": "white"})"));
}

TEST(UnrepresentableValues, EmissionBeyondFloatAndDouble) {
  // In a named material: the path is where the value was written, under /materials.
  Parts named;
  named.lamp = "[1e308, 1, 1]";
  expect_refused<float>(scene_text(named), "1e308", "/materials/lamp/emission/0", {"1e+308 " + kFloatColours});
  expect_refused<double>(scene_text(named), "1e308", "/materials/lamp/emission/0", {"1e+308 " + kDoubleColours});
  // Inline in an object.
  const std::string inline_lamp =
      with_value_object(R"({"type": "sphere", "center": [2, 0, 0], "radius": 1, "material": {"type": "diffuse_light", "emission": [1, 1e20, 1]}})");
  expect_refused<float>(inline_lamp, "1e20", "/objects/1/material/emission/1", {"1e+20 " + kFloatColours});
  expect_accepted<double>(inline_lamp);
  // Just inside: 2^56 (about 7.2e16) in float, 2^504 (about 5.2e151) in double.
  Parts inside;
  inside.lamp = "[7e16, 1, 1]";
  expect_accepted<float>(scene_text(inside));
  inside.lamp = "[5e151, 1, 1]";
  expect_accepted<double>(scene_text(inside));
  // Every colour is radiance-like: an albedo and a background too.
  expect_refused<float>(
      test::replaced(scene_text(Parts{}), R"("objects": [)", R"("background": {"type": "constant", "color": [0, 0, 1e18]}, "objects": [)"), "1e18",
      "/background/color/2", {"1e+18 " + kFloatColours});
}

TEST(UnrepresentableValues, CameraBeyondFloatAndDouble) {
  Parts far;
  far.look_from = "[0, 0, 1e308]";
  expect_refused<float>(scene_text(far), "1e308", "/camera/look_from/2", {"1e+308 " + kFloatLengths});
  expect_refused<double>(scene_text(far), "1e308", "/camera/look_from/2",
                         {"1e+308 is beyond double's supported range for lengths and coordinates (|x| <= 5.24e+151; see docs/scene-format.md)"});
  Parts inside;
  inside.look_from = "[0, 0, 7e16]";
  expect_accepted<float>(scene_text(inside));
  inside.look_from = "[0, 0, 5e151]";
  expect_accepted<double>(scene_text(inside));
}

// Values that fit the format but whose effect vanishes in it: a field of view so narrow that neighbouring pixels
// see the same ray, a checker or noise cell below the spacing of the scene's coordinates, a repeat that leaves the
// texture coordinates too coarse for the image's texels. Each rendered one flat colour, accepted without a word.
TEST(UnrepresentableValues, ValuesWhoseEffectVanishesInTheFormat) {
  const std::string base = scene_text(Parts{});
  const std::string narrow = test::replaced(base, R"("vertical_fov": 40)", R"("vertical_fov": 1e-300)");
  expect_refused<float>(narrow, "1e-300", "/camera/vertical_fov", {"1e-300 degrees makes a pixel", "below float's spacing", "the same ray"});
  expect_refused<double>(narrow, "1e-300", "/camera/vertical_fov", {"below double's spacing"});
  // A thousandth of a degree still resolves each pixel in float at this distance; a millionth only in double.
  expect_accepted<float>(test::replaced(base, R"("vertical_fov": 40)", R"("vertical_fov": 1e-3)"));
  const std::string millionth = test::replaced(base, R"("vertical_fov": 40)", R"("vertical_fov": 1e-6)");
  expect_refused<float>(millionth, "1e-6", "/camera/vertical_fov", {"below float's spacing"});
  expect_accepted<double>(millionth);

  const auto textured = [&](const std::string& texture) {
    return test::replaced(base, R"("white": {"type": "lambertian", "albedo": [0.8, 0.8, 0.8]})",
                          R"("white": {"type": "lambertian", "texture": )" + texture + "}");
  };
  const std::string checker = textured(R"({"type": "checker", "odd": [0.2, 0.2, 0.2], "even": [0.9, 0.9, 0.9], "frequency": 1e30})");
  expect_refused<float>(checker, "1e30", "/materials/white/texture/frequency", {"1e+30 makes checker cells of", "the pattern vanishes"});
  expect_refused<double>(checker, "1e30", "/materials/white/texture/frequency", {"below double's spacing"});
  expect_accepted<float>(textured(R"({"type": "checker", "odd": [0.2, 0.2, 0.2], "even": [0.9, 0.9, 0.9], "frequency": 1e4})"));
  const std::string noise = textured(R"({"type": "noise", "scale": 1e12})");
  expect_refused<float>(noise, "1e12", "/materials/white/texture/scale", {"makes noise cells of"});
  expect_accepted<double>(noise);
  const std::string image = textured(R"({"type": "image", "file": "textures/planet-1024x512.png", "repeat": 1e30})");
  expect_refused<float>(image, "1e30", "/materials/white/texture/repeat", {"too coarse to tell the image's 1024x512 texels apart"});
  expect_refused<double>(image, "1e30", "/materials/white/texture/repeat", {"double's texture coordinates"});
  expect_accepted<float>(textured(R"({"type": "image", "file": "textures/planet-1024x512.png", "repeat": 1000})"));
}

TEST(UnrepresentableValues, TriangleEdgeBeyondFloat) {
  // A triangle's normal squares the squared length of cross(edge1, edge2): its edges have a range of their own.
  expect_refused<float>(
      with_value_object(R"({"type": "triangle", "vertices": [[0, 0, 0], [2e9, 0, 0], [0, 1, 0]], "material": "white"})"), "[2e9, 0, 0]",
      "/objects/1/vertices/1",
      {"2e+09 (the edge from vertex 0) is beyond float's supported range for triangle edges (|x| <= 1.07e+09; see docs/scene-format.md)"});
  expect_accepted<float>(with_value_object(R"({"type": "triangle", "vertices": [[0, 0, 0], [1e9, 0, 0], [0, 1, 0]], "material": "white"})"));
  expect_accepted<double>(with_value_object(R"({"type": "triangle", "vertices": [[0, 0, 0], [2e9, 0, 0], [0, 1, 0]], "material": "white"})"));
}

TEST(UnrepresentableValues, MediumWithTinyDensity) {
  // 1 / density is the mean free path, a length.
  const std::string medium = R"({"type": "medium", "boundary": {"type": "sphere", "center": [2, 0, 0], "radius": 0.5}, "density": DENSITY, )"
                             R"("material": {"type": "isotropic", "albedo": [1, 1, 1]}})";
  expect_refused<float>(with_value_object(test::replaced(medium, "DENSITY", "1e-30")), "1e-30", "/objects/1/density",
                        {"1e+30 (1 / density, the mean free path) " + kFloatLengths});
  expect_accepted<float>(with_value_object(test::replaced(medium, "DENSITY", "1.5e-17")));
  expect_accepted<double>(with_value_object(test::replaced(medium, "DENSITY", "1e-30")));
}

TEST(UnrepresentableValues, FixedPointValueOutOfRange) {
  // Q16.16 holds up to 32768; colours are not scaled.
  Parts bright;
  bright.lamp = "[1, 1, 1e5]";
  expect_refused<Fixed<16, 16>>(scene_text(bright), "1e5", "/materials/lamp/emission/2",
                                {"100000 does not fit q16.16 (|x| <= 32768; see docs/numerics.md)"});
  bright.lamp = "[1, 1, 30000]";
  expect_accepted<Fixed<16, 16>>(scene_text(bright));
  // A 0.01-unit quad beside a 1000-unit sphere: Q10.10 scales the scene by 1/32 (its intersection tests need
  // coordinates within an eighth of 512). The quad fits: it stores its dual edges times a power of two near its edge
  // length (they were 1 / length, 3200 after scaling). Q32.32, which still squares distances, scales by 1/128.
  const std::string mixed = test::replaced(with_value_object(R"({"type": "sphere", "center": [0, -1000, 0], "radius": 1000, "material": "white"})"),
                                           R"("material": "white"}
  ])",
                                           R"("material": "white"},
    {"type": "quad", "corner": [0, 0, 0], "u": [0.01, 0, 0], "v": [0, 0.01, 0], "material": "white"}
  ])");
  expect_accepted<Fixed<10, 10>>(mixed);
  expect_accepted<Fixed<32, 32>>(mixed);
  // A per-length value still grows as the scene shrinks: the checker's 19.1 cells per unit (frequency 60 / pi)
  // become 611 after scaling by 1/32, beyond Q10.10.
  const std::string checkered = test::replaced(
      mixed, R"("radius": 1000, "material": "white")",
      R"("radius": 1000, "material": {"type": "lambertian", "texture": {"type": "checker", "odd": [0.2, 0.3, 0.1], "even": [0.9, 0.9, 0.9], "frequency": 60}})");
  expect_refused<Fixed<10, 10>>(checkered, "60}", "/objects/1/material/texture/frequency",
                                {"19.0986 (cells per unit length, frequency / pi), 611.155 after scaling lengths by 0.03125, does not fit q10.10"});
  expect_accepted<Fixed<16, 16>>(checkered);
}

// ---- through the command line ----

TEST(UnrepresentableValues, CommandLineRefusesWithOneLineAndNoImage) {
  test::TempDir dir;
  const std::filesystem::path scene = dir / "scene.json";
  const std::string text = with_value_object(R"({"type": "sphere", "center": [2, 0, 0], "radius": 1e30, "material": "white"})");
  test::write_text_file(scene, text);
  const std::string render = "render " + test::quoted(scene) + " -q -o " + test::quoted(dir / "out.png");
  const test::CommandResult result = test::run_pathtracer(render, dir);
  EXPECT_EQ(result.exit_code, 1);
  const std::vector<std::string> lines = test::lines_of(result.err);
  ASSERT_EQ(lines.size(), 1u) << result.err;
  const std::string place = place_of(text, "1e30").substr(kValuesSource.size());
  EXPECT_EQ(lines[0], "pathtracer: error: " + scene.string() + place + "/objects/1/radius: 1e+30 " + kFloatLengths);
  EXPECT_EQ(dir.entries(), std::vector<std::string>({"scene.json"})) << "no image may be written";
  // The same scene in double renders.
  const test::CommandResult in_double = test::run_pathtracer(render + " --number-format double", dir);
  EXPECT_EQ(in_double.exit_code, 0) << in_double.err;
  EXPECT_TRUE(std::filesystem::is_regular_file(dir / "out.png"));
}

}  // namespace
}  // namespace pt
