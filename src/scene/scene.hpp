// The parsed scene: what a scene file says, in double precision on the host, before it is flattened for kernels.
#pragma once

#include <array>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

#include "base/errors.hpp"
#include "base/render_settings.hpp"
#include "kernel/material.hpp"
#include "kernel/shapes.hpp"
#include "kernel/scene_view.hpp"

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

using ObjectShape = std::variant<Sphere<double>, MovingSphereSettings, TriangleSettings, QuadSettings, BoxSettings, MediumSettings>;

struct SceneObject {
  ObjectShape shape;
  RigidTransform transform;
  u32 material = 0;
};

// Where the parts of a parsed scene were written, so that checks made after parsing (flatten_scene) can name a value
// as the parser does, FILE:LINE:COLUMN: /json/path (source_position in scene/scene_loader.hpp). Object i is
// always "/objects/i" and the camera "/camera"; textures and materials, written inline or under a name, are
// listed here. Empty for scenes made in code.
struct SceneSourceMap {
  std::shared_ptr<const std::string> text;  // the scene file's text, where lines and columns are looked up
  std::vector<std::string> textures;        // per texture its JSON path; for a solid texture, that of its colour array
  std::vector<std::string> materials;       // per material its JSON path (under /materials, or inline in an object)
  std::string horizon = "/background/horizon", zenith = "/background/zenith";  // the background's two colours
};

struct SceneDescription {
  std::string source;  // the file it came from, for messages
  SceneSourceMap written;  // where its parts were written in that file
  RenderSettings render;
  CameraSettings camera;
  Background<double> background{{1, 1, 1}, {0.5, 0.7, 1.0}};
  std::vector<Texture<double>> textures;
  std::vector<u8> texels;  // every image texture's sRGB-encoded RGB texels (TextureImage), one after another
  std::vector<Material<double>> materials;
  std::vector<SceneObject> objects;
};

}  // namespace pt
