// Scene files: JSON text -> SceneDescription. Every value is checked where it is read, and the first problem
// becomes an InputError naming the file, the line and column, and the JSON path of the offending value. The text
// is first outlined (json_outline.hpp); the entries of the long lists are then parsed and read one at a time, and
// a line and column are looked up only for an error.
#include "loading/scene_loader.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <exception>
#include <functional>
#include <initializer_list>
#include <limits>
#include <map>
#include <memory>
#include <optional>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "base/input_file.hpp"
#include "base/mapped_file.hpp"
#include "base/parallel_loop.hpp"
#include "image/image_io.hpp"
#include "loading/json_outline.hpp"
#include "loading/model_files.hpp"
#include "scene/json_positions.hpp"
#include "scene/json_scan.hpp"

namespace pt {

namespace {

using Json = nlohmann::json;

// Objects parsed a batch at a time, ahead of their reading (SceneReader::read): at most this many, or this much text.
constexpr std::size_t kObjectBatch = 1024;
constexpr std::size_t kObjectBatchBytes = std::size_t{1} << 20;

std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

const char* type_name(const Json& j) {
  switch (j.type()) {
    case Json::value_t::null: return "null";
    case Json::value_t::boolean: return "a boolean";
    case Json::value_t::number_integer:
    case Json::value_t::number_unsigned:
    case Json::value_t::number_float: return "a number";
    case Json::value_t::string: return "a string";
    case Json::value_t::array: return "an array";
    case Json::value_t::object: return "an object";
    default: return "an unsupported value";
  }
}

// Shared by all nodes of one file: its name and its text.
struct Document {
  std::string source;
  std::string_view text;
  std::function<void(std::size_t)> passed;  // told where the reader is, for a mapped text (base/mapped_file.hpp)
};

// Where a node's value was parsed from: the whole text, or the text of one list entry, whose JSON path is the
// first `pointer_length` characters of the node's path. Errors are located by scanning only that text.
struct ParsedFrom {
  TextRange range;
  std::size_t pointer_length = 0;
};

// A JSON value together with its path, so that every check can say where it failed.
class Node {
 public:
  Node(const Json& value, std::string pointer, const Document& document, ParsedFrom from)
      : value_(value), pointer_(std::move(pointer)), document_(document), from_(from) {}

  [[noreturn]] void fail(const std::string& message) const { throw InputError(fmt::format("{}: {}", place(), message)); }

  // "FILE:LINE:COLUMN: POINTER", the start of a message about this value.
  std::string place() const {
    const std::optional<std::size_t> offset = text_offset();
    std::string file = document_.source;
    if (offset) {
      const TextPosition at = JsonPositions::position_of_offset(document_.text, *offset);
      file = fmt::format("{}:{}:{}", document_.source, at.line, at.column);
    }
    return fmt::format("{}: {}", file, pointer_.empty() ? "(top level)" : pointer_);
  }

  // Where the value starts in the file's text.
  std::optional<std::size_t> text_offset() const {
    const std::string_view within = document_.text.substr(from_.range.begin, from_.range.end - from_.range.begin);
    const std::optional<std::size_t> offset = find_value_offset(within, pointer_.substr(from_.pointer_length));
    if (!offset) return std::nullopt;
    return *offset + from_.range.begin;
  }

  // The value as written (for a number, its digits).
  std::string literal() const {
    const std::optional<std::size_t> offset = text_offset();
    if (!offset) return value_.dump();
    return std::string(document_.text.substr(*offset, end_of_scalar(document_.text, *offset) - *offset));
  }

  const Json& json() const { return value_; }
  const std::string& pointer() const { return pointer_; }

  void expect_object() const {
    if (!value_.is_object()) fail(fmt::format("expected an object, found {}", type_name(value_)));
  }

  // Rejects keys outside `allowed`, suggesting the closest allowed one for a misspelling.
  void allow_keys(std::initializer_list<const char*> allowed) const {
    expect_object();
    for (const auto& item : value_.items()) {
      const std::string& key = item.key();
      if (std::any_of(allowed.begin(), allowed.end(), [&](const char* a) { return key == a; })) continue;
      std::string best;
      std::size_t best_distance = 3;
      for (const char* a : allowed) {
        const std::size_t d = edit_distance(key, a);
        if (d < best_distance) {
          best_distance = d;
          best = a;
        }
      }
      child(key).fail(best.empty() ? fmt::format("unknown key '{}'", clip(key))
                                   : fmt::format("unknown key '{}' (did you mean '{}'?)", clip(key), best));
    }
  }

  bool has(const char* key) const { return value_.is_object() && value_.contains(key); }

  Node child(const std::string& key) const { return Node(value_.at(key), pointer_ + "/" + escape_pointer_token(key), document_, from_); }

  Node at(const char* key) const {
    expect_object();
    if (!value_.contains(key)) fail(fmt::format("missing required key '{}'", key));
    return child(key);
  }

  Node element(std::size_t i) const { return Node(value_.at(i), pointer_ + "/" + std::to_string(i), document_, from_); }

  std::size_t array_size(std::size_t expected_min, std::size_t expected_max) const {
    if (!value_.is_array()) fail(fmt::format("expected an array, found {}", type_name(value_)));
    const std::size_t n = value_.size();
    if (n < expected_min || n > expected_max) {
      if (expected_min == expected_max) fail(fmt::format("expected {} elements, found {}", expected_min, n));
      fail(fmt::format("expected between {} and {} elements, found {}", expected_min, expected_max, n));
    }
    return n;
  }

