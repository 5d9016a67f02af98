// PLY and OBJ model files. Real files from Debian's assimp-testmodels (the tests that read them are skipped where
// the package is not installed) read to the counts and bounds computed apart from the readers, by
// tools/model_reference_counts.py; the same data in every PLY encoding reads the same; and broken files, written
// here or taken from the package's invalid/ folder, are refused with one InputError, one line naming the file and
// the place.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "loading/model_files.hpp"
#include "loading/polygon_cutting.hpp"
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

const std::filesystem::path kModels = "/usr/share/assimp/models";

#define REQUIRE_TEST_MODELS() \
  if (!std::filesystem::is_directory(kModels)) GTEST_SKIP() << kModels.string() << " is not there (Debian's assimp-testmodels package)"

// Exact equality of points (Vec3 has no ==), with the values in the failure message.
testing::AssertionResult same(const Vec3d& a, const Vec3d& b) {
  if (a.x == b.x && a.y == b.y && a.z == b.z) return testing::AssertionSuccess();
  return testing::AssertionFailure() << fmt::format("({}, {}, {}) differs from ({}, {}, {})", a.x, a.y, a.z, b.x, b.y, b.z);
}

testing::AssertionResult same(const std::vector<Vec3d>& a, const std::vector<Vec3d>& b) {
  if (a.size() != b.size()) return testing::AssertionFailure() << a.size() << " points, not " << b.size();
  for (std::size_t i = 0; i < a.size(); ++i)
    if (const testing::AssertionResult result = same(a[i], b[i]); !result)
      return testing::AssertionFailure() << "point " << i << ": " << result.message();
  return testing::AssertionSuccess();
}

// Bounds from the reference script, which reads the text as doubles; the readers round a PLY file's float
// properties to float, hence the tolerance.
void expect_bounds(const MeshFile& file, Vec3d lo, Vec3d hi, double tolerance = 1e-6) { test::expect_placed_bounds(file, lo, hi, tolerance); }

// What every file these readers give must satisfy besides consistency: one placement per mesh, at the origin.
void expect_well_formed(const MeshFile& file) {
  ASSERT_FALSE(file.meshes.empty());
  expect_consistent(file, 1e-12);
  EXPECT_EQ(file.placements.size(), file.meshes.size());
  for (std::size_t m = 0; m < file.meshes.size(); ++m) {
    EXPECT_FALSE(file.meshes[m].name.empty());
    EXPECT_EQ(file.placements[m].mesh, m);
    EXPECT_TRUE(file.placements[m].transform.is_identity());
  }
}

// ---------------------------------------------------------------------------------------------------------------
// PLY: the package's files

TEST(PlyReader, WusonAsciiWithNormalsAndUvs) {
  REQUIRE_TEST_MODELS();
  const MeshFile file = read_mesh_file(kModels / "PLY/Wuson.ply");
  expect_well_formed(file);
  ASSERT_EQ(file.meshes.size(), 1u);
  const TriangleMesh& mesh = file.meshes[0];
  // model_reference_counts.py: 3732 triangles, 11184 vertices (a vertex per corner, as Blender wrote it)
  EXPECT_EQ(mesh.triangles.size(), 3732u);
  EXPECT_EQ(mesh.positions.size(), 11184u);
  EXPECT_EQ(mesh.normals.size(), 11184u);
  EXPECT_EQ(mesh.uvs.size(), 11184u);  // named s and t
  expect_bounds(file, {-0.459976, -0.000566, -1.622242}, {0.459976, 1.515251, 1.622242});
  EXPECT_TRUE(mesh.materials.empty());
  ASSERT_EQ(file.materials.size(), 1u);
  EXPECT_EQ(file.materials[0].name, "default");
  // Line 3 is "Created by Blender3D 247 ...": a comment without the word, skipped with a warning.
  EXPECT_TRUE(has_warning(file, "header line 3")) << all_warnings(file);
}

TEST(PlyReader, PondIsAPointCloud) {
  REQUIRE_TEST_MODELS();
  // pond.0.ply declares 70051 vertices and no face element (it is also 69 bytes short of its vertices).
  expect_refused(kModels / "PLY/pond.0.ply", {"has no faces", "70051 vertices"});
}

TEST(PlyReader, CubeAsciiAndBinaryAreTheSameMesh) {
  REQUIRE_TEST_MODELS();
  // cube.ply: 6 quadrilaterals as text; cube_binary.ply: the 12 triangles a fan makes of them, little-endian.
  const MeshFile ascii = read_mesh_file(kModels / "PLY/cube.ply");
  const MeshFile binary = read_mesh_file(kModels / "PLY/cube_binary.ply");
  expect_well_formed(ascii);
  expect_well_formed(binary);
  EXPECT_EQ(triangle_count(ascii), 12u);
  EXPECT_EQ(vertex_count(ascii), 8u);
  expect_bounds(ascii, {0, 0, 0}, {1, 1, 1}, 0);
  EXPECT_TRUE(same(ascii.meshes[0].positions, binary.meshes[0].positions));
  EXPECT_EQ(ascii.meshes[0].triangles, binary.meshes[0].triangles);
  EXPECT_TRUE(ascii.meshes[0].normals.empty());
  EXPECT_TRUE(ascii.meshes[0].uvs.empty());
}

TEST(PlyReader, CubeUvHasTextureCoordinates) {
  REQUIRE_TEST_MODELS();
  const MeshFile file = read_mesh_file(kModels / "PLY/cube_uv.ply");
  expect_well_formed(file);
  const TriangleMesh& mesh = file.meshes[0];
  EXPECT_EQ(mesh.triangles.size(), 12u);
  EXPECT_EQ(mesh.positions.size(), 24u);
  ASSERT_EQ(mesh.uvs.size(), 24u);
  EXPECT_EQ(mesh.normals.size(), 24u);
  expect_bounds(file, {-1, -1.000001, -1}, {1, 1, 1});
  // Vertex 2 of the file: "-1 -1 -1 0 0 -1 1 1"
  EXPECT_EQ(mesh.uvs[2], (std::array<double, 2>{1, 1}));
  EXPECT_TRUE(same(mesh.normals[2], Vec3d{0, 0, -1}));
}

TEST(PlyReader, EmptyFileIsRefused) {
  REQUIRE_TEST_MODELS();
  expect_refused(kModels / "invalid/empty.ply", {"not a PLY file"});
}

// ---------------------------------------------------------------------------------------------------------------
// PLY: files written here

// A mesh to write as PLY in any of the three encodings, with properties of every type, some to skip, and an
// element the reader does not know between the faces and the vertices (which come last).
struct PlySample {
  std::vector<std::array<double, 3>> positions;  // x is a double, y and z floats
  std::vector<std::array<double, 3>> normals;    // floats
  std::vector<std::array<double, 2>> uvs;        // floats, named texture_u and texture_v
  std::vector<std::vector<std::int64_t>> faces;
};

PlySample sample_mesh() {
  test::TestRandom random(7);
  PlySample sample;
  for (int i = 0; i < 9; ++i) {
    sample.positions.push_back({random.uniform(-5, 5), static_cast<float>(random.uniform(-5, 5)), static_cast<float>(random.uniform(-1e6, 1e6))});
    sample.normals.push_back({static_cast<float>(random.uniform(-1, 1)), static_cast<float>(random.uniform(-1, 1)), 0.5f});
    sample.uvs.push_back({static_cast<float>(random.uniform(0, 1)), static_cast<float>(random.uniform(0, 1))});
  }
  sample.faces = {{0, 1, 2}, {3, 4, 5, 6}, {8, 7, 6, 5, 4}, {1, 2}, {}, {0, 8, 4}};
  return sample;
}

class ByteWriter {
 public:
  explicit ByteWriter(bool big_endian) : swap_(big_endian != (std::endian::native == std::endian::big)) {}
  template <class T>
  void put(T value) {
    unsigned char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
    if (swap_) std::reverse(bytes, bytes + sizeof(T));
    text.append(reinterpret_cast<const char*>(bytes), sizeof(T));
  }
  std::string text;

 private:
  bool swap_;
};

