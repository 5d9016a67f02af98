// The parsed scene: what a scene file says, in double precision on the host, before it is flattened for kernels.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <deque>
#include <filesystem>
#include <iterator>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <tuple>
#include <unordered_map>
#include <utility>
#include <variant>
#include <vector>

#include "base/errors.hpp"
#include "base/render_settings.hpp"
#include "kernel/material.hpp"
#include "kernel/scene_view.hpp"
#include "kernel/shapes.hpp"

namespace pt {

using Vec3d = Vec3<double>;

struct CameraSettings {
  Vec3d look_from;
  Vec3d look_at;
  Vec3d up{0, 1, 0};
  double vertical_fov = 40;
  double aperture = 0;
  double focus_distance = 0;  // 0: the distance from look_from to look_at
  double shutter_open = 0, shutter_close = 1;
};

// A rigid motion: rotation (a 3x3 matrix) followed by a translation.
struct RigidTransform {
  double rotation[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  Vec3d translation{};

  static RigidTransform from_euler_degrees(const Vec3d& degrees, const Vec3d& translation);
  Vec3d apply_vector(const Vec3d& v) const;
  Vec3d apply_point(const Vec3d& p) const { return apply_vector(p) + translation; }
  RigidTransform then(const RigidTransform& outer) const;  // this first, then outer
  bool is_identity() const;
};

// A general affine map x -> linear x + translation: meshes are scaled and sheared as well as rotated.
struct AffineTransform {
  double linear[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  Vec3d translation{};

  static AffineTransform from_rigid(const RigidTransform& rigid);
  static AffineTransform scaling(const Vec3d& factors);
  // From a column-major 4x4 matrix whose last row is 0 0 0 1 (glTF's `matrix`).
  static AffineTransform from_column_major(const double m[16]);
  Vec3d apply_point(const Vec3d& p) const { return apply_vector(p) + translation; }
  Vec3d apply_vector(const Vec3d& v) const;
  Vec3d apply_normal(const Vec3d& n) const;                  // by the inverse transpose times the determinant's sign, not normalised
  AffineTransform then(const AffineTransform& outer) const;  // this first, then outer
  AffineTransform inverse() const;                           // of an invertible map (determinant != 0)
  double determinant() const;
  bool is_identity() const;
};

struct MovingSphereSettings {
  Vec3d center0, center1;
  double radius;
  double time0, time1;
};

struct TriangleSettings {
  std::array<Vec3d, 3> vertices;
  std::optional<std::array<Vec3d, 3>> normals;
  std::optional<std::array<std::array<double, 2>, 3>> uvs;
};

struct QuadSettings {
  Vec3d corner, u, v;
};

struct BoxSettings {
  Vec3d min, max;
};

struct MediumSettings {
  std::variant<Sphere<double>, BoxSettings> boundary;
  RigidTransform boundary_transform;
  double density;
};

// The meshes of a model file (SceneDescription::mesh_files), placed by an affine map after the file's own placements.
struct MeshSettings {
  u32 file;
  AffineTransform transform;
};

using ObjectShape = std::variant<Sphere<double>, MovingSphereSettings, TriangleSettings, QuadSettings, BoxSettings, MediumSettings, MeshSettings>;

// `material` indexes SceneDescription::materials; a mesh object without a material of its own has kMeshMaterials
// (kernel/shapes.hpp): its triangles keep the model file's materials.
struct SceneObject {
  ObjectShape shape;
  RigidTransform transform;  // the identity for a mesh, which carries its own
  u32 material = 0;
};

// A scene's objects, stored compactly: a SceneObject is as large as its largest shape plus a transform (320 bytes),
// while a scene of millions of objects is mostly spheres or triangles without a transform. Each shape kind has its
// own store, each transform other than the identity is stored once, and an object is a 16-byte record pointing into
// them: a sphere costs 48 bytes. Blocks of a std::deque grow without copying, so loading never holds a list twice.
// Objects are read by value (operator[], iteration) and changed with set().
class ObjectList {
 public:
  std::size_t size() const { return records_.size(); }
  bool empty() const { return records_.empty(); }
  void reserve(std::size_t count) { records_.reserve(count); }