  double number() const {
    if (!value_.is_number()) fail(fmt::format("expected a number, found {}", type_name(value_)));
    const double v = value_.get<double>();
    if (!std::isfinite(v)) fail("expected a finite number");
    return v;
  }
  double number_in(double lo, double hi) const {
    const double v = number();
    if (v < lo || v > hi) fail(fmt::format("{} is outside the allowed range [{}, {}]", v, lo, hi));
    return v;
  }
  double positive() const {
    const double v = number();
    if (!(v > 0)) fail(fmt::format("must be positive, found {}", v));
    return v;
  }
  u32 integer(u64 lo, u64 hi) const {
    if (!value_.is_number_integer() && !value_.is_number_unsigned()) {
      if (value_.is_number_float()) {
        // An integer too large for 64 bits (18446744073709551616) reaches here as a double: it is out of range,
        // not fractional.
        const double v = value_.get<double>();
        if (std::floor(v) == v && (v < static_cast<double>(lo) || v > static_cast<double>(hi)))
          fail(fmt::format("{} is outside the allowed range [{}, {}]", literal(), lo, hi));
        fail("expected an integer, found a fractional number");
      }
      fail(fmt::format("expected an integer, found {}", type_name(value_)));
    }
    if (value_.is_number_unsigned()) {
      const u64 v = value_.get<u64>();
      if (v < lo || v > hi) fail(fmt::format("{} is outside the allowed range [{}, {}]", v, lo, hi));
      return static_cast<u32>(v);
    }
    const std::int64_t v = value_.get<std::int64_t>();
    if (v < 0 && lo == 0) fail(fmt::format("must not be negative, found {}", v));
    if (v < static_cast<std::int64_t>(lo) || static_cast<u64>(v) > hi) fail(fmt::format("{} is outside the allowed range [{}, {}]", v, lo, hi));
    return static_cast<u32>(v);
  }
  std::string string() const {
    if (!value_.is_string()) fail(fmt::format("expected a string, found {}", type_name(value_)));
    return value_.get<std::string>();
  }
  Vec3d vec3() const {
    array_size(3, 3);
    return {element(0).number(), element(1).number(), element(2).number()};
  }
  Vec3d color() const {
    const Vec3d c = vec3();
    if (c.x < 0 || c.y < 0 || c.z < 0) fail("colour components must not be negative");
    return c;
  }
  Vec3d nonzero_vec3() const {
    const Vec3d v = vec3();
    if (length_squared(v) == 0) fail("must not be the zero vector");
    return v;
  }

 private:
  const Json& value_;
  std::string pointer_;
  const Document& document_;
  ParsedFrom from_;
};

// Builds the description while keeping name tables for textures and materials.
class SceneReader {
 public:
  SceneReader(const Document& document, std::filesystem::path base_folder, ModelReferences references, SceneDescription& scene)
      : document_(document), base_folder_(std::move(base_folder)), references_(references), scene_(scene) {}

  // `root` is the outline's document, whose lists are empty; their entries are parsed from the text one by one.
  void read(const Node& root, const JsonOutline& outline) {
    root.allow_keys({"render", "camera", "background", "textures", "materials", "objects"});
    if (root.has("render")) read_render(root.child("render"));
    read_camera(root.at("camera"));
    if (root.has("background")) read_background(root.child("background"));
    if (root.has("textures")) {
      const Node textures = root.child("textures");
      textures.expect_object();
      for (const auto& [key, range] : outline.textures.value())
        with_entry(textures.pointer() + "/" + escape_pointer_token(key), range, [&](const Node& n) { texture_names_[key] = read_texture(n); });
    }
    if (root.has("materials")) {
      const Node materials = root.child("materials");
      materials.expect_object();
      for (const auto& [key, range] : outline.materials.value())
        with_entry(materials.pointer() + "/" + escape_pointer_token(key), range, [&](const Node& n) { material_names_[key] = read_material(n); });
    }
    const Node objects = root.at("objects");
    if (!objects.json().is_array()) objects.array_size(1, 1u << 24);  // refuses it, saying what it is
    const std::vector<TextRange>& list = outline.objects.value();
    if (list.empty() || list.size() > (1u << 24)) objects.fail(fmt::format("expected between 1 and {} elements, found {}", 1u << 24, list.size()));
    scene_.objects.reserve(list.size());
    // nlohmann's parse of an entry costs about as much as reading it: each batch of objects is parsed on a second
    // thread while the batch before it is read, in order, on this one. A batch ends after kObjectBatch objects or
    // kObjectBatchBytes of text, so that the text parsed ahead of the reader (resident until the reader passes it,
    // base/mapped_file.hpp) stays small however long the objects are written.
    const auto batch_end = [&](std::size_t first) {
      std::size_t end = first;
      while (end < list.size() && end - first < kObjectBatch && (end == first || list[end].end - list[first].begin <= kObjectBatchBytes)) ++end;
      return end;
    };
    std::vector<Json> parsed, ahead;
    const auto parse_batch = [&](std::size_t first, std::vector<Json>& out) {
      out.clear();
      for (std::size_t i = first, end = batch_end(first); i < end; ++i) out.push_back(parse_entry(list[i]));
    };
    parse_batch(0, parsed);
    for (std::size_t first = 0, end = batch_end(0); first < list.size(); first = end, end = batch_end(first)) {
      std::exception_ptr read_failure, parse_failure;
      parallel_invoke(
          [&] {
            try {
              for (std::size_t i = first; i < end; ++i) {
                read_entry(parsed[i - first], objects.pointer() + "/" + std::to_string(i), list[i], [&](const Node& n) { read_object(n); });
                if (document_.passed) document_.passed(list[i].end);
              }
            } catch (...) {
              read_failure = std::current_exception();
            }
          },
          [&] {
            try {
              parse_batch(end, ahead);
            } catch (...) {
              parse_failure = std::current_exception();
            }
          });
      if (read_failure) std::rethrow_exception(read_failure);  // the earlier object's problem comes first
      if (parse_failure) std::rethrow_exception(parse_failure);
      std::swap(parsed, ahead);
    }
    decode_images();
  }