std::string ply_text(const PlySample& sample, const std::string& format) {
  std::string out = fmt::format(
      "ply\nformat {} 1.0\ncomment written by the tests\nelement face {}\nproperty uint8 flags\nproperty list uchar int vertex_indices\n"
      "property list ushort float64 weights\nelement edge 2\nproperty int32 vertex1\nproperty list int8 uint16 path\nproperty double length\n"
      "element vertex {}\nproperty float64 x\nproperty float32 y\nproperty float z\nproperty uchar red\nproperty list char short junk\n"
      "property float nx\nproperty float ny\nproperty float nz\nproperty float texture_u\nproperty float texture_v\nproperty int16 flags\n"
      "end_header\n",
      format, sample.faces.size(), sample.positions.size());
  if (format == "ascii") {
    for (const auto& face : sample.faces) {
      out += fmt::format("7 {}", face.size());
      for (const std::int64_t index : face) out += fmt::format(" {}", index);
      out += " 2 0.5 -1e-3\n";
    }
    out += "1 3 4 5 6 2.5\n  \n2 0 0.25\n";  // a blank line between elements is allowed
    for (std::size_t i = 0; i < sample.positions.size(); ++i) {
      const auto& p = sample.positions[i];
      const auto& n = sample.normals[i];
      out += fmt::format("{:.17g} {:.9g} {:.9g} 255 2 -7 9 {:.9g} {:.9g} {:.9g} {:.9g} {:.9g} -3\n", p[0], p[1], p[2], n[0], n[1], n[2],
                         sample.uvs[i][0], sample.uvs[i][1]);
    }
    return out;
  }
  ByteWriter body(format == "binary_big_endian");
  for (const auto& face : sample.faces) {
    body.put<std::uint8_t>(7);
    body.put<std::uint8_t>(static_cast<std::uint8_t>(face.size()));
    for (const std::int64_t index : face) body.put<std::int32_t>(static_cast<std::int32_t>(index));
    body.put<std::uint16_t>(2);
    body.put<double>(0.5);
    body.put<double>(-1e-3);
  }
  for (const auto& [vertex1, path, length] :
       {std::tuple{1, std::vector<std::uint16_t>{4, 5, 6}, 2.5}, std::tuple{2, std::vector<std::uint16_t>{}, 0.25}}) {
    body.put<std::int32_t>(vertex1);
    body.put<std::int8_t>(static_cast<std::int8_t>(path.size()));
    for (const std::uint16_t item : path) body.put<std::uint16_t>(item);
    body.put<double>(length);
  }
  for (std::size_t i = 0; i < sample.positions.size(); ++i) {
    body.put<double>(sample.positions[i][0]);
    body.put<float>(static_cast<float>(sample.positions[i][1]));
    body.put<float>(static_cast<float>(sample.positions[i][2]));
    body.put<std::uint8_t>(255);
    body.put<std::int8_t>(2);
    body.put<std::int16_t>(-7);
    body.put<std::int16_t>(9);
    for (const double n : sample.normals[i]) body.put<float>(static_cast<float>(n));
    for (const double t : sample.uvs[i]) body.put<float>(static_cast<float>(t));
    body.put<std::int16_t>(-3);
  }
  return out + body.text;
}

TEST(PlyReader, SameDataInEveryEncodingReadsTheSame) {
  test::TempDir dir;
  const PlySample sample = sample_mesh();
  std::vector<MeshFile> files;
  for (const std::string format : {"ascii", "binary_little_endian", "binary_big_endian"}) {
    const std::filesystem::path path = dir / (format + ".ply");
    test::write_text_file(path, ply_text(sample, format));
    files.push_back(read_ply_file(path));
    expect_well_formed(files.back());
  }
  const TriangleMesh& mesh = files[0].meshes[0];
  ASSERT_EQ(mesh.positions.size(), 9u);
  for (std::size_t i = 0; i < 9; ++i) {
    EXPECT_TRUE(same(mesh.positions[i], Vec3d{sample.positions[i][0], sample.positions[i][1], sample.positions[i][2]}));
    const Vec3d n{sample.normals[i][0], sample.normals[i][1], sample.normals[i][2]};
    EXPECT_NEAR(length(mesh.normals[i] - n / length(n)), 0, 1e-15);
    EXPECT_EQ(mesh.uvs[i], sample.uvs[i]);
  }
  // Fans around each face's first corner; the faces of 2 and 0 corners are skipped with a warning.
  const std::vector<std::array<u32, 3>> triangles = {{0, 1, 2}, {3, 4, 5}, {3, 5, 6}, {8, 7, 6}, {8, 6, 5}, {8, 5, 4}, {0, 8, 4}};
  EXPECT_EQ(mesh.triangles, triangles);
  for (const MeshFile& file : files) {
    EXPECT_TRUE(same(file.meshes[0].positions, mesh.positions));
    EXPECT_TRUE(same(file.meshes[0].normals, mesh.normals));
    EXPECT_EQ(file.meshes[0].uvs, mesh.uvs);
    EXPECT_EQ(file.meshes[0].triangles, mesh.triangles);
    EXPECT_TRUE(has_warning(file, "2 faces of fewer than 3 vertices skipped")) << all_warnings(file);
    EXPECT_TRUE(has_warning(file, "elements not read: edge (2)")) << all_warnings(file);
    EXPECT_TRUE(has_warning(file, "vertex properties not read: red, junk, flags")) << all_warnings(file);
    EXPECT_FALSE(has_warning(file, "ignored")) << all_warnings(file);
  }
}

std::string ascii_ply(const std::string& vertex_properties, const std::string& vertices, const std::string& faces, std::size_t vertex_count,
                      std::size_t face_count) {
  return fmt::format("ply\nformat ascii 1.0\nelement vertex {}\n{}element face {}\nproperty list uchar int vertex_indices\nend_header\n{}{}",
                     vertex_count, vertex_properties, face_count, vertices, faces);
}

const std::string kXyz = "property float x\nproperty float y\nproperty float z\n";
const std::string kSquare = "0 0 0\n1 0 0\n1 1 0\n0 1 0\n";

TEST(PlyReader, TextureCoordinatesUnderEveryName) {
  test::TempDir dir;
  for (const auto& [u, v] : {std::pair{"u", "v"}, std::pair{"s", "t"}, std::pair{"texture_u", "texture_v"}, std::pair{"texture_s", "texture_t"}}) {
    const std::filesystem::path path = dir / fmt::format("{}.ply", u);
    test::write_text_file(path, ascii_ply(kXyz + fmt::format("property float {}\nproperty float {}\n", u, v),
                                          "0 0 0 0 0\n1 0 0 1 0\n1 1 0 1 1\n0 1 0 0 0.75\n", "4 0 1 2 3\n", 4, 1));
    const MeshFile file = read_ply_file(path);
    ASSERT_EQ(file.meshes[0].uvs.size(), 4u) << u;
    EXPECT_EQ(file.meshes[0].uvs[3], (std::array<double, 2>{0, 0.75})) << u;
  }
  // Half a pair: read without texture coordinates, and said.
  const std::filesystem::path path = dir / "half.ply";
  test::write_text_file(path, ascii_ply(kXyz + "property float s\n", "0 0 0 0\n1 0 0 1\n1 1 0 1\n", "3 0 1 2\n", 3, 1));
  const MeshFile file = read_ply_file(path);
  EXPECT_TRUE(file.meshes[0].uvs.empty());
  EXPECT_TRUE(has_warning(file, "'s' without 't'")) << all_warnings(file);
}

TEST(PlyReader, NormalsAreNormalisedAndZeroOnesDropped) {
  test::TempDir dir;
  const std::string normals = "property float nx\nproperty float ny\nproperty float nz\n";
  test::write_text_file(dir / "n.ply", ascii_ply(kXyz + normals, "0 0 0 0 0 2\n1 0 0 3 4 0\n1 1 0 0 0 -1\n", "3 0 1 2\n", 3, 1));
  const MeshFile file = read_ply_file(dir / "n.ply");
  EXPECT_TRUE(same(file.meshes[0].normals, std::vector<Vec3d>{{0, 0, 1}, {0.6, 0.8, 0}, {0, 0, -1}}));
  test::write_text_file(dir / "zero.ply", ascii_ply(kXyz + normals, "0 0 0 0 0 2\n1 0 0 0 0 0\n1 1 0 0 0 -1\n", "3 0 1 2\n", 3, 1));
  const MeshFile zero = read_ply_file(dir / "zero.ply");
  EXPECT_TRUE(zero.meshes[0].normals.empty());
  EXPECT_TRUE(has_warning(zero, "1 vertex normals of zero length")) << all_warnings(zero);
  // Some of the three: refused.
  test::write_text_file(dir / "partial.ply",
                        ascii_ply(kXyz + "property float nx\nproperty float nz\n", "0 0 0 0 1\n1 0 0 0 1\n1 1 0 0 1\n", "3 0 1 2\n", 3, 1));
  expect_refused(dir / "partial.ply", {"line 3:", "normal", "all three or none"});
}

