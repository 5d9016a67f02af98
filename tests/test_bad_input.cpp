// Checks that bad input gets one clear error naming file, JSON path and line:column, and that then no image is written.
//
// Scene texts go through the parser; a few cases also through the command-line program.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <functional>
#include <future>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "base/mapped_file.hpp"
#include "image/image_io.hpp"
#include "kernel/fixed_point.hpp"
#include "scene/json_positions.hpp"
#include "test_support.hpp"

namespace pt {
namespace {

const std::string kSource = "bad-scene.json";

// A valid scene with a second object (index 1, on line 8) that each case replaces.
const std::string kBase = R"({
  "render": {"width": 8, "height": 6, "samples_per_pixel": 1, "max_depth": 4},
  "camera": {"look_from": [0, 0, 3], "look_at": [0, 0, 0], "vertical_fov": 40},
  "textures": {"grid": {"type": "uv_checker", "odd": [0, 0, 0], "even": [1, 1, 1]}},
  "materials": {"white": {"type": "lambertian", "albedo": [0.8, 0.8, 0.8]}},
  "objects": [
    {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "white"},
    OBJECT
  ]
}
)";
const std::string kValidObject = R"({"type": "quad", "corner": [-2, -2, -1], "u": [4, 0, 0], "v": [0, 4, 0], "material": "white"})";

std::string with_object(const std::string& object) { return test::replaced(kBase, "OBJECT", object); }
std::string with(const std::string& from, const std::string& to) { return test::replaced(with_object(kValidObject), from, to); }
// The base scene with an environment background of these keys (besides its type).
std::string environment(const std::string& keys) {
  return with(R"("objects": [)", R"("background": {"type": "environment", )" + keys + R"(}, "objects": [)");
}