 private:
  // Parses one list entry (the outline has checked its text) and reads it.
  template <class Read>
  void with_entry(std::string pointer, TextRange range, Read&& read) {
    read_entry(parse_entry(range), std::move(pointer), range, read);
  }
  Json parse_entry(TextRange range) const { return Json::parse(document_.text.data() + range.begin, document_.text.data() + range.end); }
  template <class Read>
  void read_entry(const Json& value, std::string pointer, TextRange range, Read&& read) {
    const std::size_t pointer_length = pointer.size();
    read(Node(value, std::move(pointer), document_, ParsedFrom{range, pointer_length}));
  }

  void read_render(const Node& n) {
    n.allow_keys({"width", "height", "samples_per_pixel", "max_depth", "seed", "russian_roulette_depth", "light_sampling", "light_threshold", "sampler", "noise_threshold", "t_min"});
    RenderSettings& r = scene_.render;
    if (n.has("width")) r.width = n.child("width").integer(1, kMaxImageSide);
    if (n.has("height")) r.height = n.child("height").integer(1, kMaxImageSide);
    if (static_cast<u64>(r.width) * r.height > kMaxImagePixels) n.fail(fmt::format("{}x{} pixels is too large", r.width, r.height));
    if (n.has("samples_per_pixel")) r.samples_per_pixel = n.child("samples_per_pixel").integer(1, kMaxSamplesPerPixel);
    if (n.has("max_depth")) r.max_depth = n.child("max_depth").integer(1, kMaxDepth);
    if (n.has("seed")) r.seed = n.child("seed").integer(0, 0xffffffffu);
    if (n.has("russian_roulette_depth")) r.roulette_depth = n.child("russian_roulette_depth").integer(0, kMaxDepth);
    if (n.has("noise_threshold")) r.noise_threshold = n.child("noise_threshold").number_in(0, kMaxNoiseThreshold);
    if (n.has("light_threshold")) r.light_threshold = n.child("light_threshold").number_in(0, kMaxLightThreshold);
    if (n.has("light_sampling")) {
      const Node choice = n.child("light_sampling");
      const std::string value = choice.string();
      const std::optional<LightSampling> sampling = parse_light_sampling(value);
      if (!sampling) choice.fail(fmt::format("'{}' is not a light sampling: auto, nee or none", clip(value)));
      r.light_sampling = *sampling;
    }
    if (n.has("sampler")) {
      const Node choice = n.child("sampler");
      const std::string value = choice.string();
      if (value != "sobol" && value != "independent") choice.fail(fmt::format("'{}' is not a sampler: sobol or independent", clip(value)));
      r.sampler = value == "independent" ? SamplerKind::kIndependent : SamplerKind::kSobol;
    }
    // t_min once kept rays from hitting the surface they leave; its fixed distance was wrong at most scales. Rays
    // now start off the surface by the hit point's own rounding error bound (kernel/shapes.hpp, describe_hit).
    if (n.has("t_min"))
      n.child("t_min").fail(
          "t_min is no longer a setting: rays leave surfaces from an offset derived from the rounding error of the "
          "hit point, at every scale and in every number format; remove it (see docs/scene-format.md)");
  }

  void read_camera(const Node& n) {
    n.allow_keys({"look_from", "look_at", "up", "vertical_fov", "aperture", "focus_distance", "shutter"});
    CameraSettings& c = scene_.camera;
    c.look_from = n.at("look_from").vec3();
    c.look_at = n.at("look_at").vec3();
    if (length_squared(c.look_at - c.look_from) == 0) n.child("look_at").fail("look_at must differ from look_from");
    if (n.has("up")) c.up = n.child("up").nonzero_vec3();
    if (length_squared(cross(c.up, c.look_at - c.look_from)) == 0) n.fail("the up vector is parallel to the view direction");
    const Node fov = n.at("vertical_fov");
    c.vertical_fov = fov.number();
    if (!(c.vertical_fov > 0 && c.vertical_fov < 180)) fov.fail("vertical_fov must lie strictly between 0 and 180 degrees");
    if (n.has("aperture")) c.aperture = n.child("aperture").number_in(0, 1e6);
    c.focus_distance = n.has("focus_distance") ? n.child("focus_distance").positive() : length(c.look_at - c.look_from);
    if (n.has("shutter")) {
      const Node s = n.child("shutter");
      s.array_size(2, 2);
      c.shutter_open = s.element(0).number();
      c.shutter_close = s.element(1).number();
      if (c.shutter_close < c.shutter_open) s.fail("the shutter closes before it opens");
    }
  }

  void read_background(const Node& n) {
    const std::string type = n.at("type").string();
    if (type == "sky") {
      n.allow_keys({"type", "horizon", "zenith"});
      if (n.has("horizon")) scene_.background.horizon = n.child("horizon").color();
      if (n.has("zenith")) scene_.background.zenith = n.child("zenith").color();
    } else if (type == "constant") {
      n.allow_keys({"type", "color"});
      const Vec3d c = n.at("color").color();
      scene_.background = {c, c, {}};
      scene_.written.horizon = scene_.written.zenith = n.child("color").pointer();
    } else if (type == "environment") {
      n.allow_keys({"type", "file", "strength", "rotate"});
      const Node file = n.at("file");
      const std::string name = file.string();
      if (name.empty()) file.fail("the image file name is empty");
      EnvironmentSettings environment;
      if (n.has("strength")) environment.strength = n.child("strength").number_in(0, 1e30);
      if (n.has("rotate")) {
        // Degrees about the up axis (y), or about x, then y, then z as an object's transform rotates.
        const Node rotate = n.child("rotate");
        const Vec3d degrees = rotate.json().is_number() ? Vec3d{0, rotate.number(), 0} : rotate.vec3();
        environment.rotation = RigidTransform::from_euler_degrees(degrees, {});
      }
      LinearImage image;
      try {
        image = read_environment_image(base_folder_ / name);
      } catch (const InputError& e) {
        file.fail(e.what());
      }
      environment.width = image.width;
      environment.height = image.height;
      environment.rgb = std::move(image.rgb);
      scene_.environment = std::move(environment);
      scene_.written.environment = file.pointer();
    } else {
      n.child("type").fail(fmt::format("unknown background type '{}' (expected 'sky', 'constant' or 'environment')", clip(type)));
    }
  }