TEST(PlyReader, IndexOutOfRangeIsRefused) {
  test::TempDir dir;
  test::write_text_file(dir / "a.ply", ascii_ply(kXyz, kSquare, "3 0 1 2\n4 0 1 2 9999\n", 4, 2));
  expect_refused(dir / "a.ply", {"line 15: face 1: vertex index 9999 out of range (the file has 4 vertices)"});
  test::write_text_file(dir / "negative.ply", ascii_ply(kXyz, kSquare, "3 0 -1 2\n", 4, 1));
  expect_refused(dir / "negative.ply", {"line 14: face 0: vertex index -1 out of range"});
  // Binary: the place is the element's number.
  std::string binary = ply_text(sample_mesh(), "binary_little_endian");
  const std::size_t first_index = binary.find("end_header\n") + 11 + 2;  // flags and the list's length
  const std::int32_t bad = 12;
  std::memcpy(binary.data() + first_index + 4, &bad, 4);
  test::write_text_file(dir / "b.ply", binary);
  expect_refused(dir / "b.ply", {"face 0: vertex index 12 out of range (the file has 9 vertices)"});
}

TEST(PlyReader, TruncatedBinaryBodyIsRefused) {
  test::TempDir dir;
  const std::string whole = ply_text(sample_mesh(), "binary_little_endian");
  // Cut inside the last vertex (the header's counts fit in what is left: lists may be short).
  test::write_text_file(dir / "a.ply", whole.substr(0, whole.size() - 5));
  expect_refused(dir / "a.ply", {"vertex 8:", "cut short"});
  // A list longer than the rest of the file: refused before room is made for it.
  std::string longer = whole;
  longer[whole.find("end_header\n") + 11 + 1] = static_cast<char>(200);  // the length of face 0's vertex_indices
  test::write_text_file(dir / "b.ply", longer);
  expect_refused(dir / "b.ply", {"face 0: the file ends inside list 'vertex_indices' of 200 items"});
  // Cut before the elements the header declares: refused from the header alone.
  test::write_text_file(dir / "c.ply", whole.substr(0, whole.find("end_header\n") + 11 + 100));
  expect_refused(dir / "c.ply", {"line 12:", "9 'vertex' elements", "only 100 bytes"});
}

TEST(PlyReader, HeaderCountsBeyondTheFileOrTheLimitsAreRefusedBeforeAllocating) {
  test::TempDir dir;
  // 2^40 faces: beyond the limit on triangles.
  test::write_text_file(dir / "huge.ply",
                        "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                        "element face 1099511627776\nproperty list uchar int vertex_indices\nend_header\n" +
                            std::string(36 + 13, '\0'));
  expect_refused(dir / "huge.ply", {"line 7:", "1099511627776 faces, more than the 268435456"});
  // 100 million vertices (within the limit, 2.4 GB as read) in a 200-byte file: the file cannot hold them.
  test::write_text_file(dir / "lie.ply",
                        "ply\nformat binary_big_endian 1.0\nelement vertex 100000000\nproperty float x\nproperty float y\nproperty float z\n"
                        "element face 1\nproperty list uchar int vertex_indices\nend_header\n" +
                            std::string(49, '\0'));
  expect_refused(dir / "lie.ply", {"line 3:", "100000000 'vertex' elements", "at least 12 bytes each", "only 49 bytes"});
  // As text: each value takes two bytes at least.
  test::write_text_file(dir / "lie.txt.ply", ascii_ply(kXyz, kSquare, "3 0 1 2\n", 4, 50000000));
  expect_refused(dir / "lie.txt.ply", {"line 7:", "50000000 'face' elements", "as text"});
  test::write_text_file(dir / "many.ply", ascii_ply(kXyz, kSquare, "3 0 1 2\n", 300000000, 1));
  expect_refused(dir / "many.ply", {"line 3:", "300000000 vertices, more than the 268435456"});
}

TEST(PlyReader, BadHeadersAreRefusedWithTheirLine) {
  test::TempDir dir;
  const auto refused = [&](const std::string& name, const std::string& text, const std::vector<std::string>& parts) {
    test::write_text_file(dir / name, text);
    expect_refused(dir / name, parts);
  };
  refused("format.ply", "ply\nformat binary_middle_endian 1.0\nelement vertex 0\nend_header\n", {"line 2: unknown format 'binary_middle_endian'"});
  refused("version.ply", "ply\nformat ascii 2.0\nend_header\n", {"line 2:", "version '2.0'"});
  refused("end.ply", "ply\nformat ascii 1.0\nelement vertex 3\n" + kXyz + "0 0 0\n1 0 0\n0 1 0\n", {"line 9:", "no end_header"});
  refused("magic.ply", "PLY\nformat ascii 1.0\nend_header\n", {"not a PLY file"});
  refused("type.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty real x\nend_header\n", {"line 4: unknown property type 'real'"});
  refused("orphan.ply", "ply\nformat ascii 1.0\nproperty float x\nend_header\n", {"line 3: a property before any element"});
  refused("count.ply", "ply\nformat ascii 1.0\nelement vertex -3\nend_header\n", {"line 3:", "not a whole number"});
  refused("twice.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty double x\nend_header\n",
          {"line 5: a second property 'x'"});
  refused("noz.ply", ascii_ply("property float x\nproperty float y\n", "", "", 0, 0), {"line 3: the vertex element has no property 'z'"});
  refused("noindices.ply",
          "ply\nformat ascii 1.0\nelement vertex 1\n" + kXyz + "element face 1\nproperty list uchar int corners\nend_header\n0 0 0\n3 0 0 0\n",
          {"line 7:", "no list 'vertex_indices'"});
  refused("floatindices.ply",
          "ply\nformat ascii 1.0\nelement vertex 1\n" + kXyz + "element face 1\nproperty list uchar float vertex_indices\nend_header\n",
          {"line 8:", "floating-point"});
  refused("nofaces.ply", ascii_ply(kXyz, kSquare, "", 4, 0), {"has no faces"});
}

TEST(PlyReader, BadBodiesAreRefusedWithTheirPlace) {
  test::TempDir dir;
  const auto refused = [&](const std::string& name, const std::string& text, const std::vector<std::string>& parts) {
    test::write_text_file(dir / name, text);
    expect_refused(dir / name, parts);
  };
  refused("nan.ply", ascii_ply(kXyz, "0 0 0\nnan 0 0\n1 1 0\n", "3 0 1 2\n", 3, 1), {"line 11: vertex 1: position is not finite"});
  refused("inf.ply", ascii_ply(kXyz, "0 0 0\n1 0 0\n1 1 1e39\n", "3 0 1 2\n", 3, 1), {"line 12: vertex 2: position is not finite"});
  refused("word.ply", ascii_ply(kXyz, "0 0 0\n1 zero 0\n1 1 0\n", "3 0 1 2\n", 3, 1), {"line 11: vertex 1: 'zero' is not a number"});
  refused("few.ply", ascii_ply(kXyz, "0 0 0\n1 0\n1 1 0\n", "3 0 1 2\n", 3, 1), {"line 11: vertex 1: fewer values"});
  refused("more.ply", ascii_ply(kXyz, "0 0 0\n1 0 0 0\n1 1 0\n", "3 0 1 2\n", 3, 1), {"line 11: vertex 1: more values"});
  refused("range.ply", ascii_ply(kXyz, kSquare, "300 0 1 2\n", 4, 1), {"line 14: face 0: 300 is out of range", "uchar"});
  refused("short.ply", ascii_ply(kXyz, kSquare, "4 0 1 2\n", 4, 1), {"line 14: face 0: fewer values"});
  refused("missing.ply", ascii_ply(kXyz, kSquare, "3 0 1 2\n", 4, 2), {"ends before face 1 (the header declares 2)"});
  std::string binary = ply_text(sample_mesh(), "binary_big_endian");
  const std::size_t last_vertex = binary.size() - 44;  // x of the last vertex: a double, big-endian
  const std::uint64_t nan = std::bit_cast<std::uint64_t>(std::numeric_limits<double>::quiet_NaN());
  for (int i = 0; i < 8; ++i) binary[last_vertex + i] = static_cast<char>(nan >> (56 - 8 * i));
  refused("nan-binary.ply", binary, {"vertex 8: position is not finite"});
}