  void push_back(const SceneObject& object) { records_.push_back(store(object)); }
  void set(std::size_t i, const SceneObject& object) { records_[i] = store(object); }  // the old shape's slot is left unused

  SceneObject operator[](std::size_t i) const {
    const Record& r = records_[i];
    SceneObject object;
    object.shape = load(r.shape, r.slot, std::make_index_sequence<std::variant_size_v<ObjectShape>>{});
    if (r.transform != kIdentity) object.transform = transforms_[r.transform];
    object.material = r.material;
    return object;
  }

  class Iterator {
   public:
    using iterator_category = std::input_iterator_tag;
    using value_type = SceneObject;
    using difference_type = std::ptrdiff_t;
    using pointer = void;
    using reference = SceneObject;
    Iterator(const ObjectList* list, std::size_t i) : list_(list), i_(i) {}
    SceneObject operator*() const { return (*list_)[i_]; }
    Iterator& operator++() {
      ++i_;
      return *this;
    }
    bool operator==(const Iterator& other) const { return i_ == other.i_; }
    bool operator!=(const Iterator& other) const { return i_ != other.i_; }

   private:
    const ObjectList* list_;
    std::size_t i_;
  };
  Iterator begin() const { return {this, 0}; }
  Iterator end() const { return {this, records_.size()}; }

 private:
  static constexpr u32 kIdentity = ~0u;
  struct Record {
    u32 slot;       // index in the store of its shape kind
    u32 transform;  // index in transforms_, or kIdentity
    u32 material;
    u8 shape;  // the ObjectShape alternative
  };
  template <class Variant>
  struct StoresOf;
  template <class... Shapes>
  struct StoresOf<std::variant<Shapes...>> {
    using type = std::tuple<std::deque<Shapes>...>;
  };

  Record store(const SceneObject& object) {
    Record r{};
    r.shape = static_cast<u8>(object.shape.index());
    std::visit(
        [&](const auto& shape) {
          auto& shapes = std::get<std::deque<std::decay_t<decltype(shape)>>>(stores_);
          r.slot = static_cast<u32>(shapes.size());
          shapes.push_back(shape);
        },
        object.shape);
    r.transform = kIdentity;
    if (!object.transform.is_identity()) {
      r.transform = static_cast<u32>(transforms_.size());
      transforms_.push_back(object.transform);
    }
    r.material = object.material;
    return r;
  }

  template <std::size_t... I>
  ObjectShape load(u8 shape, u32 slot, std::index_sequence<I...>) const {
    ObjectShape out;
    (void)((shape == I ? (out.template emplace<I>(std::get<I>(stores_)[slot]), true) : false) || ...);
    return out;
  }

  std::vector<Record> records_;
  typename StoresOf<ObjectShape>::type stores_;
  std::deque<RigidTransform> transforms_;
};

// Where the parts of a parsed scene were written, so that checks made after parsing (flatten_scene) can name a value
// as the parser does, FILE:LINE:COLUMN: /json/path (source_position below). Object i is
// always "/objects/i" and the camera "/camera"; textures and materials, written inline or under a name, are
// listed here. Empty for scenes made in code.
// A list of JSON paths, each 8 bytes: a path is a pattern (kept once) and the number of its first numeric part, so
// that a scene of a million inline materials ("/objects/N/material", "/objects/N/material/albedo") keeps two
// patterns and a number each, where the paths' characters took about 60 bytes a material.
class JsonPathList {
 public:
  void push_back(std::string_view path) {
    // The first part that is a decimal index ("/12/": digits, no leading zero, below 2^32 - 1) becomes the number.
    std::size_t at = 0, digits = 0;
    u32 number = kNoNumber;
    for (std::size_t begin = 0; begin < path.size(); ) {
      const std::size_t end = std::min(path.find('/', begin + 1), path.size());
      const std::string_view part = path.substr(begin + 1, end - begin - 1);
      if (begin < path.size() && path[begin] == '/' && !part.empty() && part.size() <= 9 && (part.size() == 1 || part[0] != '0') &&
          std::all_of(part.begin(), part.end(), [](char c) { return c >= '0' && c <= '9'; })) {
        number = 0;
        for (const char c : part) number = number * 10 + static_cast<u32>(c - '0');
        at = begin + 1;
        digits = part.size();
        break;
      }
      begin = end;
    }
    std::string text = number == kNoNumber ? std::string(path) : std::string(path.substr(0, at)) + std::string(path.substr(at + digits));
    const u32 place = static_cast<u32>(number == kNoNumber ? text.size() : at);
    // The number's place is part of the pattern: "/a/1/" and "/a//1" without their numbers are both "/a//".
    auto [it, added] = pattern_index_.emplace(std::to_string(place) + ':' + text, static_cast<u32>(patterns_.size()));
    if (added) patterns_.push_back(Pattern{std::move(text), place});
    entries_.push_back(Entry{it->second, number});
  }
  std::size_t size() const { return entries_.size(); }
  std::string operator[](std::size_t i) const {
    const Entry& e = entries_[i];
    const Pattern& p = patterns_[e.pattern];
    if (e.number == kNoNumber) return p.text;
    return p.text.substr(0, p.at) + std::to_string(e.number) + p.text.substr(p.at);
  }