  // `pointer`: where it was written; for a solid texture, its colour array.
  u32 add_texture(const Texture<double>& t, const std::string& pointer) {
    scene_.textures.push_back(t);
    scene_.written.textures.push_back(pointer);
    return static_cast<u32>(scene_.textures.size() - 1);
  }

  u32 read_texture(const Node& n) {
    const std::string type = n.at("type").string();
    if (type == "solid") {
      n.allow_keys({"type", "color"});
      const Node color = n.at("color");
      return add_texture(SolidTexture<double>{color.color()}, color.pointer());
    }
    if (type == "checker") {
      n.allow_keys({"type", "odd", "even", "frequency"});
      const double f = n.has("frequency") ? n.child("frequency").positive() : 10.0;
      return add_texture(CheckerTexture<double>{n.at("odd").color(), n.at("even").color(), f / 3.14159265358979323846}, n.pointer());
    }
    if (type == "uv_checker") {
      n.allow_keys({"type", "odd", "even", "columns", "rows"});
      const double columns = n.has("columns") ? n.child("columns").integer(1, 1u << 20) : 8;
      const double rows = n.has("rows") ? n.child("rows").integer(1, 1u << 20) : 8;
      return add_texture(UvCheckerTexture<double>{n.at("odd").color(), n.at("even").color(), columns, rows}, n.pointer());
    }
    if (type == "image") {
      n.allow_keys({"type", "file", "repeat"});
      const Node file = n.at("file");
      const std::string name = file.string();
      if (name.empty()) file.fail("the image file name is empty");
      const double repeat = n.has("repeat") ? n.child("repeat").positive() : 1.0;
      const ImageRef image = load_image(file, name);
      return add_image_texture(image, repeat, 0, n.pointer());
    }
    if (type == "noise") {
      n.allow_keys({"type", "kind", "scale", "turbulence_depth"});
      NoiseKind kind = NoiseKind::kPerlin;
      if (n.has("kind")) {
        const std::string k = n.child("kind").string();
        if (k == "perlin")
          kind = NoiseKind::kPerlin;
        else if (k == "turbulence")
          kind = NoiseKind::kTurbulence;
        else if (k == "marble")
          kind = NoiseKind::kMarble;
        else
          n.child("kind").fail(fmt::format("unknown noise kind '{}' (expected 'perlin', 'turbulence' or 'marble')", clip(k)));
      }
      const double scale = n.has("scale") ? n.child("scale").positive() : 1.0;
      const u32 depth = n.has("turbulence_depth") ? n.child("turbulence_depth").integer(1, 16) : 7;
      return add_texture(NoiseTexture<double>{scale, kind, depth, 1}, n.pointer());
    }
    n.child("type").fail(fmt::format("unknown texture type '{}' (expected solid, checker, uv_checker, image or noise)", clip(type)));
  }

  struct ImageRef {
    u32 width, height;
    std::size_t image;  // in pending_images_
  };

  // An image being decoded later (decode_images): its file, the place that named it, where its texels go among
  // the scene file's images, and their size.
  struct PendingImage {
    std::filesystem::path path;
    std::string place;
    u64 byte_offset, bytes;
  };

  // A texture of an image whose texels are placed once decoded: `linear` for data (normal maps) rather than colour.
  u32 add_image_texture(const ImageRef& image, double repeat, u32 linear, const std::string& pointer) {
    const u32 texture = add_texture(ImageTexture<double>{image.width, image.height, 0, repeat, {1, 1, 1}, linear}, pointer);
    image_textures_.emplace_back(texture, image.image);
    return texture;
  }

  // An image's place among the scene's texels, from its header: images are decoded only once the whole scene is
  // read (decode_images), so that images too large together are refused before any is decoded.
  ImageRef load_image(const Node& where, const std::string& name) {
    const std::filesystem::path path = base_folder_ / name;
    const std::string key = path.lexically_normal().string();
    if (const auto it = images_.find(key); it != images_.end()) return it->second;
    TextureSize size;
    try {
      size = read_texture_image_size(path);
    } catch (const InputError& e) {
      where.fail(e.what());
    }
    const u64 bytes = u64{3} * size.width * size.height;
    if (scene_.texels.size() + pending_texel_bytes_ + bytes > kMaxSceneTexelBytes)
      where.fail(
          fmt::format("the scene's images are too large in total (at most {} MiB of texels; see docs/scene-format.md)", kMaxSceneTexelBytes >> 20));
    pending_images_.push_back(PendingImage{path, where.place(), pending_texel_bytes_, bytes});
    const ImageRef ref{size.width, size.height, pending_images_.size() - 1};
    pending_texel_bytes_ += bytes;
    images_.emplace(key, ref);
    return ref;
  }