TEST(PlyReader, SpecialFilesAreRefused) {
  test::TempDir dir;
  expect_refused(dir / "absent.ply", {"cannot open the PLY file"});
  ASSERT_EQ(::mkfifo((dir / "fifo.ply").c_str(), 0600), 0);
  expect_refused(dir / "fifo.ply", {"FIFO"});
  std::filesystem::create_directory(dir / "folder.ply");
  expect_refused(dir / "folder.ply", {"folder"});
}

// ---------------------------------------------------------------------------------------------------------------
// OBJ: the package's files

TEST(ObjReader, SpiderWithTexturedMaterials) {
  REQUIRE_TEST_MODELS();
  const MeshFile file = read_mesh_file(kModels / "OBJ/spider.obj");
  expect_well_formed(file);
  // model_reference_counts.py: 19 groups, 1368 triangles, 974 distinct position/uv/normal triples
  EXPECT_EQ(file.meshes.size(), 19u);
  EXPECT_EQ(triangle_count(file), 1368u);
  EXPECT_EQ(vertex_count(file), 974u);
  EXPECT_EQ(file.meshes[0].name, "HLeib01");
  EXPECT_EQ(file.meshes[0].triangles.size(), 80u);
  EXPECT_EQ(file.meshes[0].positions.size(), 42u);
  expect_bounds(file, {-92.655235, -42.233826, -106.6912}, {57.936218, 37.503952, 86.6912}, 1e-9);
  // The four materials the faces use, in the library's order (Brusttex is not used); every face has one.
  std::vector<std::string> names;
  for (const MeshMaterial& material : file.materials) names.push_back(material.name);
  EXPECT_EQ(names, (std::vector<std::string>{"Skin", "HLeibTex", "BeinTex", "Augentex"}));
  std::map<u32, u64> triangles_per_material;
  for (const TriangleMesh& mesh : file.meshes)
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) ++triangles_per_material[mesh.materials.empty() ? 0 : mesh.materials[t]];
  EXPECT_EQ(triangles_per_material, (std::map<u32, u64>{{0, 260}, {1, 80}, {2, 952}, {3, 76}}));  // counted with awk from the usemtl lines
  // map_Kd .\wal67ar_small.jpg and the like: Windows paths, each image read once.
  EXPECT_EQ(file.textures.size(), 4u);
  for (const MeshMaterial& material : file.materials) EXPECT_GE(material.base_color_texture, 0) << material.name;
  EXPECT_NEAR(file.materials[0].base_color.x, 0.827451, 1e-12);  // Kd of Skin multiplies its texture
  EXPECT_EQ(file.materials[0].roughness, 1.0);                   // no Pr
  for (const TriangleMesh& mesh : file.meshes) EXPECT_EQ(mesh.uvs.size(), mesh.positions.size()) << mesh.name;
}

TEST(ObjReader, WusonHasNormalsAndUvs) {
  REQUIRE_TEST_MODELS();
  const MeshFile file = read_mesh_file(kModels / "OBJ/WusonOBJ.obj");
  expect_well_formed(file);
  ASSERT_EQ(file.meshes.size(), 1u);
  // The same model as PLY/Wuson.ply: the same triangles and bounds, but corners shared (2117 vertices, not 11184).
  EXPECT_EQ(triangle_count(file), 3732u);
  EXPECT_EQ(vertex_count(file), 2117u);
  EXPECT_EQ(file.meshes[0].normals.size(), 2117u);
  EXPECT_EQ(file.meshes[0].uvs.size(), 2117u);
  expect_bounds(file, {-0.459976, -0.000566, -1.622242}, {0.459976, 1.515251, 1.622242}, 1e-12);
}

TEST(ObjReader, BoxWithAnUndefinedMaterial) {
  REQUIRE_TEST_MODELS();
  const MeshFile file = read_mesh_file(kModels / "OBJ/box.obj");
  expect_well_formed(file);
  EXPECT_EQ(triangle_count(file), 12u);
  EXPECT_EQ(vertex_count(file), 8u);
  expect_bounds(file, {-0.5, -0.5, -0.5}, {0.5, 0.5, 0.5}, 0);
  EXPECT_EQ(file.meshes[0].name, "1");
  // "usemtl Default" with no material library: a warning with the line, and the default material.
  ASSERT_EQ(file.materials.size(), 1u);
  EXPECT_EQ(file.materials[0].name, "default");
  EXPECT_TRUE(has_warning(file, "line 22: material 'Default' is not defined")) << all_warnings(file);
}

TEST(ObjReader, CubeUsemtlHasPerTriangleMaterials) {
  REQUIRE_TEST_MODELS();
  const MeshFile file = read_mesh_file(kModels / "OBJ/cube_usemtl.obj");
  expect_well_formed(file);
  EXPECT_EQ(triangle_count(file), 12u);
  EXPECT_EQ(vertex_count(file), 24u);  // 8 positions, each with the normal of 3 sides
  expect_bounds(file, {0, 0, 0}, {1, 1, 1}, 0);
  // The library defines mtl and mtl2; mtl3, used by the first two faces (line 21 and 23), is not defined: they get
  // the default.
  ASSERT_EQ(file.materials.size(), 3u);
  EXPECT_EQ(file.materials[0].name, "mtl");
  EXPECT_EQ(file.materials[1].name, "mtl2");
  EXPECT_EQ(file.materials[2].name, "default");
  EXPECT_EQ(file.meshes[0].materials, (std::vector<u32>{2, 2, 0, 0, 0, 1, 1, 1, 1, 0, 0, 0}));
  EXPECT_TRUE(same(file.materials[0].base_color, Vec3d{1, 1, 1}));
  EXPECT_TRUE(has_warning(file, "line 21: material 'mtl3' is not defined")) << all_warnings(file);
  EXPECT_TRUE(has_warning(file, "specular highlights")) << all_warnings(file);
  for (const Vec3d& n : file.meshes[0].normals) EXPECT_EQ(std::abs(n.x) + std::abs(n.y) + std::abs(n.z), 1.0);
}

TEST(ObjReader, OddlyWrittenFiles) {
  REQUIRE_TEST_MODELS();
  // number_formats.obj: "f 1 2 4" uses 0 0 0, "1 2. 3.0" and "-1 -2. -3.0".
  const MeshFile numbers = read_mesh_file(kModels / "OBJ/number_formats.obj");
  expect_well_formed(numbers);
  EXPECT_EQ(triangle_count(numbers), 1u);
  EXPECT_TRUE(same(numbers.meshes[0].positions, std::vector<Vec3d>{{0, 0, 0}, {1, 2, 3}, {-1, -2, -3}}));
  // box_without_lineending.obj: the last face has no newline after it.
  const MeshFile unended = read_mesh_file(kModels / "OBJ/box_without_lineending.obj");
  expect_well_formed(unended);
  EXPECT_EQ(triangle_count(unended), 12u);
  EXPECT_EQ(vertex_count(unended), 8u);
  expect_bounds(unended, {-0.5, -0.5, -0.5}, {0.5, 0.5, 0.5}, 0);
  // multiple_spaces.obj: runs of blanks between and after the numbers.
  const MeshFile spaces = read_mesh_file(kModels / "OBJ/multiple_spaces.obj");
  expect_well_formed(spaces);
  EXPECT_TRUE(same(spaces.meshes[0].positions, std::vector<Vec3d>{{1, 2, 3}, {2, 3, 1}, {3, 1, 2}}));
  EXPECT_TRUE(spaces.meshes[0].uvs.empty());  // "f 1 2 3" names no texture coordinates
}

// The triangles' area in the plane x = const that concave_polygon.obj lies in.
double area_in_yz(const TriangleMesh& mesh) {
  double area = 0;
  for (const auto& t : mesh.triangles) {
    const Vec3d a = mesh.positions[t[0]], b = mesh.positions[t[1]], c = mesh.positions[t[2]];
    area += std::abs((b.y - a.y) * (c.z - a.z) - (c.y - a.y) * (b.z - a.z)) / 2;
  }
  return area;
}

