// glTF 2.0 model files (.gltf with external or embedded buffers, .glb) -> MeshFile, through tinygltf.
//
// The steps: the file is opened as every input is (regular files only) and its bytes split into JSON and BIN here;
// the JSON is checked whole by gltf_json_check (types, ranges, references, byte ranges, the node hierarchy,
// required extensions), each fault with its JSON path; tinygltf then reads the same bytes, with file callbacks that
// read only regular files in the model's folder and an image callback that decodes nothing; last, the model is
// converted here: the scene's node tree into placements, each placed mesh into one TriangleMesh (its primitives'
// triangles with a material each), the materials its primitives use, and the images those materials use, decoded
// by the project's texture reader. docs/model-files-gltf.md describes the mapping, the refusals and the warnings.
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <numbers>
#include <set>
#include <string_view>
#include <tuple>

#include <fmt/format.h>
#include <tiny_gltf.h>
#include <nlohmann/json.hpp>

#include "base/errors.hpp"
#include "base/input_file.hpp"
#include "loading/gltf_json_check.hpp"
#include "loading/json_outline.hpp"
#include "loading/model_files.hpp"

namespace pt {

namespace {

// tinygltf takes a file's length as an unsigned int, and a .glb's header holds it in 32 bits: a model file and each
// buffer file it names are at most 4 GiB - 1.
constexpr u64 kMaxGltfFileBytes = std::numeric_limits<u32>::max();

constexpr u32 kGlbMagic = 0x46546C67;      // "glTF"
constexpr u32 kGlbJsonChunk = 0x4E4F534A;  // "JSON"
constexpr u32 kGlbBinChunk = 0x004E4942;   // "BIN\0"

u32 load_le32(const unsigned char* p) { return u32{p[0]} | (u32{p[1]} << 8) | (u32{p[2]} << 16) | (u32{p[3]} << 24); }
u32 load_le16(const unsigned char* p) { return u32{p[0]} | (u32{p[1]} << 8); }

// Reads the whole of an opened regular file into `out`, at most kMaxGltfFileBytes. Returns an empty string, or what
// went wrong.
template <class Bytes>
std::string read_input(InputFile& input, const std::string& path, Bytes& out) {
  struct stat status {};
  if (::fstat(input.descriptor(), &status) != 0) return fmt::format("cannot read '{}': {}", path, std::strerror(errno));
  if (static_cast<u64>(status.st_size) > kMaxGltfFileBytes)
    return fmt::format("'{}' has {} bytes, more than a glTF file or buffer may have ({})", path, status.st_size, kMaxGltfFileBytes);
  out.resize(static_cast<std::size_t>(status.st_size));
  std::size_t got = 0;
  while (got < out.size()) {
    const ssize_t n = ::read(input.descriptor(), reinterpret_cast<char*>(out.data()) + got, out.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return fmt::format("cannot read '{}': {}", path, std::strerror(errno));
    if (n == 0) break;
    got += static_cast<std::size_t>(n);
  }
  if (got != out.size()) return fmt::format("'{}' changed while it was read", path);
  return {};
}

// What tinygltf's callbacks know: files are read from the model's folder only (tinygltf also looks in the working
// folder), and the external images are left to the reader.
struct FileAccess {
  std::string folder_prefix;
  std::set<std::string> skipped;  // the external images
  std::string error;              // the first failure, said better than tinygltf says it
};

bool file_exists(const std::string& path, void* user) {
  const FileAccess& access = *static_cast<const FileAccess*>(user);
  if (path.compare(0, access.folder_prefix.size(), access.folder_prefix) != 0) return false;
  if (access.skipped.count(path) != 0) return false;  // tinygltf then keeps the image's URI, and goes on
  struct stat status {};
  return ::stat(path.c_str(), &status) == 0;
}

std::string expand_file_path(const std::string& path, void*) { return path; }

bool read_whole_file(std::vector<unsigned char>* out, std::string* err, const std::string& path, void* user) {
  FileAccess& access = *static_cast<FileAccess*>(user);
  InputFile input = InputFile::open(path);
  std::string problem;
  switch (input.problem()) {
    case InputFile::Problem::kNone: problem = read_input(input, path, *out); break;
    case InputFile::Problem::kMissing: problem = fmt::format("'{}' does not exist", path); break;
    case InputFile::Problem::kFolder: problem = fmt::format("'{}' is a folder, not a file", path); break;
    case InputFile::Problem::kNotRegular: problem = fmt::format("'{}' is {}, not a regular file", path, input.reason()); break;
    case InputFile::Problem::kCannotOpen: problem = fmt::format("cannot open '{}': {}", path, input.reason()); break;
  }
  if (problem.empty()) return true;
  if (access.error.empty()) access.error = problem;
  if (err) *err += problem;
  return false;
}

bool write_whole_file(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
  if (err) *err += "files are not written";
  return false;
}

// Decodes nothing: images are decoded by the reader, and only those a material uses. A data URI's bytes are kept
// (tinygltf frees them); an image in a buffer view is read from its buffer later, an external one from its file.
bool keep_image_bytes(tinygltf::Image* image, const int, std::string* err, std::string*, int, int, const unsigned char* bytes, int size, void*) {
  if (image->bufferView >= 0 || !image->uri.empty()) return true;
  if (!bytes || size <= 0) {
    if (err) *err += "an empty image";
    return false;
  }
  image->image.assign(bytes, bytes + size);
  return true;
}

// A .glb's two chunks, checked as tinygltf checks them (and a little more: the BIN chunk's header is counted).
struct GlbParts {
  std::size_t json_offset = 0, json_length = 0;
  std::optional<u64> bin_length;
};

GlbParts split_glb(const std::string& name, const std::string& bytes) {
  const auto data = reinterpret_cast<const unsigned char*>(bytes.data());
  const auto fail = [&](const std::string& problem) { throw InputError(fmt::format("{}: not a valid .glb: {}", name, problem)); };
  if (bytes.size() < 20) fail(fmt::format("{} bytes are too few for its header and a JSON chunk", bytes.size()));
  const u32 version = load_le32(data + 4), length = load_le32(data + 8);
  if (version != 2) fail(fmt::format("binary glTF version {} is not read (only version 2)", version));
  if (length > bytes.size()) fail(fmt::format("its header gives a length of {} bytes, but the file has {}", length, bytes.size()));
  const u64 json_length = load_le32(data + 12);
  if (load_le32(data + 16) != kGlbJsonChunk) fail("its first chunk is not JSON");
  const u64 json_end = 20 + json_length;
  if (json_length == 0 || json_end > length) fail(fmt::format("its JSON chunk of {} bytes does not fit in the file's {}", json_length, length));
  if (json_end % 4 != 0) fail(fmt::format("its JSON chunk of {} bytes does not end on a 4-byte boundary", json_length));
  GlbParts parts{20, static_cast<std::size_t>(json_length), std::nullopt};
  if (json_end == length) return parts;
  if (length - json_end < 12) fail(fmt::format("{} bytes after the JSON chunk are too few for a BIN chunk", length - json_end));
  const u64 bin_length = load_le32(data + json_end);
  if (load_le32(data + json_end + 4) != kGlbBinChunk) fail("its second chunk is not BIN");
  if (bin_length < 4 || bin_length % 4 != 0) fail(fmt::format("its BIN chunk of {} bytes is not a positive multiple of 4", bin_length));
  if (json_end + 8 + bin_length > length) fail(fmt::format("its BIN chunk of {} bytes does not fit in the file's {}", bin_length, length));
  parts.bin_length = bin_length;
  return parts;
}

const char* component_type_name(int type) {
  switch (type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: return "bytes";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return "unsigned bytes";
    case TINYGLTF_COMPONENT_TYPE_SHORT: return "shorts";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return "unsigned shorts";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return "unsigned ints";
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return "floats";
    default: return "components of an unknown type";
  }
}

const char* type_name(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR: return "SCALAR";
    case TINYGLTF_TYPE_VEC2: return "VEC2";
    case TINYGLTF_TYPE_VEC3: return "VEC3";
    case TINYGLTF_TYPE_VEC4: return "VEC4";
    case TINYGLTF_TYPE_MAT2: return "MAT2";
    case TINYGLTF_TYPE_MAT3: return "MAT3";
    case TINYGLTF_TYPE_MAT4: return "MAT4";
    default: return "of an unknown type";
  }
}

const char* mode_name(int mode) {
  switch (mode) {
    case TINYGLTF_MODE_POINTS: return "POINTS";
    case TINYGLTF_MODE_LINE: return "LINES";
    case TINYGLTF_MODE_LINE_LOOP: return "LINE_LOOP";
    case TINYGLTF_MODE_LINE_STRIP: return "LINE_STRIP";
    case TINYGLTF_MODE_TRIANGLES: return "TRIANGLES";
    case TINYGLTF_MODE_TRIANGLE_STRIP: return "TRIANGLE_STRIP";
    case TINYGLTF_MODE_TRIANGLE_FAN: return "TRIANGLE_FAN";
    default: return "an unknown mode";
  }
}

// The elements of one accessor, where they lie in their buffer.
struct Elements {
  const unsigned char* data = nullptr;
  std::size_t count = 0, stride = 0;
  int component_type = 0, components = 0;
  bool normalized = false;