  // Decodes the images the scene file names into the scene's texels, after those of its model files, and sets the
  // texel offsets of the textures that use them.
  void decode_images() {
    const u64 base = scene_.texels.size();
    scene_.texels.reserve(base + pending_texel_bytes_);
    for (const PendingImage& pending : pending_images_) {
      TextureImage image;
      try {
        image = read_texture_image(pending.path);
      } catch (const InputError& e) {
        throw InputError(fmt::format("{}: {}", pending.place, e.what()));
      }
      if (image.srgb.size() != pending.bytes)  // the file changed since its header was read
        throw InputError(fmt::format("{}: image file '{}' changed while the scene was read", pending.place, pending.path.string()));
      scene_.texels.insert(scene_.texels.end(), image.srgb.begin(), image.srgb.end());  // at base + pending.byte_offset
    }
    for (const auto& [texture, image] : image_textures_) {
      ImageTexture<double>& t = std::get<ImageTexture<double>>(scene_.textures[texture]);
      t.offset = static_cast<u32>((base + pending_images_[image].byte_offset) / 3);
    }
  }

  // A texture given by name, inline object, or (with `color_key`) a plain colour.
  u32 read_texture_reference(const Node& n) {
    if (n.json().is_string()) {
      const std::string name = n.string();
      const auto it = texture_names_.find(name);
      if (it == texture_names_.end()) n.fail(fmt::format("unknown texture '{}'", clip(name)));
      return it->second;
    }
    if (n.json().is_object()) return read_texture(n);
    n.fail(fmt::format("expected a texture name or a texture object, found {}", type_name(n.json())));
  }

  u32 read_colour_or_texture(const Node& n, const char* color_key) {
    if (n.has(color_key) && n.has("texture")) n.fail(fmt::format("give either '{}' or 'texture', not both", color_key));
    if (n.has("texture")) return read_texture_reference(n.child("texture"));
    const Node color = n.at(color_key);
    return add_texture(SolidTexture<double>{color.color()}, color.pointer());
  }

  u32 add_material(const Material<double>& m, const std::string& pointer) {
    scene_.materials.push_back(m);
    scene_.written.materials.push_back(pointer);
    return static_cast<u32>(scene_.materials.size() - 1);
  }

  u32 read_material(const Node& n) {
    const std::string type = n.at("type").string();
    if (type == "lambertian") {
      n.allow_keys({"type", "albedo", "texture"});
      return add_material(Lambertian<double>{read_colour_or_texture(n, "albedo")}, n.pointer());
    }
    if (type == "metal") {
      n.allow_keys({"type", "albedo", "fuzz"});
      const double fuzz = n.has("fuzz") ? n.child("fuzz").number_in(0, 1) : 0.0;
      return add_material(Metal<double>{n.at("albedo").color(), fuzz}, n.pointer());
    }
    if (type == "dielectric") {
      n.allow_keys({"type", "ior", "tint"});
      const double ior = n.has("ior") ? n.child("ior").positive() : 1.5;
      const Vec3d tint = n.has("tint") ? n.child("tint").color() : Vec3d{1, 1, 1};
      return add_material(Dielectric<double>{ior, tint}, n.pointer());
    }
    if (type == "diffuse_light") {
      n.allow_keys({"type", "emission", "texture"});
      return add_material(DiffuseLight<double>{read_colour_or_texture(n, "emission")}, n.pointer());
    }
    if (type == "isotropic") {
      n.allow_keys({"type", "albedo", "texture"});
      return add_material(Isotropic<double>{read_colour_or_texture(n, "albedo")}, n.pointer());
    }
    if (type == "metallic_roughness") {
      n.allow_keys({"type", "base_color", "texture", "metallic", "roughness", "metallic_roughness_texture", "normal_map", "normal_scale"});
      const u32 base = read_colour_or_texture(n, "base_color");
      const double metallic = n.has("metallic") ? n.child("metallic").number_in(0, 1) : 0.0;
      const double roughness = n.has("roughness") ? n.child("roughness").number_in(0, 1) : 0.5;
      u32 factors;
      if (n.has("metallic_roughness_texture")) {
        // glTF's layout: roughness in green, metallic in blue, the bytes read as linear data, times the factors.
        const Node map = n.child("metallic_roughness_texture");
        const u32 texture = read_texture_reference(map);
        const auto* image = std::get_if<ImageTexture<double>>(&scene_.textures[texture]);
        if (!image) map.fail("a metallic-roughness texture must be an image (roughness in its green channel, metallic in its blue one)");
        ImageTexture<double> data = *image;
        data.linear = 1;
        data.factor = {1, roughness, metallic};
        factors = add_texture(data, map.pointer());
      } else {
        factors = add_texture(SolidTexture<double>{{0, roughness, metallic}}, n.pointer());
      }
      u32 normal_map = kNoNormalMap;
      if (n.has("normal_map")) {
        // A tangent-space normal map (glTF's normalTexture): an image file, its bytes read as linear data.
        const Node map = n.child("normal_map");
        const std::string name = map.string();
        if (name.empty()) map.fail("the normal map's file name is empty");
        const ImageRef image = load_image(map, name);
        normal_map = add_image_texture(image, 1.0, 1, map.pointer());
      }
      if (n.has("normal_scale") && !n.has("normal_map")) n.child("normal_scale").fail("'normal_scale' needs a 'normal_map'");
      const double normal_scale = n.has("normal_scale") ? n.child("normal_scale").number_in(-100, 100) : 1.0;
      return add_material(MetallicRoughness<double>{base, factors, normal_map, normal_scale}, n.pointer());
    }
    n.child("type").fail(fmt::format(
        "unknown material type '{}' (expected lambertian, metal, dielectric, diffuse_light, isotropic or metallic_roughness)", clip(type)));
  }

  u32 read_material_reference(const Node& n) {
    if (n.json().is_string()) {
      const std::string name = n.string();
      const auto it = material_names_.find(name);
      if (it == material_names_.end()) n.fail(fmt::format("unknown material '{}'", clip(name)));
      return it->second;
    }
    if (n.json().is_object()) return read_material(n);
    n.fail(fmt::format("expected a material name or a material object, found {}", type_name(n.json())));
  }