TEST(ObjReader, ConcavePolygonIsCutIntoEars) {
  REQUIRE_TEST_MODELS();
  const MeshFile file = read_mesh_file(kModels / "OBJ/concave_polygon.obj");
  expect_well_formed(file);
  // One face of 66 corners (64 distinct positions: a ring joined to its hole by an edge walked twice).
  EXPECT_EQ(triangle_count(file), 64u);
  EXPECT_EQ(vertex_count(file), 64u);
  expect_bounds(file, {-1.146, 1.6575, 1.6055}, {-1.146, 3.1425, 3.0905}, 1e-12);
  // The polygon's area by the shoelace formula over its corners (computed in Python): the triangles cover it
  // exactly only if none lies outside it or over another, which a fan of this concave polygon would not.
  EXPECT_NEAR(area_in_yz(file.meshes[0]), 0.2454966872, 1e-9);
}

// A polygon in the xy plane and its area by the shoelace formula (positive counter-clockwise).
double shoelace_area(const std::vector<Vec3d>& corners) {
  double twice = 0;
  for (std::size_t i = 0; i < corners.size(); ++i) {
    const Vec3d& a = corners[i];
    const Vec3d& b = corners[(i + 1) % corners.size()];
    twice += a.x * b.y - b.x * a.y;
  }
  return twice / 2;
}

TEST(PolygonCutting, LargePolygonsAreCutExactlyWithWorkLinearInTheirCorners) {
  constexpr u32 kCorners = 100000;
  const double pi = std::acos(-1.0);
  std::map<std::string, std::vector<Vec3d>> polygons;
  for (u32 i = 0; i < kCorners; ++i) {
    const double angle = 2 * pi * i / kCorners;
    polygons["circle"].push_back({std::cos(angle), std::sin(angle), 0});
    const double radius = i % 2 == 0 ? 1.0 : 0.5;  // every other corner reflex
    polygons["star"].push_back({radius * std::cos(angle), radius * std::sin(angle), 0});
  }
  // A comb: a base of height 1 and kCorners / 4 teeth of height 9, counter-clockwise from the base's left end.
  std::vector<Vec3d>& comb = polygons["comb"];
  const int teeth = kCorners / 4;
  comb.push_back({0, 0, 0});
  comb.push_back({2.0 * teeth - 1, 0, 0});
  for (int i = teeth - 1; i >= 0; --i) {
    comb.push_back({2.0 * i + 1, 10, 0});
    comb.push_back({2.0 * i, 10, 0});
    if (i > 0) {
      comb.push_back({2.0 * i, 1, 0});
      comb.push_back({2.0 * i - 1, 1, 0});
    }
  }
  for (const auto& [name, corners] : polygons) {
    SCOPED_TRACE(name);
    std::vector<std::array<u32, 3>> triangles;
    const PolygonCut cut = cut_polygon(corners, triangles);
    EXPECT_TRUE(cut.ears_found);
    ASSERT_EQ(triangles.size(), corners.size() - 2);
    // Every triangle keeps the polygon's winding and together they cover its area: none lies outside it or over another.
    double area = 0;
    for (const auto& t : triangles) {
      const double a = shoelace_area({corners[t[0]], corners[t[1]], corners[t[2]]});
      EXPECT_GE(a, 0);
      area += a;
    }
    EXPECT_NEAR(area, shoelace_area(corners), 1e-9 * std::abs(shoelace_area(corners)));
    // Walking round the polygon and testing every remaining corner against every candidate ear did about
    // corners^2 / 2 tests (5e9 here, half a minute); the queue of candidates and the reflex corners' grid keep the
    // work to a bounded number of steps per corner.
    EXPECT_LE(cut.ears_tried, 3 * corners.size());
    EXPECT_LE(cut.corner_tests, 100 * corners.size());
  }
}

// tinyobjloader counts a face's corners in a byte: faces of more than 255 corners were read again with its own
// triangulation, which takes time quadratic in the corners (half a minute for 100,000) and cuts concave faces wrong.
// Their counts now come from the text, and they are cut as every polygon is: a star of 20,000 corners, a face of
// exactly 256 (a count of 0 in a byte) and a triangle between them read with their areas exact and no warning.
TEST(ObjReader, FacesOfMoreThan255CornersAreCutAsEveryPolygonIs) {
  test::TempDir dir;
  constexpr int kStar = 20000, kRing = 256;
  const double pi = std::acos(-1.0);
  std::string obj;
  for (int i = 0; i < kStar; ++i) {
    const double angle = 2 * pi * i / kStar, radius = i % 2 == 0 ? 1.0 : 0.5;
    obj += fmt::format("v {:.17g} {:.17g} 0\n", radius * std::cos(angle), radius * std::sin(angle));
  }
  for (int i = 0; i < kRing; ++i) obj += fmt::format("v {:.17g} {:.17g} 1\n", std::cos(2 * pi * i / kRing), std::sin(2 * pi * i / kRing));
  obj += "f";
  for (int i = 1; i <= kStar; ++i) obj += fmt::format(" {}", i);
  obj += fmt::format("\nf 1 {} {}\n\tf", kStar / 4 + 1, kStar / 2 + 1);
  for (int i = 1; i <= kRing; ++i) obj += fmt::format("\t{}", kStar + i);
  obj += " \r\n";
  test::write_text_file(dir / "big-faces.obj", obj);
  const MeshFile file = read_mesh_file(dir / "big-faces.obj");
  EXPECT_TRUE(file.warnings.empty()) << test::all_warnings(file);
  ASSERT_EQ(file.meshes.size(), 1u);
  const TriangleMesh& mesh = file.meshes[0];
  ASSERT_EQ(mesh.triangles.size(), static_cast<std::size_t>(kStar - 2 + 1 + kRing - 2));
  // Signed areas in the xy plane, by face: each triangle keeps its face's winding, and they add up to the faces' own.
  double star = 0, triangle = 0, ring = 0;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const Vec3d& a = mesh.positions[mesh.triangles[t][0]];
    const Vec3d& b = mesh.positions[mesh.triangles[t][1]];
    const Vec3d& c = mesh.positions[mesh.triangles[t][2]];
    const double area = ((b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y)) / 2;
    EXPECT_GE(area, 0) << t;
    (t < kStar - 2 ? star : t == kStar - 2 ? triangle : ring) += area;
  }
  std::vector<Vec3d> star_corners, ring_corners;
  for (int i = 0; i < kStar; ++i) {
    const double angle = 2 * pi * i / kStar, radius = i % 2 == 0 ? 1.0 : 0.5;
    star_corners.push_back({radius * std::cos(angle), radius * std::sin(angle), 0});
  }
  for (int i = 0; i < kRing; ++i) ring_corners.push_back({std::cos(2 * pi * i / kRing), std::sin(2 * pi * i / kRing), 1});
  EXPECT_NEAR(star, shoelace_area(star_corners), 1e-9);
  EXPECT_NEAR(ring, shoelace_area(ring_corners), 1e-9);
  EXPECT_NEAR(triangle, 1.0, 1e-9);  // (1, 0), (0, 1), (-1, 0)
}

// A model given as the scene has a camera placed to frame it: where a vertex does not fit the kernels' type, the
// vertex is named, not the camera (which was blamed as /camera/look_from/0, a path the model does not have).
TEST(ObjReader, VertexBeyondTheKernelsRangeIsNamedRatherThanTheCameraFramingIt) {
  test::TempDir dir;
  test::write_text_file(dir / "big.obj", "v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n");
  const SceneDescription scene = load_scene_file(dir / "big.obj");
  try {
    test::flatten<float>(scene);
    ADD_FAILURE() << "accepted in float";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_TRUE(message.starts_with((dir / "big.obj").string() + ": 1e+39 (a vertex of mesh 'mesh 0') is beyond float's")) << message;
    EXPECT_EQ(message.find("/camera"), std::string::npos) << message;
  }
  EXPECT_NO_THROW(test::flatten<double>(scene));
}