  std::size_t component_size() const {
    switch (component_type) {
      case TINYGLTF_COMPONENT_TYPE_BYTE:
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
      case TINYGLTF_COMPONENT_TYPE_SHORT:
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
      default: return 4;
    }
  }

  // Component c of element i, as a double (normalized integers in [0, 1] or [-1, 1]).
  double component(std::size_t i, int c) const {
    const unsigned char* p = data + i * stride + static_cast<std::size_t>(c) * component_size();
    switch (component_type) {
      case TINYGLTF_COMPONENT_TYPE_FLOAT: return static_cast<double>(std::bit_cast<float>(load_le32(p)));
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return normalized ? p[0] / 255.0 : p[0];
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return normalized ? load_le16(p) / 65535.0 : load_le16(p);
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return load_le32(p);
      case TINYGLTF_COMPONENT_TYPE_BYTE: {
        const double v = static_cast<std::int8_t>(p[0]);
        return normalized ? std::max(v / 127.0, -1.0) : v;
      }
      case TINYGLTF_COMPONENT_TYPE_SHORT: {
        const double v = static_cast<std::int16_t>(load_le16(p));
        return normalized ? std::max(v / 32767.0, -1.0) : v;
      }
      default: return 0;
    }
  }

  u32 index(std::size_t i) const {
    const unsigned char* p = data + i * stride;
    switch (component_type) {
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return p[0];
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return load_le16(p);
      default: return load_le32(p);
    }
  }
};

// The vertex data of one combination of accessors (POSITION, NORMAL, TEXCOORD), read once per mesh.
struct VertexSource {
  std::vector<Vec3d> positions;
  std::vector<Vec3d> normals;                   // empty: none, or refused (not unit-length-able)
  std::vector<std::array<double, 2>> uvs;       // empty: none
  std::vector<std::array<double, 4>> tangents;  // empty: none, not asked for (no normal map), or refused
  std::int64_t base = -1;                       // where it starts in the mesh's arrays, once placed there
};

class Converter {
 public:
  Converter(const tinygltf::Model& model, const std::string& name, const std::string& folder_prefix, MeshFile& out)
      : model_(model), name_(name), folder_prefix_(folder_prefix), out_(out) {}