// The message of the InputError that parsing `text` throws (a failure, and "", where it is accepted).
std::string parse_error(const std::string& text) {
  try {
    test::parse(text, kSource);
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "accepted";
  return "";
}

struct BadScene {
  std::string name;
  std::string text;
  std::string pointer;      // the JSON path the message names; "" for syntax errors
  std::string message;      // a part of the message
  std::string at;           // a unique part of the text; '^' marks where line:column must point (else its first character)
  std::string absent = "";  // a text the message must not contain
};

// How gtest names a case in messages and in CTest's test list.
void PrintTo(const BadScene& c, std::ostream* out) { *out << c.name; }

std::vector<BadScene> bad_scenes() {
  const std::string sphere = R"({"type": "sphere", "center": [2, 0, 0], )";
  const std::string medium = R"({"type": "medium", "boundary": {"type": "sphere", "center": [2, 0, 0], "radius": 0.5}, )";
  return {
      // Syntax: nlohmann's message with the position of the offending character.
      {"TrailingComma", with_object(sphere + R"("radius": 1, "material": "white",})"), "", "invalid JSON", R"("white",^})"},
      {"NaNLiteral", with_object(sphere + R"("radius": NaN, "material": "white"})"), "", "invalid JSON", "^NaN"},
      {"InfinityLiteral", with_object(sphere + R"("radius": Infinity, "material": "white"})"), "", "invalid JSON", "^Infinity"},
      {"SingleQuotes", with_object(R"({"type": 'sphere', "center": [2, 0, 0], "radius": 1, "material": "white"})"), "", "invalid JSON", "^'sphere'"},
      {"Comment", with("\"objects\": [", "\"objects\": [ // the objects\n"), "", "invalid JSON", "^// the"},
      {"Truncated", kBase.substr(0, kBase.find("\"camera\"") + 12), "", "invalid JSON", "\"camera\": {\"^"},
      // Mesh objects: the model file, its transform and material.
      {"MissingModelFile", with_object(R"({"type": "mesh", "file": "models/missing.ply"})"), "/objects/1/file",
       "missing.ply: cannot open the PLY file", R"("file": ^"models/missing.ply")"},
      {"MissingNormalMap",
       with_object(
           R"({"type": "quad", "corner": [-2, -2, -1], "u": [4, 0, 0], "v": [0, 4, 0], "material": {"type": "metallic_roughness", "base_color": [0.5, 0.5, 0.5], "normal_map": "textures/absent-normals.png"}})"),
       "/objects/1/material/normal_map", "absent-normals.png' does not exist", R"("normal_map": ^"textures/absent-normals.png")"},
      {"NormalMapThatIsNotAnImage",
       with_object(
           R"({"type": "quad", "corner": [-2, -2, -1], "u": [4, 0, 0], "v": [0, 4, 0], "material": {"type": "metallic_roughness", "base_color": [0.5, 0.5, 0.5], "normal_map": "models/knot.ply"}})"),
       "/objects/1/material/normal_map", "cannot read image file", R"("normal_map": ^"models/knot.ply")"},
      {"NormalScaleWithoutNormalMap",
       with_object(
           R"({"type": "quad", "corner": [-2, -2, -1], "u": [4, 0, 0], "v": [0, 4, 0], "material": {"type": "metallic_roughness", "base_color": [0.5, 0.5, 0.5], "normal_scale": 2}})"),
       "/objects/1/material/normal_scale", "'normal_scale' needs a 'normal_map'", R"("normal_scale": ^2)"},
      {"ModelFileOfUnknownType", with_object(R"({"type": "mesh", "file": "textures/planet-1024x512.png"})"), "/objects/1/file",
       "unknown model file type '.png'", R"("file": ^"textures/planet)"},
      {"MeshScaledByZero", with_object(R"({"type": "mesh", "file": "models/knot.ply", "transform": {"scale": [1, 0, 1]}})"),
       "/objects/1/transform/scale", "a scale factor must not be zero", R"("scale": ^[1, 0, 1])"},
      {"MeshTransformKeyMisspelt", with_object(R"({"type": "mesh", "file": "models/knot.ply", "transform": {"scael": 2}})"),
       "/objects/1/transform/scael", "did you mean 'scale'?", R"("scael": ^2)"},
      {"MeshWithIsotropicMaterial",
       with_object(R"({"type": "mesh", "file": "models/knot.ply", "material": {"type": "isotropic", "albedo": [0.5, 0.5, 0.5]}})"),
       "/objects/1/material", "an isotropic material only belongs to a medium", R"("material": ^{"type": "isotropic")"},
      // Unknown and misspelt keys.
      {"MisspeltObjectKey", with_object(sphere + R"("radus": 1, "material": "white"})"), "/objects/1/radus",
       "unknown key 'radus' (did you mean 'radius'?)", R"("radus": ^1)"},
      {"MisspeltTopLevelKey", with("\"materials\":", "\"materails\":"), "/materails", "unknown key 'materails' (did you mean 'materials'?)",
       R"("materails": ^{)"},
      {"MisspeltRenderKey", with("\"samples_per_pixel\"", "\"sample_per_pixel\""), "/render/sample_per_pixel", "did you mean 'samples_per_pixel'?",
       R"("sample_per_pixel": ^1)"},
      {"MisspeltCameraKey", with("\"look_from\"", "\"look_form\""), "/camera/look_form", "did you mean 'look_from'?", R"("look_form": ^[)"},
      {"MisspeltMaterialKey", with("\"albedo\": [0.8", "\"albdo\": [0.8"), "/materials/white/albdo", "did you mean 'albedo'?", R"("albdo": ^[0.8)"},
      {"UnknownKeyWithoutSuggestion", with_object(sphere + R"("radius": 1, "temperature": 5, "material": "white"})"), "/objects/1/temperature",
       "unknown key 'temperature'", R"("temperature": ^5)", "did you mean"},
      // Wrong types.
      {"RadiusIsAString", with_object(sphere + R"("radius": "1", "material": "white"})"), "/objects/1/radius", "expected a number, found a string",
       R"("radius": ^"1")"},
      {"RadiusIsABoolean", with_object(sphere + R"("radius": true, "material": "white"})"), "/objects/1/radius", "expected a number, found a boolean",
       R"("radius": ^true)"},
      {"CentreHasTwoComponents", with_object(R"({"type": "sphere", "center": [2, 0], "radius": 1, "material": "white"})"), "/objects/1/center",
       "expected 3 elements, found 2", R"("center": ^[2, 0])"},
      {"ColourComponentIsAString", with_object(sphere + R"("radius": 1, "material": {"type": "lambertian", "albedo": [0.5, "x", 0.5]}})"),
       "/objects/1/material/albedo/1", "expected a number, found a string", R"(^"x")"},
      {"WidthIsFractional", with("\"width\": 8", "\"width\": 8.5"), "/render/width", "expected an integer, found a fractional number", "^8.5"},
      // An integer too large for 64 bits reaches the reader as a double: it is out of range, not fractional.
      {"IntegerBeyond64BitsIsOutOfRange", with("\"width\": 8", "\"width\": 18446744073709551616"), "/render/width",
       "18446744073709551616 is outside the allowed range [1, 16384]", "^18446744073709551616", "fractional"},
      {"NumberOverflowIsLocated", with_object(sphere + R"("radius": 1e999, "material": "white"})"), "/objects/1/radius",
       "the number 1e999 is beyond the range of a double", "^1e999"},
      {"NegativeNumberOverflowIsLocated", with("\"vertical_fov\": 40", "\"vertical_fov\": -1e999"), "/camera/vertical_fov",
       "the number -1e999 is beyond the range of a double", "^-1e999"},
      {"ObjectsIsAnObject", R"({"camera": {"look_from": [0, 0, 3], "look_at": [0, 0, 0], "vertical_fov": 40},
 "objects": {}})",
       "/objects", "expected an array, found an object", R"("objects": ^{})"},
      {"TopLevelIsAnArray", "[1, 2]", "(top level)", "expected an object, found an array", "^[1, 2]"},
      {"MaterialIsANumber", with_object(sphere + R"("radius": 1, "material": 3})"), "/objects/1/material",
       "expected a material name or a material object, found a number", R"("material": ^3)"},
      // Missing required fields.
      {"MissingCamera",
       test::replaced(with_object(kValidObject), R"(  "camera": {"look_from": [0, 0, 3], "look_at": [0, 0, 0], "vertical_fov": 40},
)",
                      ""),
       "(top level)", "missing required key 'camera'", "^{\n  \"render\""},
      {"MissingRadius", with_object(R"({"type": "sphere", "center": [2, 0, 0], "material": "white"})"), "/objects/1", "missing required key 'radius'",
       R"(^{"type": "sphere", "center": [2, 0, 0], "material")"},
      {"MissingObjectType", with_object(R"({"center": [2, 0, 0], "radius": 1, "material": "white"})"), "/objects/1", "missing required key 'type'",
       R"(^{"center": [2)"},
      {"MissingMaterial", with_object(sphere + R"("radius": 1})"), "/objects/1", "missing required key 'material'",
       R"(^{"type": "sphere", "center": [2)"},
      {"MissingFieldOfView", with(R"(, "vertical_fov": 40)", ""), "/camera", "missing required key 'vertical_fov'", R"("camera": ^{)"},
      {"NoObjects",
       test::replaced(test::replaced(kBase, "    OBJECT\n", ""), R"(    {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "white"},
)",
                      ""),
       "/objects", "expected between 1 and", R"("objects": ^[)"},
      // Out-of-range and meaningless values.
      {"NegativeRadius", with_object(sphere + R"("radius": -1, "material": "white"})"), "/objects/1/radius", "must be positive, found -1", "^-1,"},
      {"ZeroRadius", with_object(sphere + R"("radius": 0, "material": "white"})"), "/objects/1/radius", "must be positive, found 0",
       R"("radius": ^0)"},
      {"ZeroWidth", with("\"width\": 8", "\"width\": 0"), "/render/width", "0 is outside the allowed range [1, 16384]", R"("width": ^0)"},
      {"WidthAboveLimit", with("\"width\": 8", "\"width\": 100000"), "/render/width", "100000 is outside the allowed range", "^100000"},
      {"TooManyPixels", with(R"("width": 8, "height": 6)", R"("width": 16384, "height": 16384)"), "/render", "16384x16384 pixels is too large",
       R"("render": ^{)"},
      {"ZeroSamples", with("\"samples_per_pixel\": 1", "\"samples_per_pixel\": 0"), "/render/samples_per_pixel", "outside the allowed range",
       R"("samples_per_pixel": ^0)"},
      {"UnknownSampler", with("\"max_depth\": 4", "\"max_depth\": 4, \"sampler\": \"halton\""), "/render/sampler",
       "'halton' is not a sampler: sobol or independent", R"(^"halton")"},
      {"DepthAboveLimit", with("\"max_depth\": 4", "\"max_depth\": 10001"), "/render/max_depth", "10001 is outside the allowed range", "^10001"},
      {"NegativeSeed", with("\"max_depth\": 4", "\"max_depth\": 4, \"seed\": -3"), "/render/seed", "must not be negative, found -3", "^-3"},
      {"RetiredTmin", with("\"max_depth\": 4", "\"max_depth\": 4, \"t_min\": 0.001"), "/render/t_min", "t_min is no longer a setting", "^0.001"},
      {"NegativeDensity", with_object(medium + R"("density": -1, "material": {"type": "isotropic", "albedo": [1, 1, 1]}})"), "/objects/1/density",
       "must be positive, found -1", R"("density": ^-1)"},
      {"NegativeColourComponent", with_object(sphere + R"("radius": 1, "material": {"type": "lambertian", "albedo": [-0.5, 0.5, 0.5]}})"),
       "/objects/1/material/albedo", "colour components must not be negative", "^[-0.5"},
      {"FieldOfView180", with("\"vertical_fov\": 40", "\"vertical_fov\": 180"), "/camera/vertical_fov", "strictly between 0 and 180", "^180"},
      {"FuzzAboveOne", with_object(sphere + R"("radius": 1, "material": {"type": "metal", "albedo": [1, 1, 1], "fuzz": 1.5}})"),
       "/objects/1/material/fuzz", "outside the allowed range [0, 1]", "^1.5"},
      {"MetallicAboveOne",
       with_object(sphere + R"("radius": 1, "material": {"type": "metallic_roughness", "base_color": [1, 1, 1], "metallic": 2}})"),
       "/objects/1/material/metallic", "outside the allowed range [0, 1]", R"("metallic": ^2)"},
      {"MetallicRoughnessMapNotAnImage",
       with_object(sphere +
                   R"("radius": 1, "material": {"type": "metallic_roughness", "base_color": [1, 1, 1], "metallic_roughness_texture": "grid"}})"),
       "/objects/1/material/metallic_roughness_texture", "a metallic-roughness texture must be an image", R"("metallic_roughness_texture": ^"grid")"},
      {"ZeroIndexOfRefraction", with_object(sphere + R"("radius": 1, "material": {"type": "dielectric", "ior": 0}})"), "/objects/1/material/ior",
       "must be positive", R"("ior": ^0)"},
      {"DegenerateTriangle", with_object(R"({"type": "triangle", "vertices": [[0, 0, 0], [1, 1, 1], [2, 2, 2]], "material": "white"})"),
       "/objects/1/vertices", "degenerate", R"("vertices": ^[[)"},
      {"ParallelQuadEdges", with_object(R"({"type": "quad", "corner": [0, 0, 0], "u": [1, 0, 0], "v": [2, 0, 0], "material": "white"})"),
       "/objects/1/v", "parallel or zero", R"("v": ^[2, 0, 0])"},
      {"InvertedBox", with_object(R"({"type": "box", "min": [0, 0, 0], "max": [1, -1, 1], "material": "white"})"), "/objects/1/max",
       "every component of max must exceed min", R"("max": ^[1, -1, 1])"},
      {"LookAtEqualsLookFrom", with(R"("look_at": [0, 0, 0])", R"("look_at": [0, 0, 3])"), "/camera/look_at", "must differ",
       R"("look_at": ^[0, 0, 3])"},
      {"UpParallelToView", with(R"("vertical_fov": 40)", R"("vertical_fov": 40, "up": [0, 0, -2])"), "/camera", "parallel to the view direction",
       R"("camera": ^{)"},
      {"ShutterClosesBeforeOpening", with(R"("vertical_fov": 40)", R"("vertical_fov": 40, "shutter": [1, 0.5])"), "/camera/shutter",
       "closes before it opens", "^[1, 0.5]"},
      {"MovingSphereTimesReversed",
       with_object(
           R"({"type": "moving_sphere", "center0": [2, 0, 0], "center1": [2, 1, 0], "radius": 1, "time0": 1, "time1": 0, "material": "white"})"),
       "/objects/1/time1", "time1 must be later than time0", R"("time1": ^0)"},
      // References to things that do not exist, and misplaced materials.
      {"UnknownMaterialName", with_object(sphere + R"("radius": 1, "material": "glas"})"), "/objects/1/material", "unknown material 'glas'",
       R"(^"glas")"},
      {"UnknownTextureName", with_object(sphere + R"("radius": 1, "material": {"type": "lambertian", "texture": "gird"}})"),
       "/objects/1/material/texture", "unknown texture 'gird'", R"(^"gird")"},
      {"MediumWithSurfaceMaterial", with_object(medium + R"("density": 1, "material": "white"})"), "/objects/1/material",
       "a medium's material must be isotropic", R"("density": 1, "material": ^"white")"},
      {"IsotropicOnASurface", with_object(sphere + R"("radius": 1, "material": {"type": "isotropic", "albedo": [1, 1, 1]}})"), "/objects/1/material",
       "an isotropic material only belongs to a medium", R"(^{"type": "isotropic")"},
      {"UnknownObjectType", with_object(R"({"type": "cube", "material": "white"})"), "/objects/1/type", "unknown object type 'cube'", R"(^"cube")"},
      {"UnknownMaterialType", with_object(sphere + R"("radius": 1, "material": {"type": "glass"}})"), "/objects/1/material/type",
       "unknown material type 'glass'", R"(^"glass")"},
      {"UnknownTextureType", with(R"("type": "uv_checker")", R"("type": "stripes")"), "/textures/grid/type", "unknown texture type 'stripes'",
       R"(^"stripes")"},
      {"UnknownBackgroundType", with(R"("objects": [)", R"("background": {"type": "gradient"}, "objects": [)"), "/background/type",
       "unknown background type 'gradient'", R"(^"gradient")"},
      {"AlbedoAndTextureTogether",
       with_object(sphere + R"("radius": 1, "material": {"type": "lambertian", "albedo": [1, 1, 1], "texture": "grid"}})"), "/objects/1/material",
       "give either 'albedo' or 'texture', not both", R"(^{"type": "lambertian", "albedo": [1, 1, 1])"},
      {"MediumBoundaryCylinder",
       with_object(R"({"type": "medium", "boundary": {"type": "cylinder"}, "density": 1, "material": {"type": "isotropic", "albedo": [1, 1, 1]}})"),
       "/objects/1/boundary/type", "must be a sphere or a box, not 'cylinder'", R"(^"cylinder")"},
      {"UnknownNoiseKind",
       with(R"("grid": {"type": "uv_checker", "odd": [0, 0, 0], "even": [1, 1, 1]})", R"("grid": {"type": "noise", "kind": "simplex"})"),
       "/textures/grid/kind", "unknown noise kind 'simplex'", R"(^"simplex")"},
      // Image files (relative to the scene's folder, here scenes/).
      {"MissingImageFile",
       with(R"("grid": {"type": "uv_checker", "odd": [0, 0, 0], "even": [1, 1, 1]})",
            R"("grid": {"type": "image", "file": "textures/no-such-image.png"})"),
       "/textures/grid/file", "no-such-image.png' does not exist", R"(^"textures/no-such)"},
      {"ImageFileIsAFolder",
       with(R"("grid": {"type": "uv_checker", "odd": [0, 0, 0], "even": [1, 1, 1]})", R"("grid": {"type": "image", "file": "textures"})"),
       "/textures/grid/file", "cannot read image file", R"("file": ^"textures")"},
      {"EmptyImageFileName",
       with(R"("grid": {"type": "uv_checker", "odd": [0, 0, 0], "even": [1, 1, 1]})", R"("grid": {"type": "image", "file": ""})"),
       "/textures/grid/file", "the image file name is empty", R"("file": ^"")"},
      // Environment images (background); bad texels and files that are not images are tested below with files of their own.
      {"MissingEnvironmentImage", environment(R"("file": "textures/no-such-sky.exr")"), "/background/file", "no-such-sky.exr' does not exist",
       R"(^"textures/no-such-sky)"},
      {"EnvironmentImageIsAFolder", environment(R"("file": "textures")"), "/background/file", "cannot read image file", R"("file": ^"textures")"},
      {"EnvironmentImageUnreadable", environment(R"("file": "README.md")"), "/background/file", "cannot read image file", R"(^"README.md")"},
      {"EnvironmentWithoutFile", environment(R"("strength": 2)"), "/background", "missing required key 'file'", R"(^{"type": "environment")"},
      {"EnvironmentFileNotAString", environment(R"("file": ["sky.exr"])"), "/background/file", "expected a string, found an array",
       R"(^["sky.exr"])"},
      {"EnvironmentEmptyFileName", environment(R"("file": "")"), "/background/file", "the image file name is empty", R"("file": ^"")"},
      {"EnvironmentNegativeStrength", environment(R"("file": "textures/sky-256x128.exr", "strength": -1)"), "/background/strength",
       "-1 is outside the allowed range", R"("strength": ^-1)"},
      {"EnvironmentStrengthNotANumber", environment(R"("file": "textures/sky-256x128.exr", "strength": "bright")"), "/background/strength",
       "expected a number, found a string", R"(^"bright")"},
      {"EnvironmentRotateNotAnAngle", environment(R"("file": "textures/sky-256x128.exr", "rotate": "left")"), "/background/rotate",
       "expected an array", R"(^"left")"},
      {"EnvironmentRotateTwoAngles", environment(R"("file": "textures/sky-256x128.exr", "rotate": [0, 90])"), "/background/rotate",
       "expected 3 elements", R"(^[0, 90])"},
      {"EnvironmentMisspelledKey", environment(R"("file": "textures/sky-256x128.exr", "strenght": 2)"), "/background/strenght",
       "did you mean 'strength'", R"("strenght": ^2)"},
  };
}