TEST(ObjReader, MaterialNameWithSpaces) {
  REQUIRE_TEST_MODELS();
  // "newmtl Hard Shiny Plastic White" and "usemtl  Hard Shiny Plastic White ": tinyobjloader alone would look up
  // "Hard" and give the faces no material.
  const MeshFile file = read_mesh_file(kModels / "OBJ/space_in_material_name.obj");
  expect_well_formed(file);
  EXPECT_EQ(triangle_count(file), 64u);
  ASSERT_EQ(file.materials.size(), 1u);
  EXPECT_EQ(file.materials[0].name, "Hard Shiny Plastic White");
  EXPECT_NEAR(file.materials[0].base_color.x, 0.141176, 1e-12);
  EXPECT_NEAR(file.materials[0].base_color.y, 0.184314, 1e-12);
  EXPECT_NEAR(file.materials[0].base_color.z, 0.411765, 1e-12);
  EXPECT_FALSE(has_warning(file, "not defined")) << all_warnings(file);
}

TEST(ObjReader, InvalidFilesOfThePackage) {
  REQUIRE_TEST_MODELS();
  expect_refused(kModels / "invalid/empty.obj", {"has no faces"});
  // malformed.obj: "f 4 12 2 1" (line 23) names a vertex the file does not have, "f 0 7 8 5" (line 28) vertex 0.
  // tinyobjloader stops at the second, so that is the one reported.
  expect_refused(kModels / "invalid/malformed.obj", {"line 28:", "vertex index is 0"});
  // malformed2.obj is box.obj with "usemtl DefaultDoesNotExist", a bare "f" and "o -1": nothing the reader refuses
  // in box.obj either (an undefined material is a warning there too; a statement with no vertices is skipped).
  const MeshFile file = read_mesh_file(kModels / "invalid/malformed2.obj");
  expect_well_formed(file);
  EXPECT_EQ(triangle_count(file), 10u);
  EXPECT_TRUE(has_warning(file, "material 'DefaultDoesNotExist' is not defined")) << all_warnings(file);
}

// ---------------------------------------------------------------------------------------------------------------
// OBJ: files written here

const std::string kTriangleObj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";

TEST(ObjReader, IndexOutOfRangeIsRefused) {
  test::TempDir dir;
  const auto refused = [&](const std::string& name, const std::string& text, const std::vector<std::string>& parts) {
    test::write_text_file(dir / name, text);
    expect_refused(dir / name, parts);
  };
  refused("triangle.obj", kTriangleObj + "f 1 2 3\nf 1 2 9\n", {"line 6: vertex index 9 out of range (the file has 4 vertices)"});
  // tinyobjloader drops a quadrilateral with such an index and only warns.
  refused("quad.obj", kTriangleObj + "f 1 2 3 4\nf 1 2 3 5\n", {"line 6: vertex index 5 out of range (the file has 4 vertices)"});
  refused("relative.obj", kTriangleObj + "f -1 -2 -5\n", {"line 5: vertex index -5 out of range (only 4 vertices before it)"});
  refused("normal.obj", kTriangleObj + "vn 0 0 1\nf 1//1 2//1 3//2\n", {"line 6: normal index 2 out of range (the file has 1 normals)"});
  refused("uv.obj", kTriangleObj + "vt 0 0\nf 1/1 2/3 3/1\n", {"line 6: texture coordinate index 3 out of range"});
  refused("zero.obj", kTriangleObj + "f 0 1 2\n", {"line 5: cannot read the 'f' statement"});
}

TEST(ObjReader, NonFiniteNumbersAreRefused) {
  test::TempDir dir;
  test::write_text_file(dir / "inf.obj", "v 0 0 0\nv 1e999 0 0\nv 0 1 0\nf 1 2 3\n");
  expect_refused(dir / "inf.obj", {"line 2: vertex position is not finite"});
  test::write_text_file(dir / "normal.obj", kTriangleObj + "vn 0 -1e400 0\nf 1//1 2//1 3//1\n");
  expect_refused(dir / "normal.obj", {"line 5: normal is not finite"});
}

TEST(ObjReader, FilesWithoutFacesAreRefused) {
  test::TempDir dir;
  test::write_text_file(dir / "lines.obj", kTriangleObj + "l 1 2 3 4\np 1 2\n");
  expect_refused(dir / "lines.obj", {"has no faces", "4 vertices, 1 lines, 2 points"});
  test::write_text_file(dir / "short.obj", kTriangleObj + "f 1 2\n");
  expect_refused(dir / "short.obj", {"has no faces"});
}

TEST(ObjReader, MissingMaterialLibraryOrTextureIsRefused) {
  test::TempDir dir;
  test::write_text_file(dir / "a.obj", "# comment\nmtllib missing.mtl\n" + kTriangleObj + "f 1 2 3\n");
  expect_refused(dir / "a.obj", {"line 2: material library", (dir / "missing.mtl").string(), "no such file"});
  test::write_text_file(dir / "b.mtl", "newmtl red\nKd 1 0 0\n\nnewmtl picture\nKd 1 1 1\nmap_Kd textures/absent.png\n");
  test::write_text_file(dir / "b.obj", "mtllib b.mtl\n" + kTriangleObj + "usemtl picture\nf 1 2 3\n");
  expect_refused(dir / "b.obj", {"b.mtl: line 4: material 'picture': map_Kd:", (dir / "textures/absent.png").string(), "does not exist"});
  // A FIFO where the library should be is refused at once, not read.
  ASSERT_EQ(::mkfifo((dir / "fifo.mtl").c_str(), 0600), 0);
  test::write_text_file(dir / "c.obj", "mtllib fifo.mtl\n" + kTriangleObj + "f 1 2 3\n");
  expect_refused(dir / "c.obj", {"line 1: material library", "FIFO"});
  ASSERT_EQ(::mkfifo((dir / "fifo.obj").c_str(), 0600), 0);
  expect_refused(dir / "fifo.obj", {"FIFO"});
  expect_refused(dir / "absent.obj", {"cannot open the OBJ file"});
}

// A model from elsewhere may name only files in its own folder and below: `mtllib ../../../../etc/passwd` was
// followed. The OBJ's folder bounds its libraries' textures too, links resolved.
TEST(ObjReader, FilesOutsideTheModelsFolderAreRefused) {
  test::TempDir dir;
  std::filesystem::create_directories(dir / "model/maps");
  LinearImage image;
  image.width = image.height = 1;
  image.rgb = {1, 0, 0};
  write_image(dir / "outside.png", image);
  write_image(dir / "model/inside.png", image);
  test::write_text_file(dir / "outside.mtl", "newmtl red\nKd 1 0 0\n");
  const std::string faces = kTriangleObj + "vt 0 0\nvt 1 0\nvt 1 1\nusemtl red\nf 1/1 2/2 3/3\n";

  const auto obj = [&](const std::string& name, const std::string& mtllib) {
    test::write_text_file(dir / "model" / name, "mtllib " + mtllib + "\n" + faces);
    return dir / "model" / name;
  };
  expect_refused(obj("up.obj", "../outside.mtl"),
                 {"line 1: material library", (dir / "model/../outside.mtl").string(), "outside the model's folder"});
  expect_refused(obj("absolute.obj", (dir / "outside.mtl").string()), {"line 1: material library", "outside the model's folder"});
  expect_refused(obj("passwd.obj", "../../../../../../../../etc/passwd"), {"line 1: material library", "outside the model's folder"});
  std::filesystem::create_symlink(dir / "outside.mtl", dir / "model/link.mtl");
  expect_refused(obj("link.obj", "link.mtl"), {"line 1: material library", "link.mtl", "outside the model's folder"});
  EXPECT_EQ(read_obj_file(dir / "model/up.obj", ModelReferences::kAnywhere).materials.size(), 1u) << "allowed where the user says so";

  // A library in a subfolder names textures relative to itself: up to the model's folder is inside, beyond is not.
  test::write_text_file(dir / "model/maps/in.mtl", "newmtl red\nmap_Kd ../inside.png\n");
  EXPECT_EQ(read_obj_file(obj("texture-in.obj", "maps/in.mtl")).textures.size(), 1u);
  test::write_text_file(dir / "model/maps/out.mtl", "newmtl red\nKd 1 1 1\nmap_Kd ../../outside.png\n");
  expect_refused(obj("texture-out.obj", "maps/out.mtl"), {"out.mtl: line 1: material 'red': map_Kd:", "outside.png", "outside the model's folder"});
  EXPECT_EQ(read_obj_file(dir / "model/texture-out.obj", ModelReferences::kAnywhere).textures.size(), 1u);
}