  void run(const gltf::JsonFacts& facts) {
    for (const std::string& extension : facts.extensions_not_read) {
      std::string what = "its effect is not rendered";
      if (extension == "KHR_draco_mesh_compression")
        what = "Draco-compressed meshes are not decoded; their uncompressed fallback is read";
      else if (extension == "KHR_texture_transform")
        what = "texture transforms are not applied";
      else if (extension == "KHR_lights_punctual")
        what = "its lights are not placed";
      else if (extension == "KHR_materials_variants")
        what = "the default materials are used";
      warn("extension " + extension, fmt::format("extension {} is not read: {}", extension, what));
    }
    if (!model_.animations.empty()) warn("animations", "animations are not played: nodes keep their transforms as written");
    if (!model_.skins.empty()) warn("skins", "skins are not applied: skinned meshes are drawn as stored (their bind pose), placed by their nodes");
    traverse();
    convert_meshes();
    if (out_.materials.empty()) out_.materials.push_back(gltf_default_material());
    if (undrawn_ > 0) {
      std::string modes;
      for (const std::string& m : undrawn_modes_) modes += (modes.empty() ? "" : ", ") + m;
      warn("modes", fmt::format("points and lines are not rendered: {} primitives of mode {}", undrawn_, modes));
    }
    if (singular_placements_ > 0)
      warn("singular",
           fmt::format("{} placements of meshes by nodes whose transform is singular (a scale of 0) are not drawn", singular_placements_));
  }

 private:
  [[noreturn]] void fail(const std::string& path, const std::string& problem) const {
    throw InputError(fmt::format("{}: {}: {}", name_, path, problem));
  }

  // One warning for each kind of thing (`key`), one line whatever names from the file it quotes.
  void warn(const std::string& key, const std::string& message) {
    if (warned_.insert(key).second) out_.warnings.push_back(escape_control_characters(message));
  }

  // A transform that places a mesh: finite and invertible.
  // Whether a transform's entries and its determinant (the factor by which it scales volumes) are finite.
  static bool finite_transform(const AffineTransform& t) {
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        if (!std::isfinite(t.linear[i][j])) return false;
    return is_finite(t.translation) && std::isfinite(t.determinant());
  }