TextPosition position_of(const std::string& text, const std::string& marker) {
  std::string plain = marker;
  const std::size_t caret = plain.find('^');
  if (caret != std::string::npos) plain.erase(caret, 1);
  const std::size_t found = text.find(plain);
  if (found == std::string::npos || text.find(plain, found + 1) != std::string::npos)
    throw std::logic_error("marker '" + marker + "' is not unique in the scene text");
  return JsonPositions::position_of_offset(text, found + (caret == std::string::npos ? 0 : caret));
}

class BadSceneIsRejected : public ::testing::TestWithParam<BadScene> {};

TEST_P(BadSceneIsRejected, WithFileLineColumnPathAndReason) {
  const BadScene& c = GetParam();
  const TextPosition at = position_of(c.text, c.at);
  const std::string prefix = kSource + ":" + std::to_string(at.line) + ":" + std::to_string(at.column) + ": ";
  const std::string place = c.pointer.empty() ? "" : c.pointer + ": ";
  try {
    test::parse(c.text, kSource);
    FAIL() << "accepted:\n" << c.text;
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind(prefix + place, 0), 0u) << message << "\nexpected it to start with: " << prefix + place;
    EXPECT_NE(message.find(c.message), std::string::npos) << message;
    if (!c.absent.empty()) {
      EXPECT_EQ(message.find(c.absent), std::string::npos) << message;
    }
    EXPECT_EQ(message.find('\n'), std::string::npos) << "one line: " << message;
  }
}

INSTANTIATE_TEST_SUITE_P(Cases, BadSceneIsRejected, ::testing::ValuesIn(bad_scenes()),
                         [](const ::testing::TestParamInfo<BadScene>& info) { return info.param.name; });

TEST(BadSceneIsRejectedGuard, BaseSceneIsValid) {
  // Every case above is the valid base scene with one thing broken.
  const SceneDescription scene = test::parse(with_object(kValidObject), kSource);
  EXPECT_EQ(scene.objects.size(), 2u);
  EXPECT_EQ(scene.render.width, 8u);
}

TEST(BadSceneIsRejectedGuard, PositionsAreExactInAHandCountedCase) {
  // Line 8 is the second object; "radius" of -1 is its value at column 55 (counted by hand).
  const std::string text = with_object(R"({"type": "sphere", "center": [2, 0, 0], "radius": -1, "material": "white"})");
  ASSERT_EQ(test::lines_of(text)[7].substr(54, 2), "-1");
  try {
    test::parse(text, "hand.json");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "hand.json:8:55: /objects/1/radius: must be positive, found -1");
  }
}