// The program refuses such a model on one line and exit 1, and reads it with --trust-model-paths.
TEST(ObjReader, TrustModelPathsLetsTheProgramReadOutsideTheFolder) {
  test::TempDir dir;
  std::filesystem::create_directories(dir / "model");
  test::write_text_file(dir / "outside.mtl", "newmtl red\nKd 1 0 0\n");
  test::write_text_file(dir / "model/m.obj", "mtllib ../outside.mtl\n" + kTriangleObj + "usemtl red\nf 1 2 3\nf 1 3 4\n");
  const std::string command = "render " + test::quoted(dir / "model/m.obj") + " --width 8 --height 8 --spp 1 -o " + test::quoted(dir / "m.pfm");
  const test::CommandResult refused = test::run_pathtracer(command, dir);
  EXPECT_EQ(refused.exit_code, 1);
  EXPECT_EQ(test::lines_of(refused.err).size(), 1u) << refused.err;
  EXPECT_NE(refused.err.find("outside the model's folder (--trust-model-paths lets a model read it)"), std::string::npos) << refused.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "m.pfm"));
  const test::CommandResult trusted = test::run_pathtracer(command + " --trust-model-paths", dir);
  EXPECT_EQ(trusted.exit_code, 0) << trusted.err;
  EXPECT_TRUE(std::filesystem::exists(dir / "m.pfm"));
}

TEST(ObjReader, MaterialsMapOntoBaseColourEmissionAndRoughness) {
  test::TempDir dir;
  LinearImage image;
  image.width = 2;
  image.height = 1;
  image.rgb = {1, 0, 0, 0, 0, 1};
  std::filesystem::create_directory(dir / "maps");
  write_image(dir / "maps/red-blue.png", image);
  write_image(dir / "glow.png", image);
  // Two libraries on one line, the second in a subfolder whose textures are found relative to it.
  test::write_text_file(dir / "one.mtl", "newmtl lamp\nKd 0.2 0.3 0.4\nKe 1 2 3\nPr 0.25\nPm 0.5\nmap_Ke glow.png\n");
  test::write_text_file(dir / "maps/two.mtl", "newmtl painted\nmap_Kd red-blue.png\nbump red-blue.png\n\nnewmtl unused\nmap_Kd nothing.png\n");
  test::write_text_file(dir / "m.obj", "mtllib one.mtl maps/two.mtl\n" + kTriangleObj +
                                           "vt 0 0\nvt 1 0\nvt 1 1\nf 1/1 2/2 3/3\nusemtl lamp\nf 1 3 4\nusemtl painted\nf 1/1 3/3 4/2\n");
  const MeshFile file = read_obj_file(dir / "m.obj");
  expect_well_formed(file);
  ASSERT_EQ(file.materials.size(), 3u);
  const MeshMaterial& lamp = file.materials[0];
  EXPECT_EQ(lamp.name, "lamp");
  // tinyobjloader sums a number's digits (0.3 is 3 * 0.1): within an ulp or two of the nearest double
  EXPECT_NEAR(lamp.base_color.x, 0.2, 1e-15);
  EXPECT_NEAR(lamp.base_color.y, 0.3, 1e-15);
  EXPECT_NEAR(lamp.base_color.z, 0.4, 1e-15);
  EXPECT_TRUE(same(lamp.emission, Vec3d{1, 2, 3}));
  EXPECT_EQ(lamp.roughness, 0.25);
  EXPECT_EQ(lamp.metallic, 0.5);
  EXPECT_EQ(lamp.base_color_texture, -1);
  ASSERT_GE(lamp.emission_texture, 0);
  const MeshMaterial& painted = file.materials[1];
  EXPECT_EQ(painted.name, "painted");
  EXPECT_TRUE(same(painted.base_color, Vec3d{1, 1, 1}));  // the texture as it is, without Kd
  EXPECT_TRUE(same(painted.emission, Vec3d{0, 0, 0}));
  EXPECT_EQ(painted.roughness, 1.0);
  EXPECT_EQ(painted.metallic, 0.0);
  ASSERT_GE(painted.base_color_texture, 0);
  EXPECT_NE(painted.base_color_texture, lamp.emission_texture);
  ASSERT_EQ(file.textures.size(), 2u);
  const TextureImage& texture = file.textures[static_cast<std::size_t>(painted.base_color_texture)];
  EXPECT_EQ(texture.width, 2u);
  EXPECT_EQ(texture.srgb, (std::vector<u8>{255, 0, 0, 0, 0, 255}));
  EXPECT_EQ(file.materials[2].name, "default");
  EXPECT_EQ(file.meshes[0].materials, (std::vector<u32>{2, 0, 1}));
  // red-blue.png is no normal map: a height map, which is not rendered, said with its line.
  EXPECT_TRUE(has_warning(file, "two.mtl: line 3: material 'painted': bump map 'red-blue.png' is a height map, not a tangent-space normal map"))
      << all_warnings(file);
  EXPECT_EQ(painted.normal_texture, -1);
  EXPECT_TRUE(has_warning(file, "some faces have texture coordinates and some not")) << all_warnings(file);
}

TEST(ObjReader, SpecularAndPbrStatementsChooseTheMetallicRoughnessModel) {
  // Kd alone: diffuse, as before. Pr or Pm: the metallic-roughness model with those values. Ks above 0 without them:
  // a dielectric whose roughness follows Ns (alpha = sqrt(2 / (Ns + 2)), roughness = sqrt(alpha)), warned of.
  test::TempDir dir;
  test::write_text_file(dir / "s.mtl",
                        "newmtl matte\nKd 0.5 0.5 0.5\nKs 0 0 0\nNs 50\n\n"
                        "newmtl shiny\nKd 0.5 0.5 0.5\nKs 0.5 0.5 0.5\nNs 98\n\n"
                        "newmtl metal\nKd 0.9 0.6 0.3\nPm 1\nPr 0.3\nKs 1 1 1\nNs 5\n");
  test::write_text_file(dir / "s.obj", "mtllib s.mtl\n" + kTriangleObj + "usemtl matte\nf 1 2 3\nusemtl shiny\nf 1 3 4\nusemtl metal\nf 2 3 4\n");
  const MeshFile file = read_obj_file(dir / "s.obj");
  ASSERT_EQ(file.materials.size(), 3u);
  EXPECT_FALSE(file.materials[0].metallic_roughness_model);
  EXPECT_TRUE(file.materials[1].metallic_roughness_model);
  EXPECT_EQ(file.materials[1].metallic, 0.0);
  EXPECT_NEAR(file.materials[1].roughness, std::sqrt(std::sqrt(0.02)), 1e-6);
  EXPECT_TRUE(file.materials[2].metallic_roughness_model);
  EXPECT_EQ(file.materials[2].metallic, 1.0);
  EXPECT_NEAR(file.materials[2].roughness, 0.3, 1e-6);  // Pr wins over Ns
  EXPECT_TRUE(has_warning(file, "specular highlights (Ks) take a dielectric's reflectance (F0 = 0.04), not the colour Ks gives (material 'shiny')"))
      << all_warnings(file);
}

TEST(ObjReader, NormalMapsFromNormOrFromABumpStatementThatHoldsOne) {
  test::TempDir dir;
  test::write_ppm(dir / "normals.ppm", 2, 1, {128, 128, 255, 200, 128, 230});
  test::write_ppm(dir / "height.ppm", 2, 1, {10, 10, 10, 200, 200, 200});
  test::write_text_file(dir / "n.mtl",
                        "newmtl normed\nKd 0.5 0.5 0.5\nnorm -bm 0.5 normals.ppm\n\n"
                        "newmtl bumped\nKd 0.5 0.5 0.5\nmap_Bump normals.ppm\n\n"
                        "newmtl heights\nKd 0.5 0.5 0.5\nbump height.ppm\n");
  test::write_text_file(dir / "n.obj", "mtllib n.mtl\n" + kTriangleObj + "usemtl normed\nf 1 2 3\nusemtl bumped\nf 1 3 4\nusemtl heights\nf 2 3 4\n");
  const MeshFile file = read_obj_file(dir / "n.obj");
  ASSERT_EQ(file.materials.size(), 3u);
  const MeshMaterial& normed = file.materials[0];
  ASSERT_GE(normed.normal_texture, 0);
  EXPECT_EQ(normed.normal_scale, 0.5);
  EXPECT_TRUE(normed.metallic_roughness_model);  // normal maps shade with the metallic-roughness model
  EXPECT_EQ(file.textures.at(static_cast<std::size_t>(normed.normal_texture)).srgb, (std::vector<u8>{128, 128, 255, 200, 128, 230}));
  EXPECT_EQ(file.materials[1].normal_texture, normed.normal_texture);  // the same image, read once
  EXPECT_EQ(file.materials[1].normal_scale, 1.0);
  EXPECT_EQ(file.materials[2].normal_texture, -1);
  EXPECT_FALSE(file.materials[2].metallic_roughness_model);
  EXPECT_TRUE(has_warning(file, "n.mtl: line 11: material 'heights': bump map 'height.ppm' is a height map, not a tangent-space normal map"))
      << all_warnings(file);
  EXPECT_EQ(file.warnings.size(), 1u) << all_warnings(file);
}