  RigidTransform read_transform(const Node& n) {
    n.allow_keys({"rotate", "translate"});
    const Vec3d degrees = n.has("rotate") ? n.child("rotate").vec3() : Vec3d{};
    const Vec3d translation = n.has("translate") ? n.child("translate").vec3() : Vec3d{};
    return RigidTransform::from_euler_degrees(degrees, translation);
  }

  BoxSettings read_box(const Node& n) {
    const Node lo = n.at("min"), hi = n.at("max");
    const BoxSettings box{lo.vec3(), hi.vec3()};
    if (!(box.min.x < box.max.x && box.min.y < box.max.y && box.min.z < box.max.z)) hi.fail("every component of max must exceed min");
    return box;
  }

  Sphere<double> read_sphere(const Node& n) { return {n.at("center").vec3(), n.at("radius").positive()}; }

  // A mesh's transform: scale (one factor or three), then rotate, then translate.
  AffineTransform read_mesh_transform(const Node& n) {
    n.allow_keys({"scale", "rotate", "translate"});
    Vec3d factors{1, 1, 1};
    if (n.has("scale")) {
      const Node scale = n.child("scale");
      if (scale.json().is_number()) {
        const double f = scale.number();
        factors = {f, f, f};
      } else {
        factors = scale.vec3();
      }
      if (!(factors.x != 0 && factors.y != 0 && factors.z != 0)) scale.fail("a scale factor must not be zero");
    }
    const Vec3d degrees = n.has("rotate") ? n.child("rotate").vec3() : Vec3d{};
    const Vec3d translation = n.has("translate") ? n.child("translate").vec3() : Vec3d{};
    return AffineTransform::scaling(factors).then(AffineTransform::from_rigid(RigidTransform::from_euler_degrees(degrees, translation)));
  }

  // A model file, read once however many objects place it.
  u32 read_mesh_file_reference(const Node& n) {
    const std::filesystem::path path = base_folder_ / n.string();
    const std::string key = path.lexically_normal().string();
    if (const auto it = mesh_files_.find(key); it != mesh_files_.end()) return it->second;
    try {
      const u32 index = add_mesh_file(scene_, std::make_shared<const MeshFile>(read_mesh_file(path, references_)), n.pointer());
      if (scene_.texels.size() + pending_texel_bytes_ > kMaxSceneTexelBytes)  // with the scene file's images, not yet decoded
        n.fail(
            fmt::format("the scene's images are too large in total (at most {} MiB of texels; see docs/scene-format.md)", kMaxSceneTexelBytes >> 20));
      mesh_files_.emplace(key, index);
      return index;
    } catch (const InputError& e) {
      n.fail(e.what());
    }
  }

  void read_object(const Node& n) {
    const std::string type = n.at("type").string();
    SceneObject object;
    if (n.has("transform") && type != "mesh") object.transform = read_transform(n.child("transform"));
    const bool surface = type != "medium";
    if (type == "mesh") {
      n.allow_keys({"type", "file", "transform", "material"});
      MeshSettings mesh{read_mesh_file_reference(n.at("file")), AffineTransform{}};
      if (n.has("transform")) mesh.transform = read_mesh_transform(n.child("transform"));
      object.shape = mesh;
      object.material = kMeshMaterials;
      if (n.has("material")) {
        const Node material = n.child("material");
        object.material = read_material_reference(material);
        if (std::holds_alternative<Isotropic<double>>(scene_.materials[object.material]))
          material.fail("an isotropic material only belongs to a medium");
      }
      scene_.objects.push_back(object);
      return;
    }
    if (type == "sphere") {
      n.allow_keys({"type", "center", "radius", "material", "transform"});
      object.shape = read_sphere(n);
    } else if (type == "moving_sphere") {
      n.allow_keys({"type", "center0", "center1", "radius", "time0", "time1", "material", "transform"});
      MovingSphereSettings s{n.at("center0").vec3(), n.at("center1").vec3(), n.at("radius").positive(), 0.0, 1.0};
      if (n.has("time0")) s.time0 = n.child("time0").number();
      if (n.has("time1")) s.time1 = n.child("time1").number();
      if (!(s.time1 > s.time0)) n.child(n.has("time1") ? "time1" : "time0").fail("time1 must be later than time0");
      object.shape = s;
    } else if (type == "triangle") {
      n.allow_keys({"type", "vertices", "normals", "uvs", "material", "transform"});
      TriangleSettings t;
      const Node vertices = n.at("vertices");
      vertices.array_size(3, 3);
      for (std::size_t i = 0; i < 3; ++i) t.vertices[i] = vertices.element(i).vec3();
      if (length_squared(cross(t.vertices[1] - t.vertices[0], t.vertices[2] - t.vertices[0])) == 0)
        vertices.fail("the triangle is degenerate (zero area)");
      if (n.has("normals")) {
        const Node normals = n.child("normals");
        normals.array_size(3, 3);
        std::array<Vec3d, 3> list;
        for (std::size_t i = 0; i < 3; ++i) list[i] = normals.element(i).nonzero_vec3();
        t.normals = list;
      }
      if (n.has("uvs")) {
        const Node uvs = n.child("uvs");
        uvs.array_size(3, 3);
        std::array<std::array<double, 2>, 3> list;
        for (std::size_t i = 0; i < 3; ++i) {
          const Node uv = uvs.element(i);
          uv.array_size(2, 2);
          list[i] = {uv.element(0).number(), uv.element(1).number()};
        }
        t.uvs = list;
      }
      object.shape = t;
    } else if (type == "quad") {
      n.allow_keys({"type", "corner", "u", "v", "material", "transform"});
      const QuadSettings q{n.at("corner").vec3(), n.at("u").vec3(), n.at("v").vec3()};
      if (length_squared(cross(q.u, q.v)) == 0) n.child("v").fail("u and v must span a parallelogram (they are parallel or zero)");
      object.shape = q;
    } else if (type == "box") {
      n.allow_keys({"type", "min", "max", "material", "transform"});
      object.shape = read_box(n);
    } else if (type == "medium") {
      n.allow_keys({"type", "boundary", "density", "material", "transform"});
      const Node boundary = n.at("boundary");
      const std::string boundary_type = boundary.at("type").string();
      MediumSettings medium{Sphere<double>{}, RigidTransform{}, n.at("density").positive()};
      if (boundary.has("transform")) medium.boundary_transform = read_transform(boundary.child("transform"));
      if (boundary_type == "sphere") {
        boundary.allow_keys({"type", "center", "radius", "transform"});
        medium.boundary = read_sphere(boundary);
      } else if (boundary_type == "box") {
        boundary.allow_keys({"type", "min", "max", "transform"});
        medium.boundary = read_box(boundary);
      } else {
        boundary.child("type").fail(fmt::format("a medium boundary must be a sphere or a box, not '{}'", clip(boundary_type)));
      }
      object.shape = medium;
    } else {
      n.child("type").fail(fmt::format("unknown object type '{}' (expected sphere, moving_sphere, triangle, quad, box, medium or mesh)", clip(type)));
    }
    const Node material = n.at("material");
    object.material = read_material_reference(material);
    const bool isotropic = std::holds_alternative<Isotropic<double>>(scene_.materials[object.material]);
    if (!surface && !isotropic) material.fail("a medium's material must be isotropic");
    if (surface && isotropic) material.fail("an isotropic material only belongs to a medium");
    scene_.objects.push_back(object);
  }