 private:
  static constexpr u32 kNoNumber = ~0u;
  struct Entry {
    u32 pattern;
    u32 number;
  };
  struct Pattern {
    std::string text;  // the path without its number
    u32 at;            // where the number goes
  };
  std::vector<Entry> entries_;
  std::vector<Pattern> patterns_;
  std::unordered_map<std::string, u32> pattern_index_;
};

struct SceneSourceMap {
  // The scene's text, where lines and columns are looked up; for a scene read from a file, let go once it is parsed
  // (a large scene's text is hundreds of megabytes) and read again from `file` when a message needs a place.
  std::shared_ptr<const std::string> text;
  std::filesystem::path file;
  JsonPathList textures;   // per texture its JSON path; for a solid texture, that of its colour array
  JsonPathList materials;  // per material its JSON path (under /materials, or inline in an object)
  std::string horizon = "/background/horizon", zenith = "/background/zenith";  // the background's two colours
  std::string environment = "/background/file";                                // the environment image
};

// An environment image as read (image/image_io.hpp, read_environment_image), with what the scene says about it.
struct EnvironmentSettings {
  u32 width = 0, height = 0;
  std::vector<float> rgb;   // linear RGB, 3 floats a texel, rows from the top; finite and not negative
  double strength = 1;      // multiplies every texel
  RigidTransform rotation;  // turns the image's frame into the world's
};

struct MeshFile;  // scene/mesh.hpp

// A model file a scene places, read once however often it is placed; its materials were added to the scene's.
struct SceneMeshFile {
  std::shared_ptr<const MeshFile> file;
  std::vector<u32> materials;  // per material of the file, its index in SceneDescription::materials
};

struct SceneDescription {
  std::string source;      // the file it came from, for messages
  SceneSourceMap written;  // where its parts were written in that file
  RenderSettings render;
  CameraSettings camera;
  bool model_as_scene = false;                                    // read from a model file given as the scene: its values have no JSON paths
  bool camera_frames_model = false;                               // the camera was placed to frame that model: it was not written
  Background<double> background{{1, 1, 1}, {0.5, 0.7, 1.0}, {}};  // the gradient (its environment part is unused here)
  std::optional<EnvironmentSettings> environment;                 // in place of the gradient when present
  std::vector<Texture<double>> textures;
  std::vector<u8> texels;  // every image texture's sRGB-encoded RGB texels (TextureImage), one after another
  std::vector<Material<double>> materials;
  ObjectList objects;
  std::vector<SceneMeshFile> mesh_files;
  std::vector<std::string> warnings;  // what is read but not rendered (a model file's unsupported features), one line each
};

// "FILE:LINE:COLUMN" of the value at the JSON path `pointer` in the file the scene was read from, or "FILE" where
// that is unknown (a scene made in code, or a path not in the file). For messages about values found unfit after
// parsing (by flattening, say); it reads the text again, so it is meant for errors only.
std::string source_position(const SceneDescription& scene, const std::string& pointer);

}  // namespace pt