  // A node's own transform: its matrix, or T * R * S.
  static AffineTransform local_transform(const tinygltf::Node& node) {
    if (node.matrix.size() == 16) return AffineTransform::from_column_major(node.matrix.data());
    AffineTransform t;
    double x = 0, y = 0, z = 0, w = 1;
    if (node.rotation.size() == 4) {
      x = node.rotation[0], y = node.rotation[1], z = node.rotation[2], w = node.rotation[3];
      const double norm = std::sqrt(x * x + y * y + z * z + w * w);  // not zero: checked
      x /= norm, y /= norm, z /= norm, w /= norm;
    }
    const double r[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)},
                            {2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)},
                            {2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)}};
    const double s[3] = {node.scale.size() == 3 ? node.scale[0] : 1.0, node.scale.size() == 3 ? node.scale[1] : 1.0,
                         node.scale.size() == 3 ? node.scale[2] : 1.0};
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) t.linear[i][j] = r[i][j] * s[j];
    if (node.translation.size() == 3) t.translation = {node.translation[0], node.translation[1], node.translation[2]};
    return t;
  }

  // The scene's node trees, depth first, each child after its parent and before its next sibling: placements of
  // meshes, and the first perspective camera. The hierarchy is a forest (checked), so each node is visited once.
  void traverse() {
    std::vector<int> roots;
    if (model_.defaultScene >= 0 || !model_.scenes.empty()) {
      const int scene = model_.defaultScene >= 0 ? model_.defaultScene : 0;
      roots = model_.scenes[static_cast<std::size_t>(scene)].nodes;
    } else {
      std::vector<char> is_child(model_.nodes.size(), 0);
      for (const tinygltf::Node& node : model_.nodes)
        for (const int child : node.children) is_child[static_cast<std::size_t>(child)] = 1;
      for (std::size_t i = 0; i < model_.nodes.size(); ++i)
        if (!is_child[i]) roots.push_back(static_cast<int>(i));
    }
    std::vector<std::pair<int, AffineTransform>> stack;
    for (auto it = roots.rbegin(); it != roots.rend(); ++it) stack.emplace_back(*it, AffineTransform{});
    while (!stack.empty()) {
      const auto [index, parent] = stack.back();
      stack.pop_back();
      const tinygltf::Node& node = model_.nodes[static_cast<std::size_t>(index)];
      const AffineTransform world = local_transform(node).then(parent);
      if (node.mesh >= 0) {
        // A transform too large to be finite is a fault of the file; a singular one (a scale of 0) hides a mesh, as
        // animations do, and is skipped with a warning.
        if (!finite_transform(world))
          fail(fmt::format("/nodes/{}", index),
               "its transform, with its parents', is too large to be finite (it scales volumes by more than 1.8e308)");
        if (world.determinant() == 0) {
          ++singular_placements_;
        } else {
          placed_.emplace_back(node.mesh, world);
          used_meshes_.insert(node.mesh);
        }
      }
      if (node.camera >= 0) place_camera(node.camera, world, index);
      for (auto child = node.children.rbegin(); child != node.children.rend(); ++child) stack.emplace_back(*child, world);
    }
  }

  void place_camera(int index, const AffineTransform& world, int node) {
    const tinygltf::Camera& camera = model_.cameras[static_cast<std::size_t>(index)];
    if (camera.type != "perspective") {
      warn("orthographic", fmt::format("orthographic cameras are not read (camera {}, placed by node {})", index, node));
      return;
    }
    if (out_.camera) return;
    const Vec3d forward = world.apply_vector({0, 0, -1}), up = world.apply_vector({0, 1, 0});
    const double forward_length = length(forward), up_length = length(up);
    if (!is_finite(world.translation) || !(forward_length > 0) || !(up_length > 0) || !std::isfinite(forward_length) || !std::isfinite(up_length) ||
        length(cross(forward, up)) <= 1e-12 * forward_length * up_length) {
      warn("camera", fmt::format("camera {} is not used: the transform of node {} collapses its view or is not finite", index, node));
      return;
    }
    CameraSettings settings;
    settings.look_from = world.translation;
    settings.look_at = world.translation + forward / forward_length;
    settings.up = up / up_length;
    settings.vertical_fov = camera.perspective.yfov * 180.0 / std::numbers::pi;
    out_.camera = settings;
  }

  static MeshMaterial gltf_default_material() {
    MeshMaterial material;
    material.name = "glTF default material";
    material.base_color = {1, 1, 1};
    material.metallic = 1;
    material.roughness = 1;
    material.metallic_roughness_model = true;
    return material;
  }

  // The texture coordinate set a material's textures are read with, or -1 for a material without textures.
  int uv_set(int material_index) {
    if (material_index < 0) return -1;
    const tinygltf::Material& material = model_.materials[static_cast<std::size_t>(material_index)];
    const tinygltf::TextureInfo& base = material.pbrMetallicRoughness.baseColorTexture;
    const tinygltf::TextureInfo& emissive = material.emissiveTexture;
    const bool has_base = base.index >= 0 && has_image(base.index), has_emissive = emissive.index >= 0 && has_image(emissive.index);
    if (has_base && has_emissive && base.texCoord != emissive.texCoord)
      warn("uv sets", fmt::format("material {}: its emissive texture is read with TEXCOORD_{}, the base colour texture's set, not TEXCOORD_{}",
                                  material_index, base.texCoord, emissive.texCoord));
    if (has_base || has_emissive) return has_base ? base.texCoord : emissive.texCoord;
    // A normal texture alone: read with TEXCOORD_0 only (convert_material).
    return normal_map_only(material_index) ? 0 : -1;
  }

  // Whether the material's only texture with an image is its normal texture (so that a primitive without texture
  // coordinates loses the normal map, not its colours).
  bool normal_map_only(int material_index) const {
    if (material_index < 0) return false;
    const tinygltf::Material& material = model_.materials[static_cast<std::size_t>(material_index)];
    const auto has = [&](int texture) { return texture >= 0 && has_image(texture); };
    return has(material.normalTexture.index) && material.normalTexture.texCoord == 0 && !has(material.pbrMetallicRoughness.baseColorTexture.index) &&
           !has(material.emissiveTexture.index);
  }

  bool has_image(int texture) const { return model_.textures[static_cast<std::size_t>(texture)].source >= 0; }

  // The accessor `index` as `role` needs it (a path for messages): in a buffer view, not sparse, of one of the
  // allowed types; `count` elements when given.
  Elements elements(int index, const std::string& where, const char* role, int type, std::initializer_list<int> component_types,
                    bool normalized_integers) const {
    const tinygltf::Accessor& accessor = model_.accessors[static_cast<std::size_t>(index)];
    if (accessor.sparse.isSparse) fail(where, fmt::format("accessor {} is sparse; sparse accessors are not read", index));
    if (accessor.bufferView < 0) fail(where, fmt::format("accessor {} has no bufferView (an accessor of zeros is not read)", index));
    bool allowed = false;
    for (const int t : component_types) allowed = allowed || accessor.componentType == t;
    if (normalized_integers && accessor.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT && !accessor.normalized) allowed = false;
    if (accessor.type != type || !allowed) {
      std::string allowed_types;
      for (const int t : component_types) allowed_types += fmt::format("{}{}", allowed_types.empty() ? "" : " or ", component_type_name(t));
      fail(where, fmt::format("{} needs a {} accessor of {}{}; accessor {} is {} of {}{}", role, type_name(type), allowed_types,
                              normalized_integers && component_types.size() > 1 ? " (integers normalized)" : "", index, type_name(accessor.type),
                              accessor.normalized ? "normalized " : "", component_type_name(accessor.componentType)));
    }
    const tinygltf::BufferView& view = model_.bufferViews[static_cast<std::size_t>(accessor.bufferView)];
    const tinygltf::Buffer& buffer = model_.buffers[static_cast<std::size_t>(view.buffer)];
    Elements e;
    e.count = accessor.count;
    e.component_type = accessor.componentType;
    e.components = type == TINYGLTF_TYPE_SCALAR ? 1 : type;
    e.normalized = accessor.normalized;
    const std::size_t element = e.component_size() * static_cast<std::size_t>(e.components);
    e.stride = view.byteStride != 0 ? view.byteStride : element;
    // Checked with the JSON; checked again against the bytes tinygltf holds.
    const unsigned __int128 end =
        static_cast<unsigned __int128>(accessor.byteOffset) + static_cast<unsigned __int128>(e.count - 1) * e.stride + element;
    if (e.count == 0 || e.stride < element || end > view.byteLength || view.byteOffset > buffer.data.size() ||
        view.byteLength > buffer.data.size() - view.byteOffset)
      fail(where, fmt::format("accessor {} does not fit in its buffer view", index));
    e.data = buffer.data.data() + view.byteOffset + accessor.byteOffset;
    return e;
  }

  // Counts against the file's limits, before anything is allocated.
  void reserve(u64 vertices, u64 triangles, const std::string& where) {
    if (vertices > kMaxMeshVertices - vertices_)
      fail(where, fmt::format("the file's meshes have more than {} vertices in all, the most a model file may have", kMaxMeshVertices));
    if (triangles > kMaxMeshTriangles - triangles_)
      fail(where, fmt::format("the file's meshes have more than {} triangles in all, the most a model file may have", kMaxMeshTriangles));
    vertices_ += vertices;
    triangles_ += triangles;
  }

  bool material_has_normal_map(int material_index) const {
    if (material_index < 0) return false;
    const tinygltf::NormalTextureInfo& info = model_.materials[static_cast<std::size_t>(material_index)].normalTexture;
    return info.index >= 0 && has_image(info.index);
  }

  VertexSource read_vertices(int position, int normal, int uv, int uv_set, int tangent, const std::string& where) {
    VertexSource source;
    const std::string attributes = where + "/attributes";
    const Elements p = elements(position, attributes + "/POSITION", "POSITION", TINYGLTF_TYPE_VEC3, {TINYGLTF_COMPONENT_TYPE_FLOAT}, false);
    reserve(p.count, 0, where);
    source.positions.resize(p.count);
    for (std::size_t i = 0; i < p.count; ++i) {
      const Vec3d v{p.component(i, 0), p.component(i, 1), p.component(i, 2)};
      if (!is_finite(v))
        fail(attributes + "/POSITION", fmt::format("position {} of accessor {} is not finite ({}, {}, {})", i, position, v.x, v.y, v.z));
      source.positions[i] = v;
    }
    if (normal >= 0) {
      const Elements n = elements(normal, attributes + "/NORMAL", "NORMAL", TINYGLTF_TYPE_VEC3, {TINYGLTF_COMPONENT_TYPE_FLOAT}, false);
      if (n.count != p.count) fail(attributes + "/NORMAL", fmt::format("accessor {} has {} normals for {} positions", normal, n.count, p.count));
      source.normals.resize(n.count);
      std::size_t bad = 0;
      for (std::size_t i = 0; i < n.count; ++i) {
        const Vec3d v{n.component(i, 0), n.component(i, 1), n.component(i, 2)};
        const double l = length(v);
        if (!std::isfinite(l) || l < 1e-12)
          ++bad;
        else
          source.normals[i] = v / l;
      }
      if (bad > 0) {
        source.normals.clear();
        warn("bad normals", fmt::format("{}/NORMAL: {} of the {} normals of accessor {} are zero or not finite: primitives with such normals "
                                        "(this is the first) are shaded with flat normals",
                                        attributes, bad, n.count, normal));
      }
    }
    if (uv >= 0) {
      const std::string name = fmt::format("TEXCOORD_{}", uv_set);
      const Elements t =
          elements(uv, attributes + "/" + name, name.c_str(), TINYGLTF_TYPE_VEC2,
                   {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT}, true);
      if (t.count != p.count)
        fail(attributes + "/" + name, fmt::format("accessor {} has {} texture coordinates for {} positions", uv, t.count, p.count));
      source.uvs.resize(t.count);
      for (std::size_t i = 0; i < t.count; ++i) {
        const double u = t.component(i, 0), v = t.component(i, 1);
        if (!std::isfinite(u) || !std::isfinite(v))
          fail(attributes + "/" + name, fmt::format("texture coordinate {} of accessor {} is not finite", i, uv));
        source.uvs[i] = {u, 1 - v};  // glTF's v runs down the image
      }
    }
    if (tangent >= 0 && !source.normals.empty()) {
      // xyz along increasing u, w = +-1 the bitangent's sign. Flipping v above turns the direction of increasing v,
      // not the bitangent glTF defines (w normal x xyz, up the image): the tangents are kept as written.
      const Elements t = elements(tangent, attributes + "/TANGENT", "TANGENT", TINYGLTF_TYPE_VEC4, {TINYGLTF_COMPONENT_TYPE_FLOAT}, false);
      if (t.count != p.count) fail(attributes + "/TANGENT", fmt::format("accessor {} has {} tangents for {} positions", tangent, t.count, p.count));
      source.tangents.resize(t.count);
      std::size_t bad = 0;
      for (std::size_t i = 0; i < t.count; ++i) {
        const Vec3d v{t.component(i, 0), t.component(i, 1), t.component(i, 2)};
        const double w = t.component(i, 3), l = length(v);
        if (!std::isfinite(l) || l < 1e-12 || !std::isfinite(w) || w == 0)
          ++bad;
        else
          source.tangents[i] = {v.x / l, v.y / l, v.z / l, w < 0 ? -1.0 : 1.0};
      }
      if (bad > 0) {
        source.tangents.clear();
        warn("bad tangents", fmt::format("{}/TANGENT: {} of the {} tangents of accessor {} are zero or not finite, or have w = 0: primitives with "
                                         "such tangents (this is the first) derive theirs from their texture coordinates",
                                         attributes, bad, t.count, tangent));
      }
    }
    return source;
  }

  // A primitive's triangles, as indices into its vertices.
  std::vector<std::array<u32, 3>> read_triangles(const tinygltf::Primitive& primitive, std::size_t vertices, const std::string& where) {
    std::size_t count = vertices;
    Elements indices;
    if (primitive.indices >= 0) {
      indices =
          elements(primitive.indices, where + "/indices", "indices", TINYGLTF_TYPE_SCALAR,
                   {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT}, false);
      count = indices.count;
    }
    if (primitive.mode == TINYGLTF_MODE_TRIANGLES && count % 3 != 0)
      fail(where, fmt::format("{} {} do not make whole triangles (mode TRIANGLES takes three each)", count,
                              primitive.indices >= 0 ? "indices" : "vertices"));
    const std::size_t triangles = primitive.mode == TINYGLTF_MODE_TRIANGLES ? count / 3 : count >= 3 ? count - 2 : 0;
    reserve(0, triangles, where);
    const auto vertex = [&](std::size_t i) -> u32 {
      if (primitive.indices < 0) return static_cast<u32>(i);
      const u32 v = indices.index(i);
      if (v >= vertices) fail(where + "/indices", fmt::format("index {} out of range (the primitive has {} vertices)", v, vertices));
      return v;
    };
    std::vector<std::array<u32, 3>> out(triangles);
    for (std::size_t t = 0; t < triangles; ++t) {
      if (primitive.mode == TINYGLTF_MODE_TRIANGLES)
        out[t] = {vertex(3 * t), vertex(3 * t + 1), vertex(3 * t + 2)};
      else if (primitive.mode == TINYGLTF_MODE_TRIANGLE_STRIP)  // every other triangle turned back, to keep the winding
        out[t] =
            t % 2 == 0 ? std::array<u32, 3>{vertex(t), vertex(t + 1), vertex(t + 2)} : std::array<u32, 3>{vertex(t), vertex(t + 2), vertex(t + 1)};
      else
        out[t] = {vertex(t + 1), vertex(t + 2), vertex(0)};  // TRIANGLE_FAN, as glTF orders it
    }
    return out;
  }

  // The materials the drawn primitives of the placed meshes use, in the file's order (then the glTF default
  // material, for primitives without one).
  void collect_materials() {
    std::set<int> used;
    bool default_used = false;
    for (const int m : used_meshes_)
      for (const tinygltf::Primitive& primitive : model_.meshes[static_cast<std::size_t>(m)].primitives) {
        if (!drawn(primitive)) continue;
        if (primitive.material >= 0)
          used.insert(primitive.material);
        else
          default_used = true;
      }
    for (const int m : used) {
      material_index_[m] = static_cast<u32>(out_.materials.size());
      out_.materials.push_back(convert_material(m));
    }
    if (default_used) {
      material_index_[-1] = static_cast<u32>(out_.materials.size());
      out_.materials.push_back(gltf_default_material());
    }
  }

  static bool drawn(const tinygltf::Primitive& primitive) {
    return primitive.mode >= TINYGLTF_MODE_TRIANGLES && primitive.mode <= TINYGLTF_MODE_TRIANGLE_FAN && primitive.attributes.count("POSITION") != 0;
  }

  MeshMaterial convert_material(int index) {
    const tinygltf::Material& material = model_.materials[static_cast<std::size_t>(index)];
    const std::string path = fmt::format("/materials/{}", index);
    MeshMaterial out;
    out.name = material.name.empty() ? fmt::format("material {}", index) : material.name;
    const tinygltf::PbrMetallicRoughness& pbr = material.pbrMetallicRoughness;
    const std::vector<double>& base = pbr.baseColorFactor;
    if (base.size() == 4)
      out.base_color = {base[0], base[1], base[2]};
    else
      out.base_color = {1, 1, 1};
    out.metallic = pbr.metallicFactor;
    out.roughness = pbr.roughnessFactor;
    out.metallic_roughness_model = true;
    double strength = 1;
    const auto extension = material.extensions.find("KHR_materials_emissive_strength");
    if (extension != material.extensions.end() && extension->second.Has("emissiveStrength"))
      strength = extension->second.Get("emissiveStrength").GetNumberAsDouble();
    if (material.emissiveFactor.size() == 3)
      out.emission = Vec3d{material.emissiveFactor[0], material.emissiveFactor[1], material.emissiveFactor[2]} * strength;
    if (pbr.baseColorTexture.index >= 0)
      out.base_color_texture = texture(pbr.baseColorTexture.index, path + "/pbrMetallicRoughness/baseColorTexture");
    if (material.emissiveTexture.index >= 0) out.emission_texture = texture(material.emissiveTexture.index, path + "/emissiveTexture");
    if ((material.alphaMode == "BLEND" || material.alphaMode == "MASK") && ((base.size() == 4 && base[3] < 1) || out.base_color_texture >= 0))
      warn("alpha", fmt::format("transparency is not rendered: materials with alphaMode BLEND or MASK (the first: {}, '{}') are drawn opaque, "
                                "their alpha ignored",
                                path, out.name));
    if (pbr.metallicRoughnessTexture.index >= 0)
      out.metallic_roughness_texture = texture(pbr.metallicRoughnessTexture.index, path + "/pbrMetallicRoughness/metallicRoughnessTexture");
    if (material.normalTexture.index >= 0 && has_image(material.normalTexture.index)) {
      const std::string at = path + "/normalTexture";
      if (material.normalTexture.texCoord != 0) {
        warn("normal uv set",
             fmt::format("{}: normal textures read with a texture coordinate set other than TEXCOORD_0 (here TEXCOORD_{}) are not applied", at,
                         material.normalTexture.texCoord));
      } else if (uv_set(index) != 0) {
        warn("normal uv set", fmt::format("{}: the normal texture reads TEXCOORD_0 but the material's other textures TEXCOORD_{}: it is not applied",
                                          at, uv_set(index)));
      } else {
        out.normal_texture = texture(material.normalTexture.index, at);
        out.normal_scale = material.normalTexture.scale;
      }
    }
    return out;
  }

  // The MeshFile texture of glTF texture `index`, its image decoded once however many textures use it.
  i32 texture(int index, const std::string& where) {
    const tinygltf::Texture& texture = model_.textures[static_cast<std::size_t>(index)];
    if (texture.source < 0) {
      warn("texture source", fmt::format("{}: texture {} has no image that is read (its material's factor is used alone)", where, index));
      return -1;
    }
    if (texture.sampler >= 0) {
      const tinygltf::Sampler& sampler = model_.samplers[static_cast<std::size_t>(texture.sampler)];
      if (sampler.wrapS != TINYGLTF_TEXTURE_WRAP_REPEAT || sampler.wrapT != TINYGLTF_TEXTURE_WRAP_REPEAT)
        warn("wrap", fmt::format("texture wrap modes other than REPEAT are drawn as REPEAT (the first: sampler {})", texture.sampler));
    }
    const auto [it, added] = texture_index_.try_emplace(texture.source, static_cast<i32>(out_.textures.size()));
    if (!added) return it->second;
    const std::size_t source = static_cast<std::size_t>(texture.source);
    const tinygltf::Image& image = model_.images[source];
    const std::string image_path = fmt::format("/images/{}", source);
    if (image.bufferView >= 0) {
      const tinygltf::BufferView& view = model_.bufferViews[static_cast<std::size_t>(image.bufferView)];
      const tinygltf::Buffer& buffer = model_.buffers[static_cast<std::size_t>(view.buffer)];
      if (view.byteOffset > buffer.data.size() || view.byteLength > buffer.data.size() - view.byteOffset)
        fail(image_path, fmt::format("buffer view {} does not fit in its buffer", image.bufferView));
      out_.textures.push_back(read_texture_image_from_memory(std::span<const u8>(buffer.data.data() + view.byteOffset, view.byteLength),
                                                             fmt::format("{}: {}", name_, image_path)));
    } else if (!image.uri.empty()) {
      try {
        out_.textures.push_back(read_texture_image(folder_prefix_ + gltf::decode_uri(image.uri)));
      } catch (const InputError& e) {
        fail(image_path, e.what());
      }
    } else {
      out_.textures.push_back(read_texture_image_from_memory(image.image, fmt::format("{}: {}", name_, image_path)));
    }
    return it->second;
  }

  // The placed meshes, in the file's order; a mesh without triangles (of points and lines only) is left out with
  // its placements.
  void convert_meshes() {
    collect_materials();
    std::map<int, u32> mesh_index;
    for (const int m : used_meshes_) {
      TriangleMesh mesh = convert_mesh(m);
      if (mesh.triangles.empty()) continue;
      mesh_index[m] = static_cast<u32>(out_.meshes.size());
      out_.meshes.push_back(std::move(mesh));
    }
    for (const auto& [m, transform] : placed_) {
      const auto it = mesh_index.find(m);
      if (it != mesh_index.end()) out_.placements.push_back(MeshPlacement{it->second, transform});
    }
  }

  TriangleMesh convert_mesh(int index) {
    const tinygltf::Mesh& mesh = model_.meshes[static_cast<std::size_t>(index)];
    TriangleMesh out;
    out.name = mesh.name.empty() ? fmt::format("mesh {}", index) : mesh.name;
    // First each drawn primitive's triangles and vertex data (once for each combination of accessors), then the
    // mesh's arrays: a mesh has normals (or uvs) where any of its primitives has them.
    struct Part {
      std::string path;
      std::size_t source;
      u32 material;
      std::vector<std::array<u32, 3>> triangles;
    };
    std::vector<Part> parts;
    std::map<std::tuple<int, int, int, int>, std::size_t> source_of;
    std::vector<VertexSource> sources;
    for (std::size_t k = 0; k < mesh.primitives.size(); ++k) {
      const tinygltf::Primitive& primitive = mesh.primitives[k];
      const std::string where = fmt::format("/meshes/{}/primitives/{}", index, k);
      if (primitive.mode < TINYGLTF_MODE_TRIANGLES) {
        undrawn_modes_.insert(mode_name(primitive.mode));
        ++undrawn_;
        continue;
      }
      const auto attribute = [&](const std::string& name) {
        const auto it = primitive.attributes.find(name);
        return it == primitive.attributes.end() ? -1 : it->second;
      };
      const int position = attribute("POSITION");
      if (position < 0) {
        warn("no position", fmt::format("{}: a primitive without POSITION is not drawn", where));
        continue;
      }
      if (!primitive.targets.empty()) warn("morph targets", "morph targets are not applied: meshes are drawn without them");
      if (attribute("COLOR_0") >= 0) warn("vertex colours", "vertex colours (COLOR_0) are not applied");
      const int set = uv_set(primitive.material);
      int uv = -1;
      if (set >= 0) {
        uv = attribute(fmt::format("TEXCOORD_{}", set));
        if (uv < 0 && normal_map_only(primitive.material))
          warn("normal map without uvs", fmt::format("{}: a primitive without TEXCOORD_0 is drawn without its material's normal texture", where));
        else if (uv < 0)
          fail(where, fmt::format("material {} reads its textures with TEXCOORD_{}, which the primitive does not have", primitive.material, set));
      }
      const int normal = attribute("NORMAL");
      // Tangents serve normal maps only, and glTF ignores them where a primitive has no normals.
      const int tangent = normal >= 0 && material_has_normal_map(primitive.material) ? attribute("TANGENT") : -1;
      const auto key = std::make_tuple(position, normal, uv, tangent);
      auto found = source_of.find(key);
      if (found == source_of.end()) {
        sources.push_back(read_vertices(position, normal, uv, set, tangent, where));
        found = source_of.emplace(key, sources.size() - 1).first;
      }
      parts.push_back(Part{where, found->second, material_index_.at(primitive.material),
                           read_triangles(primitive, sources[found->second].positions.size(), where)});
    }
    bool normals = false, uvs = false, tangents = !parts.empty();
    for (const Part& part : parts) {
      normals = normals || !sources[part.source].normals.empty();
      uvs = uvs || !sources[part.source].uvs.empty();
      // A mesh keeps vertex tangents only where every part has them; the others derive theirs from the uvs.
      tangents = tangents && !sources[part.source].tangents.empty() && !sources[part.source].normals.empty();
    }
    // Materials per triangle, unless every triangle has the first.
    bool per_triangle_materials = false;
    for (const Part& part : parts) per_triangle_materials = per_triangle_materials || part.material != 0;
    for (const Part& part : parts) {
      VertexSource& source = sources[part.source];
      if (normals && source.normals.empty()) {
        // Flat normals, as glTF asks of primitives without them: each triangle gets its own three vertices.
        reserve(3 * part.triangles.size(), 0, part.path);
        for (const auto& t : part.triangles) {
          const Vec3d a = source.positions[t[0]], b = source.positions[t[1]], c = source.positions[t[2]];
          const Vec3d n = cross(b - a, c - a);
          const double l = length(n);
          const Vec3d unit = l > 0 && std::isfinite(l) ? n / l : Vec3d{0, 0, 1};  // a triangle of no area is never hit
          const u32 v = static_cast<u32>(out.positions.size());
          for (int i = 0; i < 3; ++i) {
            out.positions.push_back(source.positions[t[i]]);
            out.normals.push_back(unit);
            if (uvs) out.uvs.push_back(source.uvs.empty() ? std::array<double, 2>{0, 0} : source.uvs[t[i]]);
          }
          out.triangles.push_back({v, v + 1, v + 2});
        }
      } else {
        if (source.base < 0) {
          source.base = static_cast<std::int64_t>(out.positions.size());
          out.positions.insert(out.positions.end(), source.positions.begin(), source.positions.end());
          if (normals) out.normals.insert(out.normals.end(), source.normals.begin(), source.normals.end());
          if (tangents) out.tangents.insert(out.tangents.end(), source.tangents.begin(), source.tangents.end());
          if (uvs) {
            if (source.uvs.empty())
              out.uvs.resize(out.uvs.size() + source.positions.size(), {0, 0});
            else
              out.uvs.insert(out.uvs.end(), source.uvs.begin(), source.uvs.end());
          }
        }
        const u32 base = static_cast<u32>(source.base);
        for (const auto& t : part.triangles) out.triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
      }
      if (per_triangle_materials) out.materials.resize(out.triangles.size(), part.material);
    }
    return out;
  }

  const tinygltf::Model& model_;
  const std::string& name_;
  const std::string& folder_prefix_;
  MeshFile& out_;
  std::set<std::string> warned_;
  std::vector<std::pair<int, AffineTransform>> placed_;  // glTF mesh, transform
  std::set<int> used_meshes_;
  std::map<int, u32> material_index_;  // glTF material (-1: none) -> MeshFile material
  std::map<int, i32> texture_index_;   // glTF image -> MeshFile texture
  std::size_t singular_placements_ = 0;
  std::set<std::string> undrawn_modes_;
  std::size_t undrawn_ = 0;
  u64 vertices_ = 0, triangles_ = 0;
};

}  // namespace