TEST(LargeSceneFile, IsReadThroughAMappingWithTheSameObjectsAndErrorPlaces) {
  // Files of 16 MB and more are mapped, not read whole (base/mapped_file.hpp), and their passed pages let go as the
  // outline and the objects are read: objects and error places must be those of the text read whole. 2,000 copies
  // of the valid object with spaces between them, then the hand-counted bad one: the file is about 18 MB.
  const test::TempDir dir;
  std::string objects;
  const std::string spaces(9 << 10, ' ');
  for (int i = 0; i < 2000; ++i) objects += kValidObject + ",\n" + spaces;
  const std::string good = test::replaced(with_object(kValidObject), "    {\"type\": \"sphere\"", objects + "    {\"type\": \"sphere\"");
  const std::string bad = test::replaced(with_object(R"({"type": "sphere", "center": [2, 0, 0], "radius": -1, "material": "white"})"),
                                         "    {\"type\": \"sphere\"", objects + "    {\"type\": \"sphere\"");
  ASSERT_GT(bad.size(), std::size_t{17} << 20);
  test::write_text_file(dir / "good.json", good);
  test::write_text_file(dir / "bad.json", bad);
  const SceneDescription mapped = load_scene_file(dir / "good.json");
  const SceneDescription read = test::parse(good, "good.json");
  ASSERT_EQ(mapped.objects.size(), 2002u);
  ASSERT_EQ(mapped.objects.size(), read.objects.size());
  for (std::size_t i = 0; i < read.objects.size(); i += 97) EXPECT_EQ(mapped.objects[i].shape.index(), read.objects[i].shape.index()) << i;
  std::string from_text, from_file;
  try {
    test::parse(bad, (dir / "bad.json").string());
  } catch (const InputError& e) {
    from_text = e.what();
  }
  try {
    load_scene_file(dir / "bad.json");
  } catch (const InputError& e) {
    from_file = e.what();
  }
  EXPECT_NE(from_text.find(":2008:55: /objects/2001/radius: must be positive, found -1"), std::string::npos) << from_text;
  EXPECT_EQ(from_file, from_text);
}

TEST(LargeSceneFile, ShortenedWhileMappedEndsWithOneLineAndStatusOne) {
  // Pages of a mapping beyond a file's new end cannot be read (SIGBUS): the program must say which file and exit 1,
  // not crash. The file is cut to one page while mapped, and a page after it read.
  const test::TempDir dir;
  const std::filesystem::path path = dir / "shrinking.json";
  test::write_text_file(path, std::string(1 << 20, ' '));
  EXPECT_EXIT(
      {
        const int fd = ::open(path.c_str(), O_RDONLY);
        std::unique_ptr<MappedFile> mapped = MappedFile::map(fd, 1 << 20, path.string());
        if (!mapped || ::truncate(path.c_str(), 4096) != 0) std::_Exit(3);
        volatile char c = mapped->text()[1 << 19];
        (void)c;
        std::_Exit(0);
      },
      ::testing::ExitedWithCode(1), "shrinking.json: the file shrank while it was being read");
}

TEST(NumberOverflow, LiteralBeyondDoubleRangeIsAnInputErrorNamingFileLineColumnAndPath) {
  // JSON has no NaN or infinity; 1e999 overflows a double and must not become an infinite radius. The parser stops
  // at the number, so the message points at it like any other bad value.
  for (const char* literal : {"1e999", "-1e999"}) {
    const std::string text =
        with_object(std::string(R"({"type": "sphere", "center": [2, 0, 0], "radius": )") + literal + R"(, "material": "white"})");
    try {
      test::parse(text, kSource);
      FAIL() << "accepted " << literal;
    } catch (const InputError& e) {
      const std::string message = e.what();
      EXPECT_EQ(message.rfind(kSource + ":8:55: /objects/1/radius: ", 0), 0u) << message;
      EXPECT_NE(message.find(literal), std::string::npos) << message;
    } catch (const std::exception& e) {
      FAIL() << "not an InputError: " << e.what();
    }
  }
}

// A key containing '/' or '~' (legal in material and texture names) is escaped in the JSON path (RFC 6901), and
// the line:column lookup finds it.
TEST(JsonPointerEscaping, KeysWithSlashAreEscapedAndPositioned) {
  const std::string text = with(R"("white": {"type": "lambertian", "albedo": [0.8, 0.8, 0.8]})",
                                R"("white": {"type": "lambertian", "albedo": [0.8, 0.8, 0.8]}, "a/b": {"type": "dielectric", "ior": -1})");
  const std::string message = parse_error(text);
  const TextPosition at = position_of(text, R"("ior": ^-1)");
  EXPECT_EQ(message.rfind(kSource + ":" + std::to_string(at.line) + ":" + std::to_string(at.column) + ": /materials/a~1b/ior: ", 0), 0u) << message;
}

// The parser's cost is bounded by its input: nesting beyond the limit is refused where it starts, before anything
// is built for it (100,000 levels used to take over a minute and gigabytes).
TEST(ParserBounds, NestingBeyondTheLimitIsRefusedWithFileLineAndColumn) {
  const std::size_t depth = 2000;
  const std::string text = R"({"render": )" + std::string(depth, '[') + std::string(depth, ']') + "}";
  const std::string message = parse_error(text);
  // The top-level object and 255 arrays are the 256 levels allowed; the next '[' (column 12 + 255) is refused.
  EXPECT_EQ(message, kSource + ":1:267: invalid JSON: arrays and objects nested more than 256 deep");
}

TEST(ParserBounds, NestingAtTheLimitIsParsed) {
  // 256 levels in all: past the syntax check, to the reader, which finds an unknown key.
  const std::string text = R"({"render": )" + std::string(255, '[') + std::string(255, ']') + "}";
  const std::string message = parse_error(text);
  EXPECT_EQ(message, kSource + ":1:12: /render: expected an object, found an array");
}

TEST(ParserBounds, AnEntryWithTooManyValuesIsRefusedWhereTheLimitIsPassed) {
  // One object whose centre has 200,000 numbers: refused at the first value past the limit, with its path (the
  // object, its type and the array are three values, so number 99997 is the 100,001st).
  std::string numbers;
  for (int i = 0; i < 200000; ++i) numbers += i ? ", 0" : "0";
  const std::string text = with_object(R"({"type": "sphere", "center": [)" + numbers + R"(], "radius": 1, "material": "white"})");
  const std::string message = parse_error(text);
  EXPECT_EQ(message.rfind(kSource + ":8:", 0), 0u) << message.substr(0, 200);
  EXPECT_NE(message.find("/objects/1/center/99997: more than 100000 JSON values in one entry of a list"), std::string::npos)
      << message.substr(0, 200);
}

TEST(ParserBounds, ErrorsInLaterListEntriesAreLocatedAsBefore) {
  // Entries of the object, material and texture lists are read one at a time from their text; a key given twice
  // keeps its last value, and errors name the right line and column.
  const std::string text = with(R"("white": {"type": "lambertian", "albedo": [0.8, 0.8, 0.8]})",
                                R"("white": {"type": "metal", "albedo": [1, 1, 1]},
    "white": {"type": "lambertian", "albedo": [0.8, 0.8, 0.8], "fuzz": 1})");
  const std::string message = parse_error(text);
  const TextPosition at = position_of(text, R"("fuzz": ^1)");
  EXPECT_EQ(message, kSource + ":" + std::to_string(at.line) + ":" + std::to_string(at.column) + ": /materials/white/fuzz: unknown key 'fuzz'");
}

// A scene cannot forge output lines or terminal escapes: control characters it puts into a message are escaped.
TEST(MessagesAreOneLine, ControlCharactersFromTheSceneAreEscaped) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {with_object(R"({"type": "sphere", "center": [2, 0, 0], "radius": 1, "material": "white", "x\nwarning: forged": 1})"),
       R"(/objects/1/x\nwarning: forged: unknown key 'x\nwarning: forged')"},
      {with_object(R"({"type": "sphere", "center": [2, 0, 0], "radius": 1, "material": "\u001b[31mred\r\t\u007f"})"),
       R"(unknown material '\x1b[31mred\r\t\x7f')"},
      {with_object(R"({"type": "sphere", "center": [2, 0, 0], "radius": 1, "material": "a\u009bb"})"), R"(unknown material 'a\u009bb')"},
  };
  for (const auto& [text, expected] : cases) {
    const std::string message = parse_error(text);
    EXPECT_NE(message.find(expected), std::string::npos) << message;
    EXPECT_TRUE(std::none_of(message.begin(), message.end(), [](char c) { return static_cast<unsigned char>(c) < 0x20 || c == 0x7f; })) << message;
    EXPECT_EQ(message.find("\xc2\x9b"), std::string::npos) << message;
  }
}