  const Document& document_;
  std::filesystem::path base_folder_;
  ModelReferences references_;
  SceneDescription& scene_;
  std::map<std::string, u32> texture_names_, material_names_;
  std::map<std::string, ImageRef> images_;
  std::vector<PendingImage> pending_images_;
  u64 pending_texel_bytes_ = 0;
  std::vector<std::pair<u32, std::size_t>> image_textures_;  // texture, image in pending_images_
  std::map<std::string, u32> mesh_files_;
};

}  // namespace

u32 add_mesh_file(SceneDescription& scene, std::shared_ptr<const MeshFile> file, const std::string& pointer) {
  SceneMeshFile entry;
  // The file's textures, each added to the scene's texels once, where a material uses it.
  std::vector<std::optional<u32>> texel_offsets(file->textures.size());
  auto colour = [&](const Vec3d& factor, i32 texture) {
    if (texture < 0 || static_cast<std::size_t>(texture) >= file->textures.size()) {
      scene.textures.push_back(SolidTexture<double>{factor});
    } else {
      const TextureImage& image = file->textures[texture];
      if (!texel_offsets[texture]) {
        if (scene.texels.size() + image.srgb.size() > kMaxSceneTexelBytes)
          throw InputError(fmt::format("{}: the scene's images are too large in total (at most {} MiB of texels; see docs/scene-format.md)",
                                       file->path.string(), kMaxSceneTexelBytes >> 20));
        texel_offsets[texture] = static_cast<u32>(scene.texels.size() / 3);
        scene.texels.insert(scene.texels.end(), image.srgb.begin(), image.srgb.end());
      }
      scene.textures.push_back(ImageTexture<double>{image.width, image.height, *texel_offsets[texture], 1.0, factor});
    }
    scene.written.textures.push_back(pointer);
    return static_cast<u32>(scene.textures.size() - 1);
  };
  // A metallic-roughness texture: the file's image read as linear data (green roughness, blue metallic), times the
  // factors; without an image, the factors as a solid colour.
  auto metallic_roughness = [&](const MeshMaterial& m) {
    const Vec3d factors{0, std::clamp(m.roughness, 0.0, 1.0), std::clamp(m.metallic, 0.0, 1.0)};
    const i32 texture = m.metallic_roughness_texture;
    if (texture < 0 || static_cast<std::size_t>(texture) >= file->textures.size()) return colour(factors, -1);
    const u32 index = colour(Vec3d{1, factors.y, factors.z}, texture);
    std::get<ImageTexture<double>>(scene.textures[index]).linear = 1;
    return index;
  };
  // A normal map: the file's image read as linear data, unscaled (normal_scale is the material's).
  auto normal_map = [&](const MeshMaterial& m) {
    const i32 texture = m.normal_texture;
    if (texture < 0 || static_cast<std::size_t>(texture) >= file->textures.size()) return kNoNormalMap;
    const u32 index = colour(Vec3d{1, 1, 1}, texture);
    std::get<ImageTexture<double>>(scene.textures[index]).linear = 1;
    return index;
  };
  for (const MeshMaterial& m : file->materials) {
    // Emissive surfaces become lights (which do not also reflect); the others reflect by the metallic-roughness
    // model, or diffusely where the file gives only a colour (MeshMaterial::metallic_roughness_model).
    const bool emits = m.emission_texture >= 0 || m.emission.x > 0 || m.emission.y > 0 || m.emission.z > 0;
    if (emits)
      scene.materials.push_back(DiffuseLight<double>{colour(m.emission, m.emission_texture)});
    else if (m.metallic_roughness_model)
      scene.materials.push_back(
          MetallicRoughness<double>{colour(m.base_color, m.base_color_texture), metallic_roughness(m), normal_map(m), m.normal_scale});
    else
      scene.materials.push_back(Lambertian<double>{colour(m.base_color, m.base_color_texture)});
    scene.written.materials.push_back(pointer);
    entry.materials.push_back(static_cast<u32>(scene.materials.size() - 1));
  }
  for (const std::string& warning : file->warnings) scene.warnings.push_back(fmt::format("{}: {}", file->path.string(), warning));
  entry.file = std::move(file);
  scene.mesh_files.push_back(std::move(entry));
  return static_cast<u32>(scene.mesh_files.size() - 1);
}

namespace {

// `passed`, where given, hears how far the outline and the objects have been read (MappedFile::passed).
SceneDescription parse_scene_view(std::string_view text, const std::string& source, const std::filesystem::path& base_folder,
                                  ModelReferences references, const std::function<void(std::size_t)>& passed = {}) {
  const JsonOutline outline = read_json_outline(text, source, passed);
  const Document document{source, text, passed};
  SceneDescription scene;
  scene.source = source;
  SceneReader reader(document, base_folder, references, scene);
  reader.read(Node(outline.root, "", document, ParsedFrom{TextRange{0, text.size()}, 0}), outline);
  return scene;
}

SceneDescription parse_scene_text(std::shared_ptr<const std::string> text, const std::string& source, const std::filesystem::path& base_folder,
                                  ModelReferences references) {
  SceneDescription scene = parse_scene_view(*text, source, base_folder, references);
  scene.written.text = std::move(text);
  return scene;
}

}  // namespace

SceneDescription parse_scene(std::string_view text, const std::string& source, const std::filesystem::path& base_folder, ModelReferences references) {
  return parse_scene_text(std::make_shared<const std::string>(text), source, base_folder, references);
}

namespace {

// Scene files of at least this size are mapped rather than read into memory.
constexpr off_t kMappedSceneSize = off_t{16} << 20;

bool is_model_file(const std::filesystem::path& file) {
  std::string extension = file.extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return extension == ".obj" || extension == ".ply" || extension == ".gltf" || extension == ".glb";
}

// A camera that frames the box from the front (+z), a little above, with the whole box in a 40-degree view.
CameraSettings framing_camera(const Vec3d& lo, const Vec3d& hi) {
  CameraSettings camera;
  const Vec3d center = (lo + hi) * 0.5;
  const double radius = std::max(length(hi - lo) * 0.5, 1e-9);
  camera.vertical_fov = 40;
  const double distance = 1.1 * radius / std::sin(camera.vertical_fov * 3.14159265358979323846 / 360.0);
  camera.look_at = center;
  camera.look_from = center + normalize(Vec3d{0, 0.35, 1}) * distance;
  camera.focus_distance = distance;
  return camera;
}

}  // namespace

SceneDescription scene_from_model_file(const std::filesystem::path& file, ModelReferences references) {
  SceneDescription scene;
  scene.source = file.string();
  auto model = std::make_shared<const MeshFile>(read_mesh_file(file, references));
  Vec3d lo = Vec3d::splat(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const MeshPlacement& placement : model->placements)
    for (const std::array<u32, 3>& triangle : model->meshes[placement.mesh].triangles)
      for (const u32 v : triangle) {
        const Vec3d p = placement.transform.apply_point(model->meshes[placement.mesh].positions[v]);
        if (!is_finite(p))
          throw InputError(fmt::format("{}: vertex {} of mesh '{}' is placed beyond a double's range (about 1.8e308)", file.string(), v,
                                       clip(model->meshes[placement.mesh].name)));
        lo = vmin(lo, p);
        hi = vmax(hi, p);
      }
  if (!(lo.x <= hi.x)) throw InputError(fmt::format("{}: the model has no triangles to render", file.string()));
  scene.camera = model->camera ? *model->camera : framing_camera(lo, hi);
  scene.model_as_scene = true;
  scene.camera_frames_model = !model->camera;
  SceneObject object;
  object.shape = MeshSettings{add_mesh_file(scene, model, "(model)"), AffineTransform{}};
  object.material = kMeshMaterials;
  scene.objects.push_back(object);
  return scene;
}

SceneDescription load_scene_file(const std::filesystem::path& file, ModelReferences references) {
  if (is_model_file(file)) return scene_from_model_file(file, references);
  InputFile input = InputFile::open(file);
  switch (input.problem()) {
    case InputFile::Problem::kNone: break;
    case InputFile::Problem::kMissing: throw InputError(fmt::format("{}: cannot open the scene file", file.string()));
    case InputFile::Problem::kFolder: throw InputError(fmt::format("{}: is a folder, not a scene file", file.string()));
    case InputFile::Problem::kNotRegular: throw InputError(fmt::format("{}: is {}, not a scene file", file.string(), input.reason()));
    case InputFile::Problem::kCannotOpen: throw InputError(fmt::format("{}: cannot open the scene file: {}", file.string(), input.reason()));
  }
  SceneDescription scene;
  // A large scene is read through a mapping, its passed pages let go as the outline and the objects are read: the
  // text of a 200 MB scene then costs the process little of its peak. Small ones, and files that cannot be mapped,
  // are read whole.
  struct stat status {};
  const bool large = ::fstat(input.descriptor(), &status) == 0 && status.st_size >= kMappedSceneSize;
  std::unique_ptr<MappedFile> mapped = large ? MappedFile::map(input.descriptor(), static_cast<std::size_t>(status.st_size), file.string()) : nullptr;
  if (mapped) {
    scene = parse_scene_view(mapped->text(), file.string(), file.parent_path(), references, [&](std::size_t offset) { mapped->passed(offset); });
  } else {
    std::string text;
    if (!input.read_all(text)) throw InputError(fmt::format("{}: cannot read the scene file", file.string()));
    scene = parse_scene_view(text, file.string(), file.parent_path(), references);  // its text read again from the file for a message
  }
  scene.written.file = file;
  return scene;
}

}  // namespace pt