MeshFile read_gltf_file(const std::filesystem::path& path, ModelReferences references) {
  const std::string name = path.string();
  std::string bytes;
  InputFile input = InputFile::open(path);
  switch (input.problem()) {
    case InputFile::Problem::kNone: break;
    case InputFile::Problem::kMissing: throw InputError(fmt::format("{}: cannot open the model file: it does not exist", name));
    case InputFile::Problem::kFolder: throw InputError(fmt::format("{}: is a folder, not a model file", name));
    case InputFile::Problem::kNotRegular: throw InputError(fmt::format("{}: is {}, not a model file", name, input.reason()));
    case InputFile::Problem::kCannotOpen: throw InputError(fmt::format("{}: cannot open the model file: {}", name, input.reason()));
  }
  {
    const std::string problem = read_input(input, name, bytes);
    if (!problem.empty()) throw InputError(fmt::format("{}: {}", name, problem));
  }

  // GLB or JSON, told by the first bytes (a JSON text cannot start with "glTF"), not by the extension.
  const bool binary = bytes.size() >= 4 && load_le32(reinterpret_cast<const unsigned char*>(bytes.data())) == kGlbMagic;
  GlbParts parts{0, bytes.size(), std::nullopt};
  if (binary) parts = split_glb(name, bytes);

  std::string folder = path.parent_path().string();
  const std::string folder_prefix = folder.empty() ? "./" : folder.back() == '/' ? folder : folder + "/";

  gltf::JsonFacts facts;
  {
    const char* text = bytes.data() + parts.json_offset;
    gltf::check_json_nesting(name, text, parts.json_length);
    nlohmann::json root;
    try {
      root = nlohmann::json::parse(text, text + parts.json_length);
    } catch (const nlohmann::json::out_of_range&) {
      // A number beyond a double's range ("1e999"): the outline pass names its line, column and JSON path.
      read_json_outline(std::string_view(text, parts.json_length), name);
      throw InputError(fmt::format("{}: not valid JSON: a number is beyond the range of a double", name));
    } catch (const nlohmann::json::exception& e) {
      std::string what = e.what();
      if (what.compare(0, 1, "[") == 0 && what.find("] ") != std::string::npos) what = what.substr(what.find("] ") + 2);
      throw InputError(fmt::format("{}: not valid JSON: {}", name, what));
    }
    facts = gltf::check_gltf_json(root, gltf::JsonCheckInput{name, folder_prefix, binary, parts.bin_length, references});
  }

  FileAccess access;
  access.folder_prefix = folder_prefix;
  access.skipped.insert(facts.external_images.begin(), facts.external_images.end());
  for (const std::string& buffer : facts.external_buffers) access.skipped.erase(buffer);  // a file that is both is read
  tinygltf::TinyGLTF loader;
  loader.SetFsCallbacks(tinygltf::FsCallbacks{&file_exists, &expand_file_path, &read_whole_file, &write_whole_file, &access});
  loader.SetImageLoader(&keep_image_bytes, nullptr);
  tinygltf::Model model;
  std::string err, warn;
  bool loaded = false;
  try {
    if (binary)
      loaded = loader.LoadBinaryFromMemory(&model, &err, &warn, reinterpret_cast<const unsigned char*>(bytes.data()),
                                           static_cast<unsigned>(bytes.size()), folder_prefix);
    else
      loaded = loader.LoadASCIIFromString(&model, &err, &warn, bytes.data(), static_cast<unsigned>(bytes.size()), folder_prefix);
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const std::exception& e) {
    err = e.what();
  }
  // When tinygltf succeeds, `err` may still hold its complaints about things glTF allows (a skin without
  // inverseBindMatrices): the check above is what decides.
  if (!loaded) {
    // What tinygltf says may quote a whole data URI: its first line, cut short.
    std::string said = err.substr(0, err.find('\n'));
    if (said.size() > 200) said = said.substr(0, 200) + "...";
    throw InputError(fmt::format("{}: {}", name, !access.error.empty() ? access.error : "tinygltf cannot read it: " + said));
  }
  bytes.clear();
  bytes.shrink_to_fit();

  // tinygltf drops what it cannot parse; what it holds must be what was checked.
  bool same = model.accessors.size() == facts.accessors && model.buffers.size() == facts.buffers && model.bufferViews.size() == facts.buffer_views &&
              model.cameras.size() == facts.cameras && model.images.size() == facts.images && model.materials.size() == facts.materials &&
              model.meshes.size() == facts.primitives.size() && model.nodes.size() == facts.nodes && model.scenes.size() == facts.scenes &&
              model.textures.size() == facts.textures;
  for (std::size_t m = 0; same && m < model.meshes.size(); ++m) same = model.meshes[m].primitives.size() == facts.primitives[m];
  if (!same) throw InputError(fmt::format("{}: tinygltf read the file differently from its JSON (a part was dropped)", name));

  MeshFile out;
  out.path = path;
  Converter(model, name, folder_prefix, out).run(facts);
  return out;
}

}  // namespace pt