// ---- files ----

// Runs `load` on another thread; should it block (on a FIFO), opens the FIFO's other end so that it returns, and
// fails the test. Returns the message of the InputError it threw.
std::string error_without_blocking(const std::filesystem::path& fifo, const std::function<void()>& load) {
  auto result = std::async(std::launch::async, [&]() -> std::string {
    try {
      load();
    } catch (const InputError& e) {
      return e.what();
    }
    return "(accepted)";
  });
  if (result.wait_for(std::chrono::seconds(10)) == std::future_status::timeout) {
    ADD_FAILURE() << "blocked on " << fifo;
    const int writer = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK);
    if (writer >= 0) ::close(writer);
  }
  return result.get();
}

TEST(SceneFileErrors, FifoGivenAsSceneFileIsRefusedWithoutBlocking) {
  test::TempDir dir;
  const std::filesystem::path fifo = dir / "scene.json";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_EQ(error_without_blocking(fifo, [&] { load_scene_file(fifo); }), fifo.string() + ": is a FIFO (named pipe), not a scene file");
}

TEST(SceneFileErrors, DeviceGivenAsSceneFileIsRefused) {
  // /dev/null would read as an empty text; it is refused for what it is, before any read. (/dev/zero, which never
  // ends, is tried through the program, under a memory limit: CommandLineErrors.EndlessDeviceAsSceneIsRefusedAtOnce.)
  try {
    load_scene_file("/dev/null");
    FAIL() << "accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "/dev/null: is a character device, not a scene file");
  }
}

TEST(SceneFileErrors, MissingSceneFileIsNamed) {
  test::TempDir dir;
  const std::filesystem::path missing = dir / "absent.json";
  try {
    load_scene_file(missing);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), missing.string() + ": cannot open the scene file");
  }
}

TEST(SceneFileErrors, FolderGivenAsSceneFileIsAnErrorNamingIt) {
  test::TempDir dir;
  std::filesystem::create_directory(dir / "folder.json");
  try {
    load_scene_file(dir / "folder.json");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), (dir / "folder.json").string() + ": is a folder, not a scene file");
  }
}

TEST(SceneFileErrors, ErrorsInAFileNameTheFilePath) {
  test::TempDir dir;
  const std::filesystem::path file = dir / "scene.json";
  test::write_text_file(file, with_object(R"({"type": "sphere", "center": [2, 0, 0], "radius": -1, "material": "white"})"));
  try {
    load_scene_file(file);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), file.string() + ":8:55: /objects/1/radius: must be positive, found -1");
  }
}

// A scene in `dir` whose texture is the image file `image` (relative to the scene).
std::filesystem::path scene_with_image(const test::TempDir& dir, const std::string& image) {
  const std::filesystem::path file = dir / "scene.json";
  test::write_text_file(file, with(R"("grid": {"type": "uv_checker", "odd": [0, 0, 0], "even": [1, 1, 1]})",
                                   R"("grid": {"type": "image", "file": ")" + image + R"("})"));
  return file;
}

TEST(SceneFileErrors, ImagePathsResolveAgainstTheSceneFolder) {
  // Positive control for the two tests below: a real image beside the scene loads.
  test::TempDir dir;
  std::filesystem::create_directory(dir / "maps");
  std::filesystem::copy_file(test::scene_path("textures/planet-1024x512.png"), dir / "maps" / "planet.png");
  const SceneDescription scene = load_scene_file(scene_with_image(dir, "maps/planet.png"));
  EXPECT_EQ(scene.texels.size(), 1024u * 512u * 3u);
}

TEST(SceneFileErrors, MissingImageIsNamed) {
  test::TempDir dir;
  const std::filesystem::path file = scene_with_image(dir, "maps/planet.png");
  try {
    load_scene_file(file);
    FAIL();
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind(file.string() + ":4:", 0), 0u) << message;
    EXPECT_NE(message.find("/textures/grid/file: image file '"), std::string::npos) << message;
    EXPECT_NE(message.find("planet.png' does not exist"), std::string::npos) << message;
  }
}

TEST(SceneFileErrors, FileThatIsNotAnImageIsRejected) {
  test::TempDir dir;
  test::write_text_file(dir / "fake.png", "this is not a PNG file\n");
  const std::filesystem::path file = scene_with_image(dir, "fake.png");
  try {
    load_scene_file(file);
    FAIL();
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind(file.string() + ":4:", 0), 0u) << message;
    EXPECT_NE(message.find("/textures/grid/file: cannot read image file '"), std::string::npos) << message;
  }
}

TEST(SceneFileErrors, FifoGivenAsImageIsRefusedWithoutBlocking) {
  test::TempDir dir;
  ASSERT_EQ(::mkfifo((dir / "pipe.png").c_str(), 0600), 0);
  const std::filesystem::path file = scene_with_image(dir, "pipe.png");
  const std::string message = error_without_blocking(dir / "pipe.png", [&] { load_scene_file(file); });
  EXPECT_EQ(message.rfind(file.string() + ":4:", 0), 0u) << message;
  EXPECT_NE(message.find("/textures/grid/file: cannot read image file '"), std::string::npos) << message;
  EXPECT_NE(message.find("pipe.png': it is a FIFO (named pipe), not a regular file"), std::string::npos) << message;
}

TEST(SceneFileErrors, DeviceGivenAsImageIsRefused) {
  test::TempDir dir;
  const std::filesystem::path file = scene_with_image(dir, "/dev/zero");
  try {
    load_scene_file(file);
    FAIL();
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind(file.string() + ":4:", 0), 0u) << message;
    EXPECT_NE(message.find("cannot read image file '/dev/zero': it is a character device, not a regular file"), std::string::npos) << message;
  }
}

// A PNG of only a header (signature and IHDR chunk; stb_image checks no CRC) claiming `width` x `height` RGB texels.
void write_png_header(const std::filesystem::path& path, u32 width, u32 height) {
  std::string bytes = "\x89PNG\r\n\x1a\n";
  const auto big_endian = [&](u32 v) {
    for (int shift = 24; shift >= 0; shift -= 8) bytes += static_cast<char>((v >> shift) & 0xff);
  };
  big_endian(13);
  bytes += "IHDR";
  big_endian(width);
  big_endian(height);
  bytes += std::string("\x08\x02\x00\x00\x00", 5);  // 8 bits, RGB, deflate, no filter variant, no interlace
  big_endian(0);                                    // CRC
  test::write_text_file(path, bytes);
}

TEST(SceneFileErrors, ImageSizeIsCheckedFromTheHeaderBeforeDecoding) {
  // 20000x20000 exceeds stb_image's own limit (once called an "unknown image type"); 16384x16384 passes it but
  // would decode to gigabytes; 9000x8000 is within each side but over the texel count.
  for (const auto& [width, height] : std::vector<std::pair<u32, u32>>{{20000, 20000}, {16384, 16384}, {16385, 1}, {9000, 8000}}) {
    test::TempDir dir;
    write_png_header(dir / "huge.png", width, height);
    const std::filesystem::path file = scene_with_image(dir, "huge.png");
    try {
      load_scene_file(file);
      FAIL() << width << "x" << height << " accepted";
    } catch (const InputError& e) {
      const std::string message = e.what();
      EXPECT_EQ(message.rfind(file.string() + ":4:", 0), 0u) << message;
      EXPECT_NE(message.find("huge.png' is " + std::to_string(width) + "x" + std::to_string(height) + " texels, larger than a texture may be"),
                std::string::npos)
          << message;
    }
  }
}