TEST(ObjReader, MetallicAndRoughnessMapsArePackedAsGltfDoes) {
  test::TempDir dir;
  test::write_ppm(dir / "metal.ppm", 2, 1, {0, 0, 0, 255, 255, 255});
  test::write_ppm(dir / "rough.ppm", 1, 1, {100, 100, 100});
  test::write_ppm(dir / "rough-green.ppm", 2, 1, {1, 50, 2, 3, 60, 4});
  test::write_text_file(dir / "p.mtl",
                        "newmtl both\nKd 0.5 0.5 0.5\nmap_Pm metal.ppm\nmap_Pr rough.ppm\n\n"
                        "newmtl scaled\nKd 0.5 0.5 0.5\nPr 0.5\nmap_Pr -imfchan g rough-green.ppm\nPm 0.25\n");
  test::write_text_file(dir / "p.obj", "mtllib p.mtl\n" + kTriangleObj + "usemtl both\nf 1 2 3\nusemtl scaled\nf 1 3 4\n");
  const MeshFile file = read_obj_file(dir / "p.obj");
  ASSERT_EQ(file.materials.size(), 2u);
  const MeshMaterial& both = file.materials[0];
  EXPECT_TRUE(both.metallic_roughness_model);
  ASSERT_GE(both.metallic_roughness_texture, 0);
  // Roughness in green (the 1x1 image spread over the larger width), metallic in blue; the maps as they are.
  EXPECT_EQ(file.textures.at(static_cast<std::size_t>(both.metallic_roughness_texture)).srgb, (std::vector<u8>{0, 100, 0, 0, 100, 255}));
  EXPECT_EQ(both.metallic, 1.0);
  EXPECT_EQ(both.roughness, 1.0);
  // A constant beside its map multiplies it; a constant alone fills its channel (the factor says how much).
  const MeshMaterial& scaled = file.materials[1];
  ASSERT_GE(scaled.metallic_roughness_texture, 0);
  EXPECT_EQ(file.textures.at(static_cast<std::size_t>(scaled.metallic_roughness_texture)).srgb, (std::vector<u8>{0, 50, 255, 0, 60, 255}));
  EXPECT_EQ(scaled.roughness, 0.5);
  EXPECT_EQ(scaled.metallic, 0.25);
  EXPECT_TRUE(file.warnings.empty()) << all_warnings(file);
}

TEST(ObjReader, MissingNormalOrMetallicMapIsRefusedWithItsLine) {
  test::TempDir dir;
  test::write_text_file(dir / "a.mtl", "newmtl first\nKd 1 0 0\n\nnewmtl bumpy\nKd 1 1 1\nPr 0.3\nnorm maps/absent.png\n");
  test::write_text_file(dir / "a.obj", "mtllib a.mtl\n" + kTriangleObj + "usemtl bumpy\nf 1 2 3\n");
  expect_refused(dir / "a.obj", {"a.mtl: line 7: material 'bumpy': norm:", (dir / "maps/absent.png").string(), "does not exist"});
  test::write_text_file(dir / "b.mtl", "newmtl shiny\nmap_Pm gone.png\n");
  test::write_text_file(dir / "b.obj", "mtllib b.mtl\n" + kTriangleObj + "usemtl shiny\nf 1 2 3\n");
  expect_refused(dir / "b.obj", {"b.mtl: line 2: material 'shiny': map_Pm:", "gone.png", "does not exist"});
  test::write_text_file(dir / "c.mtl", "newmtl bumpy\nmap_Bump not-an-image.png\n");
  test::write_text_file(dir / "not-an-image.png", "text\n");
  test::write_text_file(dir / "c.obj", "mtllib c.mtl\n" + kTriangleObj + "usemtl bumpy\nf 1 2 3\n");
  expect_refused(dir / "c.obj", {"c.mtl: line 2: material 'bumpy': map_Bump:", "not-an-image.png"});
}

TEST(ObjReader, CornersAreUnifiedAcrossPositionNormalAndUvIndices) {
  test::TempDir dir;
  // Two groups: a square with one normal (4 vertices), then a triangle reusing positions with other normals.
  test::write_text_file(dir / "u.obj", kTriangleObj +
                                           "vn 0 0 2\nvn 1 0 0\nvt 0 0\nvt 1 1\n"
                                           "o square\nf 1/1/1 2/1/1 3/2/1 4/2/1\n"
                                           "g other\nf -4/-2/-1 -3/-2/-1 -2/-1/-2\nf 1/1/2 2/1/2 4/2/1\n");
  const MeshFile file = read_obj_file(dir / "u.obj");
  expect_well_formed(file);
  ASSERT_EQ(file.meshes.size(), 2u);
  EXPECT_EQ(file.meshes[0].name, "square");
  EXPECT_EQ(file.meshes[1].name, "other");
  EXPECT_EQ(file.meshes[0].positions.size(), 4u);
  EXPECT_EQ(file.meshes[0].triangles.size(), 2u);
  for (const Vec3d& n : file.meshes[0].normals) EXPECT_TRUE(same(n, Vec3d{0, 0, 1}));
  // -4/-2/-1 is 1/1/2 and -3/-2/-1 is 2/1/2: both faces of "other" share them.
  const TriangleMesh& other = file.meshes[1];
  EXPECT_EQ(other.positions.size(), 4u);
  EXPECT_EQ(other.triangles, (std::vector<std::array<u32, 3>>{{0, 1, 2}, {0, 1, 3}}));
  EXPECT_TRUE(same(other.normals[0], Vec3d{1, 0, 0}));
  EXPECT_TRUE(same(other.normals[2], Vec3d{0, 0, 1}));
  EXPECT_EQ(other.uvs[2], (std::array<double, 2>{1, 1}));
  EXPECT_TRUE(same(other.positions[3], Vec3d{0, 1, 0}));
}

TEST(ObjReader, TinyobjloaderExtensionsAreSkipped) {
  test::TempDir dir;
  // Skin weights whose joint does not fit an int (tinyobjloader would convert it unchecked), and subdivision tags
  // of the most values it allows (it would copy them all into every mesh after them): neither is read.
  std::string text = kTriangleObj + "vw 0 1e300 0.5\n";
  for (int i = 0; i < 10; ++i) text += "t crease 8192/8192/8192\n";
  for (int i = 0; i < 10; ++i) text += fmt::format("g part{}\nf 1 2 3\n", i);
  test::write_text_file(dir / "x.obj", text);
  const MeshFile file = read_obj_file(dir / "x.obj");
  expect_well_formed(file);
  EXPECT_EQ(file.meshes.size(), 10u);
  EXPECT_EQ(file.meshes[9].name, "part9");
}

TEST(ObjReader, NumbersAsTinyobjloaderReadsThem) {
  test::TempDir dir;
  // Exponents with and without signs, leading dots and plus signs; "3.1+e2" reads as its leading number.
  test::write_text_file(dir / "n.obj", "v 1e2 2.e1 3.1e2\nv +1E+2 -.5 3.1+e2\nv -1e-2 +2. 1e10\nf 1 2 3\n");
  const MeshFile file = read_obj_file(dir / "n.obj");
  const std::vector<Vec3d> expected = {{100, 20, 310}, {100, -0.5, 3.1}, {-0.01, 2, 1e10}};
  ASSERT_EQ(file.meshes[0].positions.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) EXPECT_NEAR(length(file.meshes[0].positions[i] - expected[i]), 0, 1e-14 * length(expected[i])) << i;
}

}  // namespace
}  // namespace pt