// Images too large together are refused from their headers before any is decoded: six 8192x8192 textures were
// refused only after five had been decoded (27 s, 2 GB). Here the images have headers and no data, so decoding
// any of them would fail with another message.
TEST(SceneFileErrors, ImagesTooLargeTogetherAreRefusedBeforeAnyIsDecoded) {
  test::TempDir dir;
  std::string textures, materials, objects;
  for (int i = 0; i < 6; ++i) {
    test::write_text_file(dir / fmt::format("big{}.ppm", i), "P6\n8192 8192\n255\n");
    textures += fmt::format("{}\"t{}\": {{\"type\": \"image\", \"file\": \"big{}.ppm\"}}", i ? ", " : "", i, i);
    materials += fmt::format("{}\"m{}\": {{\"type\": \"lambertian\", \"texture\": \"t{}\"}}", i ? ", " : "", i, i);
    objects += fmt::format("{}{{\"type\": \"sphere\", \"center\": [{}, 0, -3], \"radius\": 0.4, \"material\": \"m{}\"}}", i ? ", " : "", i, i);
  }
  const std::filesystem::path file = dir / "scene.json";
  test::write_text_file(file, "{\"camera\": {\"look_from\": [0, 0, 0], \"look_at\": [0, 0, -1], \"vertical_fov\": 40},\n\"textures\": {" + textures +
                                  "},\n\"materials\": {" + materials + "},\n\"objects\": [" + objects + "]}\n");
  try {
    load_scene_file(file);
    FAIL() << "accepted";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind(file.string() + ":2:", 0), 0u) << message;
    EXPECT_NE(message.find("/textures/t5/file: the scene's images are too large in total"), std::string::npos) << message;
  }
  // Five fit; decoding them is what finds that their data is missing, named by the place that gave the file.
  test::write_text_file(dir / "big5.ppm", "P6\n1 1\n255\nabc");
  try {
    load_scene_file(file);
    FAIL() << "accepted";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("/textures/t0/file: "), std::string::npos) << message;
    EXPECT_NE(message.find("big0.ppm"), std::string::npos) << message;
  }
}

// A value quoted in a message is cut to a few dozen characters, and no message is longer than about a thousand:
// an error about a 50 MB string printed all of it.
TEST(MessagesAreOneLine, LongValuesAreCut) {
  const std::string huge(1 << 20, 'x');
  const std::string scene = std::string("{\"camera\": {\"look_from\": [0, 0, 0], \"look_at\": [0, 0, -1], \"vertical_fov\": 40}, \"objects\": [") +
                            "{\"type\": \"" + huge + "\"}]}";
  try {
    parse_scene(scene, "s.json", ".");
    FAIL() << "accepted";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_LT(message.size(), 300u) << message.substr(0, 300);
    EXPECT_NE(message.find("unknown object type 'xxxxxxxxxx"), std::string::npos) << message.substr(0, 300);
  }
  const InputError long_one(std::string(5000, 'y'));
  const std::string message = long_one.what();
  EXPECT_LE(message.size(), kMaxErrorMessage + 40);
  EXPECT_NE(message.find("more characters)"), std::string::npos) << message;
}

TEST(SceneFileErrors, JpegHuffmanTableOfMoreThan256CodesIsRefused) {
  // A DHT segment whose 16 code counts add up to 512: stb_image 2.27 wrote the table's code lengths and values past
  // their arrays (found by fuzz/fuzz_texture_image). The file is refused before stb_image reads it.
  std::string bytes = "\xff\xd8\xff\xc4";
  const unsigned length = 2 + 17 + 512;
  bytes += static_cast<char>(length >> 8);
  bytes += static_cast<char>(length & 0xff);
  bytes += '\0';                 // DC table 0
  bytes += std::string(16, 32);  // 32 codes of each length from 1 to 16
  bytes += std::string(512, '\0');
  bytes += "\xff\xd9";
  test::TempDir dir;
  test::write_text_file(dir / "huffman.jpg", bytes);
  const std::filesystem::path file = scene_with_image(dir, "huffman.jpg");
  try {
    load_scene_file(file);
    FAIL();
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind(file.string() + ":4:", 0), 0u) << message;
    EXPECT_NE(message.find("huffman.jpg': corrupt JPEG (a Huffman table of more than 256 codes)"), std::string::npos) << message;
  }
}

// ---- environment images with bad content ----

// A scene in `dir` whose background is the environment image `image` (relative to the scene), with extra keys.
std::filesystem::path scene_with_environment(const test::TempDir& dir, const std::string& image, const std::string& keys = "") {
  const std::filesystem::path file = dir / "scene.json";
  test::write_text_file(file, environment(R"("file": ")" + image + "\"" + keys));
  return file;
}

// A 4x2 float EXR, every texel 0.5 but texel (3, 1), which holds `value` in its green channel.
void write_environment(const std::filesystem::path& path, float value) {
  LinearImage image;
  image.width = 4;
  image.height = 2;
  image.rgb.assign(24, 0.5f);
  image.rgb[3 * (1 * 4 + 3) + 1] = value;
  write_image(path, image);
}

// The InputError of loading the scene file, flattened for T when `flatten` (a failure and "" where it is accepted).
template <class T = float>
std::string load_error(const std::filesystem::path& file, bool flatten = false) {
  try {
    const SceneDescription scene = load_scene_file(file);
    if (flatten) test::flatten<T>(scene);
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "accepted";
  return "";
}

TEST(EnvironmentImageErrors, GoodImageLoads) {
  // Positive control for the tests below.
  test::TempDir dir;
  write_environment(dir / "sky.exr", 2.0f);
  const SceneDescription scene = load_scene_file(scene_with_environment(dir, "sky.exr"));
  ASSERT_TRUE(scene.environment.has_value());
  EXPECT_EQ(scene.environment->rgb[3 * 7 + 1], 2.0f);
  using Q16 = Fixed<16, 16>;
  EXPECT_EQ(test::flatten<Q16>(scene).background.environment.width, 4u);
}

TEST(EnvironmentImageErrors, NonFiniteOrNegativeTexelsAreNamed) {
  for (const float value : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(), -0.25f}) {
    test::TempDir dir;
    write_environment(dir / "sky.exr", value);
    const std::filesystem::path file = scene_with_environment(dir, "sky.exr");
    const std::string message = load_error(file);
    EXPECT_EQ(message.rfind(file.string() + ":", 0), 0u) << message;
    EXPECT_NE(message.find(": /background/file: image file '"), std::string::npos) << message;
    EXPECT_NE(message.find("sky.exr': texel (3, 1) (column, row from the top left) has green " + fmt::format("{}", value)), std::string::npos)
        << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
}

TEST(EnvironmentImageErrors, TruncatedOrFakeExrIsNamedOnOneLine) {
  test::TempDir dir;
  write_environment(dir / "whole.exr", 1.0f);
  const std::string bytes = test::read_text_file(dir / "whole.exr");
  // Cut in the pixels, in the header, and a file of only the magic number.
  for (const std::string& cut : {bytes.substr(0, bytes.size() - 20), bytes.substr(0, 40), std::string("\x76\x2f\x31\x01")}) {
    test::write_text_file(dir / "sky.exr", cut);
    const std::filesystem::path file = scene_with_environment(dir, "sky.exr");
    const std::string message = load_error(file);
    EXPECT_EQ(message.rfind(file.string() + ":", 0), 0u) << message;
    EXPECT_NE(message.find(": /background/file: cannot read image file '"), std::string::npos) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
}

TEST(EnvironmentImageErrors, TexelsBeyondTheNumberFormatAreRefusedWhenFlattened) {
  test::TempDir dir;
  write_environment(dir / "sky.exr", 3000.0f);
  // q10.10 holds at most 511.999: the texel is refused there, and accepted by float and q16.16.
  const std::filesystem::path file = scene_with_environment(dir, "sky.exr");
  using Q10 = Fixed<10, 10>;
  using Q16 = Fixed<16, 16>;
  const std::string message = load_error<Q10>(file, true);
  EXPECT_EQ(message.rfind(file.string() + ":", 0), 0u) << message;
  EXPECT_NE(message.find(": /background/file: 3000 (the brightest texel times the strength) does not fit q10.10"), std::string::npos) << message;
  EXPECT_NO_THROW(test::flatten<Q16>(load_scene_file(file)));
  // A strength that takes a texel past float's largest value, where environment images are kept.
  write_environment(dir / "sky.exr", 1e10f);
  const std::filesystem::path strong = scene_with_environment(dir, "sky.exr", R"(, "strength": 1e30)");
  const std::string overflow = load_error<double>(strong, true);
  EXPECT_NE(overflow.find(": /background/file: a texel times the strength, 1e+40, exceeds the largest float"), std::string::npos) << overflow;
}

// ---- the command-line program ----

class CommandLineErrors : public ::testing::Test {
 protected:
  void SetUp() override {
    scene_ = dir_ / "scene.json";
    test::write_text_file(scene_, with_object(kValidObject));
  }
  // Runs `pathtracer render SCENE -q ARGUMENTS`.
  test::CommandResult render(const std::filesystem::path& scene, const std::string& arguments) {
    return test::run_pathtracer("render " + test::quoted(scene) + " -q " + arguments, dir_);
  }
  // One line "pathtracer: error: ..." containing `names`, a failure exit, and nothing left in the folder but the
  // inputs.
  void expect_single_error(const test::CommandResult& result, const std::string& names) {
    EXPECT_NE(result.exit_code, 0);
    const std::vector<std::string> lines = test::lines_of(result.err);
    ASSERT_EQ(lines.size(), 1u) << result.err;
    EXPECT_EQ(lines[0].rfind("pathtracer: error: ", 0), 0u) << lines[0];
    EXPECT_NE(lines[0].find(names), std::string::npos) << lines[0];
    std::vector<std::string> inputs = inputs_;
    std::sort(inputs.begin(), inputs.end());
    EXPECT_EQ(dir_.entries(), inputs) << "files left behind";
  }
  test::TempDir dir_;
  std::filesystem::path scene_;
  std::vector<std::string> inputs_{"scene.json"};
};

TEST_F(CommandLineErrors, ValidRenderSucceeds) {
  // Positive control: the program runs, and writes its image.
  const test::CommandResult result = render(scene_, "-o " + test::quoted(dir_ / "out.png"));
  EXPECT_EQ(result.exit_code, 0) << result.err;
  EXPECT_EQ(result.err, "");
  EXPECT_TRUE(std::filesystem::is_regular_file(dir_ / "out.png"));
}

TEST_F(CommandLineErrors, VerboseRenderReportsEveryPhase) {
  // -q silences the summary but not the phases asked for with -v.
  const test::CommandResult result = render(scene_, "-v -o " + test::quoted(dir_ / "out.png"));
  EXPECT_EQ(result.exit_code, 0) << result.err;
  for (const char* phase : {"scene load", "flatten (BVH included)", "of which BVH build", "device start", "upload", "render", "read-back", "resolve",
                            "encode and write", "total (from the start)"})
    EXPECT_NE(result.err.find(phase), std::string::npos) << phase << " missing from:\n" << result.err;
  EXPECT_TRUE(std::filesystem::is_regular_file(dir_ / "out.png"));
}

TEST_F(CommandLineErrors, MalformedSceneNamesFileAndPosition) {
  test::write_text_file(scene_, with_object(R"({"type": "sphere", "center": [2, 0, 0], "radius": NaN, "material": "white"})"));
  const test::CommandResult result = render(scene_, "-o " + test::quoted(dir_ / "out.png"));
  expect_single_error(result, scene_.string() + ":8:");
  EXPECT_NE(result.err.find("invalid JSON"), std::string::npos);
}

TEST_F(CommandLineErrors, InvalidValueNamesFilePositionAndPath) {
  test::write_text_file(scene_, with_object(R"({"type": "sphere", "center": [2, 0, 0], "radius": -1, "material": "white"})"));
  const test::CommandResult result = render(scene_, "-o " + test::quoted(dir_ / "out.png"));
  expect_single_error(result, scene_.string() + ":8:55: /objects/1/radius: must be positive, found -1");
}

TEST_F(CommandLineErrors, NumberOverflowIsRejectedWithoutOutput) {
  test::write_text_file(scene_, with_object(R"({"type": "sphere", "center": [2, 0, 0], "radius": 1e999, "material": "white"})"));
  const test::CommandResult result = render(scene_, "-o " + test::quoted(dir_ / "out.png"));
  expect_single_error(result, scene_.string() + ":8:55: /objects/1/radius: the number 1e999 is beyond the range of a double");
}

TEST_F(CommandLineErrors, EndlessDeviceAsSceneIsRefusedAtOnce) {
  // Guarded: should /dev/zero be read, the memory limit and the timeout end the program instead of the machine
  // (no memory limit under AddressSanitizer, which reserves terabytes of address space).
  const std::filesystem::path err = dir_ / "stderr.txt";
  const std::string limit = PT_TEST_SANITIZED ? "" : "ulimit -v 4000000; ";
  const std::string command = limit + "timeout 20 '" + test::pathtracer_binary() + "' render /dev/zero -q -o " + test::quoted(dir_ / "out.png") +
                              " > /dev/null 2> " + test::quoted(err);
  const int status = std::system(command.c_str());
  const std::string message = test::read_text_file(err);
  std::filesystem::remove(err);
  EXPECT_EQ(WIFEXITED(status) ? WEXITSTATUS(status) : -1, 1) << message;
  EXPECT_EQ(message, "pathtracer: error: /dev/zero: is a character device, not a scene file\n");
  EXPECT_EQ(dir_.entries(), inputs_);
}

TEST_F(CommandLineErrors, MissingSceneFileIsNamed) {
  const test::CommandResult result = render(dir_ / "absent.json", "-o " + test::quoted(dir_ / "out.png"));
  expect_single_error(result, (dir_ / "absent.json").string() + ": cannot open the scene file");
}

TEST_F(CommandLineErrors, BadEnvironmentImageIsNamedWithoutOutput) {
  write_environment(dir_ / "sky.exr", -1.0f);
  inputs_.push_back("sky.exr");
  test::write_text_file(scene_, environment(R"("file": "sky.exr")"));
  const test::CommandResult result = render(scene_, "-o " + test::quoted(dir_ / "out.png"));
  expect_single_error(result, scene_.string() + ":6:");
  EXPECT_NE(result.err.find("/background/file: image file '"), std::string::npos) << result.err;
  EXPECT_NE(result.err.find("has green -1"), std::string::npos) << result.err;
}

TEST_F(CommandLineErrors, MissingImageIsNamed) {
  test::write_text_file(
      scene_, with(R"("grid": {"type": "uv_checker", "odd": [0, 0, 0], "even": [1, 1, 1]})", R"("grid": {"type": "image", "file": "absent.png"})"));
  const test::CommandResult result = render(scene_, "-o " + test::quoted(dir_ / "out.png"));
  expect_single_error(result, scene_.string() + ":4:");
  EXPECT_NE(result.err.find("absent.png' does not exist"), std::string::npos) << result.err;
}

TEST_F(CommandLineErrors, MissingNormalMapIsNamed) {
  test::write_text_file(scene_, with(R"("white": {"type": "lambertian", "albedo": [0.8, 0.8, 0.8]})",
                                     R"("white": {"type": "metallic_roughness", "base_color": [0.8, 0.8, 0.8], "normal_map": "bumps.png"})"));
  const test::CommandResult result = render(scene_, "-o " + test::quoted(dir_ / "out.png"));
  expect_single_error(result, scene_.string() + ":5:");
  EXPECT_NE(result.err.find("/materials/white/normal_map: image file '"), std::string::npos) << result.err;
  EXPECT_NE(result.err.find("bumps.png' does not exist"), std::string::npos) << result.err;
}

TEST_F(CommandLineErrors, OutputFolderThatDoesNotExist) {
  const std::filesystem::path output = dir_ / "no-such-folder" / "out.png";
  const test::CommandResult result = render(scene_, "-o " + test::quoted(output));
  expect_single_error(result, output.string() + ": cannot write the image");
}

TEST_F(CommandLineErrors, OutputFolderThatIsAFile) {
  test::write_text_file(dir_ / "plain.txt", "a file\n");
  inputs_.push_back("plain.txt");
  const std::filesystem::path output = dir_ / "plain.txt" / "out.png";
  const test::CommandResult result = render(scene_, "-o " + test::quoted(output));
  expect_single_error(result, output.string() + ": cannot write the image: '" + (dir_ / "plain.txt").string() + "' is a file, not a folder");
}

TEST_F(CommandLineErrors, OutputPlaceIsCheckedBeforeAnyWork) {
  // The scene is broken too: the output's error comes first, since it is found before the scene is even read.
  test::write_text_file(scene_, "{ not json");
  const std::filesystem::path output = dir_ / "no-such-folder" / "out.png";
  const test::CommandResult result = render(scene_, "-o " + test::quoted(output));
  expect_single_error(result, output.string() + ": cannot write the image: folder '" + (dir_ / "no-such-folder").string() + "' does not exist");
}

TEST_F(CommandLineErrors, ReadOnlyOutputLocation) {
  // A folder without write permission; where permissions do not bind (running as root) /proc, which refuses new
  // files to everyone.
  const std::filesystem::path locked = dir_ / "locked";
  std::filesystem::create_directory(locked);
  std::filesystem::permissions(locked, std::filesystem::perms::owner_read | std::filesystem::perms::owner_exec);
  std::filesystem::path folder = locked;
  if (std::ofstream(locked / "probe").good()) {
    std::filesystem::remove(locked / "probe");
    folder = "/proc";
  }
  inputs_.push_back("locked");
  const std::filesystem::path output = folder / "pathtracer-test-output.png";
  const test::CommandResult result = render(scene_, "-o " + test::quoted(output));
  expect_single_error(result, output.string() + ": cannot write the image");
  EXPECT_FALSE(std::filesystem::exists(output));
  EXPECT_TRUE(std::filesystem::is_empty(locked));
}

TEST_F(CommandLineErrors, OutputPathThatIsAFolderLeavesNoTemporary) {
  std::filesystem::create_directory(dir_ / "taken.png");
  inputs_.push_back("taken.png");
  const test::CommandResult result = render(scene_, "-o " + test::quoted(dir_ / "taken.png"));
  expect_single_error(result, (dir_ / "taken.png").string() + ": cannot write the image");
  EXPECT_TRUE(std::filesystem::is_empty(dir_ / "taken.png"));
}

TEST_F(CommandLineErrors, UnknownOutputExtension) {
  for (const char* name : {"out.jpg", "out"}) {
    const test::CommandResult result = render(scene_, "-o " + test::quoted(dir_ / name));
    expect_single_error(result, (dir_ / name).string() + ": unknown image extension");
  }
}

TEST_F(CommandLineErrors, AbsurdSizeOnTheCommandLine) {
  // Each side above the limit: refused by the option parser, which names the option, in the one-line form.
  test::CommandResult result = render(scene_, "--width 1000000 --height 1000000 -o " + test::quoted(dir_ / "out.png"));
  EXPECT_NE(result.exit_code, 0);
  ASSERT_EQ(test::lines_of(result.err).size(), 1u) << result.err;
  EXPECT_EQ(result.err.rfind("pathtracer: error: --width", 0), 0u) << result.err;
  EXPECT_EQ(dir_.entries(), inputs_);
  // Each side allowed, the product not: the options are named, not the scene file.
  result = render(scene_, "--width 16384 --height 4097 -o " + test::quoted(dir_ / "out.png"));
  expect_single_error(result, "pathtracer: error: --width 16384 --height 4097: 16384x4097 pixels is too large (at most 67108864 pixels");
  EXPECT_EQ(result.exit_code, 1);
}

TEST_F(CommandLineErrors, SizeTooLargeWithOneSideFromTheSceneNamesTheOptionAndTheScene) {
  test::write_text_file(scene_, with(R"("width": 8, "height": 6)", R"("width": 8, "height": 5000)"));
  const test::CommandResult result = render(scene_, "--width 16384 -o " + test::quoted(dir_ / "out.png"));
  expect_single_error(result,
                      "pathtracer: error: --width 16384 with the scene's height 5000 (" + scene_.string() + "): 16384x5000 pixels is too large");
  EXPECT_EQ(result.exit_code, 1);
}

TEST_F(CommandLineErrors, NumericsSizeTooLargeNamesTheOptions) {
  const test::CommandResult result =
      test::run_pathtracer("numerics " + test::quoted(scene_) + " --width 16384 --height 4097 -o " + test::quoted(dir_ / "results"), dir_);
  expect_single_error(result, "pathtracer: error: --width 16384 --height 4097: 16384x4097 pixels is too large");
  EXPECT_EQ(result.exit_code, 1);
}

TEST_F(CommandLineErrors, NumericsFolderThatIsAFileIsRefusedBeforeRendering) {
  test::write_text_file(dir_ / "results", "a file\n");
  inputs_.push_back("results");
  const test::CommandResult result = test::run_pathtracer("numerics " + test::quoted(scene_) + " -o " + test::quoted(dir_ / "results"), dir_);
  expect_single_error(result, (dir_ / "results").string() + ": cannot write the results: it is a file, not a folder");
  EXPECT_EQ(result.exit_code, 1);
}

// Every mistake on the command line exits with the one code of every input error (1), not the option parser's
// own codes (104-114), in the one-line form, naming the option where there is one.
TEST_F(CommandLineErrors, CommandLineMistakesExitWithTheInputErrorCode) {
  const std::string out = " -o " + test::quoted(dir_ / "out.png");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"render " + test::quoted(scene_) + " --width 0" + out, "--width"},
      {"render " + test::quoted(scene_) + " --spp many" + out, "--spp"},
      {"render " + test::quoted(scene_) + " --backend nowhere" + out, "--backend"},
      {"render " + test::quoted(scene_) + " --no-such-option" + out, "--no-such-option"},
      {"render " + test::quoted(scene_) + " --width" + out, "--width"},
      {"bench " + test::quoted(scene_) + " --runs 0", "--runs"},
      // NaN passes every comparison CLI11's PositiveNumber makes; an index that names no device, a SYCL device
      // without the SYCL backend: each was accepted and ignored.
      {"render " + test::quoted(scene_) + " --time-limit nan" + out, "--time-limit: 'nan' is not a positive number of seconds"},
      {"render " + test::quoted(scene_) + " --time-limit inf" + out, "--time-limit: 'inf' is not"},
      {"render " + test::quoted(scene_) + " --checkpoint " + test::quoted(dir_ / "film") + " --checkpoint-interval nan" + out,
       "--checkpoint-interval: 'nan' is not"},
      {"render " + test::quoted(scene_) + " --device 7" + out, "--device 7: there is no device 7 to render on: the backend is cpu"},
      {"bench " + test::quoted(scene_) + " --device 0,3", "--device 0,3: there is no device 3"},
      {"render " + test::quoted(scene_) + " --sycl-device 0" + out, "--sycl-device 0: only the sycl backend takes it"},
      {"numerics", "scene"},
      {"numerics " + test::quoted(scene_) + " --formats q99.99", "--formats"},
      {"", "subcommand"},
      {"paint", "'paint' is not a command (render, bench, numerics, devices)"},
      {"rendr", "'rendr' is not a command (render, bench, numerics, devices); did you mean 'render'?"},
      {"devises", "did you mean 'devices'?"},
  };
  for (const auto& [arguments, names] : cases) {
    SCOPED_TRACE(arguments);
    const test::CommandResult result = test::run_pathtracer(arguments, dir_);
    EXPECT_EQ(result.exit_code, 1) << result.err;
    const std::vector<std::string> lines = test::lines_of(result.err);
    ASSERT_EQ(lines.size(), 1u) << result.err;
    EXPECT_EQ(lines[0].rfind("pathtracer: error: ", 0), 0u) << lines[0];
    EXPECT_NE(lines[0].find(names), std::string::npos) << lines[0];
    EXPECT_EQ(dir_.entries(), inputs_);
  }
}

// --help and --version succeed; --help documents the exit status and the size limit.
TEST_F(CommandLineErrors, HelpAndVersionExitZeroAndHelpDocumentsTheExitStatus) {
  const std::filesystem::path out = dir_ / "stdout.txt";
  for (const char* arguments : {"--help", "--version", "render --help"}) {
    const std::string command = "'" + test::pathtracer_binary() + "' " + arguments + " > " + test::quoted(out) + " 2>&1";
    const int status = std::system(command.c_str());
    ASSERT_TRUE(WIFEXITED(status)) << arguments;
    EXPECT_EQ(WEXITSTATUS(status), 0) << arguments;
    const std::string text = test::read_text_file(out);
    if (std::string(arguments) == "--help") {
      EXPECT_NE(text.find("Exit status: 0 on success; 1 on any error: bad input (command line"), std::string::npos) << text;
      EXPECT_NE(text.find("67108864 pixels in all"), std::string::npos) << text;
    }
    if (std::string(arguments) == "--version") {
      EXPECT_EQ(text.rfind("pathtracer ", 0), 0u) << text;
    }
  }
  std::filesystem::remove(out);
}

TEST_F(CommandLineErrors, AbsurdSizeInTheSceneFile) {
  test::write_text_file(scene_, with(R"("width": 8, "height": 6)", R"("width": 16000, "height": 16000)"));
  const test::CommandResult result = render(scene_, "-o " + test::quoted(dir_ / "out.png"));
  expect_single_error(result, scene_.string() + ":2:13: /render: 16000x16000 pixels is too large");
}

}  // namespace
}  // namespace pt
