// The glTF reader's first pass over the JSON: types, ranges, references, byte ranges, the node hierarchy, data
// URIs, external buffer files and required extensions, each fault reported with its JSON path.
#include "loading/gltf_json_check.hpp"

#include <sys/stat.h>

#include <array>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <set>
#include <string_view>

#include <fmt/format.h>

#include "base/errors.hpp"
#include "loading/model_file_input.hpp"

namespace pt::gltf {

using json = nlohmann::json;

void check_json_nesting(const std::string& file_name, const char* text, std::size_t size) {
  std::size_t depth = 0;
  bool in_string = false;
  for (std::size_t i = 0; i < size; ++i) {
    const char c = text[i];
    if (in_string) {
      if (c == '\\')
        ++i;
      else if (c == '"')
        in_string = false;
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > kMaxJsonNesting)
        throw InputError(fmt::format("{}: JSON nesting deeper than {} levels (at byte {})", file_name, kMaxJsonNesting, i));
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    }
  }
}

std::string decode_uri(const std::string& uri) {
  const auto hex = [](char c) -> unsigned {
    if (c >= '0' && c <= '9') return static_cast<unsigned>(c - '0');
    if (c >= 'a' && c <= 'f') return static_cast<unsigned>(c - 'a' + 10);
    if (c >= 'A' && c <= 'F') return static_cast<unsigned>(c - 'A' + 10);
    return 0;
  };
  std::string out;
  out.reserve(uri.size());
  for (std::size_t i = 0; i < uri.size(); ++i) {
    if (uri[i] == '+') {
      out += ' ';
    } else if (uri[i] == '%' && i + 2 < uri.size()) {
      out += static_cast<char>((hex(uri[i + 1]) << 4) | hex(uri[i + 2]));
      i += 2;
    } else {
      out += uri[i];
    }
  }
  return out;
}

namespace {

// The extensions the reader reads; a file may require these.
constexpr std::array<std::string_view, 1> kExtensionsRead = {"KHR_materials_emissive_strength"};

// The data URIs tinygltf decodes (base64 only).
constexpr std::array<std::string_view, 7> kDataUriPrefixes = {"data:application/octet-stream;base64,",
                                                              "data:application/gltf-buffer;base64,",
                                                              "data:image/jpeg;base64,",
                                                              "data:image/png;base64,",
                                                              "data:image/bmp;base64,",
                                                              "data:image/gif;base64,",
                                                              "data:text/plain;base64,"};

const char* kind_of(const json& v) {
  switch (v.type()) {
    case json::value_t::null: return "null";
    case json::value_t::object: return "an object";
    case json::value_t::array: return "an array";
    case json::value_t::string: return "a string";
    case json::value_t::boolean: return "a boolean";
    case json::value_t::number_integer:
    case json::value_t::number_unsigned: return "an integer";
    case json::value_t::number_float: return "a floating-point number";
    default: return "binary data";
  }
}

// A JSON pointer's reference token for a key ('~' and '/' escaped).
std::string token(std::string_view key) {
  std::string out;
  for (const char c : key) {
    if (c == '~')
      out += "~0";
    else if (c == '/')
      out += "~1";
    else
      out += c;
  }
  return out;
}

std::string at(const std::string& path, std::string_view key) { return path + "/" + token(key); }
std::string at(const std::string& path, std::size_t index) { return fmt::format("{}/{}", path, index); }

// The byte size of one element of an accessor, with the column padding of small matrices.
u64 element_size(u64 component_type, const std::string& type) {
  const u64 component = component_type == 5120 || component_type == 5121 ? 1 : component_type == 5122 || component_type == 5123 ? 2 : 4;
  if (type == "SCALAR") return component;
  if (type == "VEC2") return 2 * component;
  if (type == "VEC3") return 3 * component;
  if (type == "VEC4") return 4 * component;
  // Matrix columns start on 4-byte boundaries.
  const u64 rows = type == "MAT2" ? 2 : type == "MAT3" ? 3 : 4;
  const u64 column = (rows * component + 3) / 4 * 4;
  return rows * column;
}

u64 component_count(const std::string& type) {
  if (type == "SCALAR") return 1;
  if (type == "VEC2") return 2;
  if (type == "VEC3") return 3;
  if (type == "VEC4" || type == "MAT2") return 4;
  if (type == "MAT3") return 9;
  return 16;
}

class Checker {
 public:
  explicit Checker(const JsonCheckInput& input) : input_(input) {}

  [[noreturn]] void fail(const std::string& path, const std::string& problem) const {
    throw InputError(fmt::format("{}: {}: {}", input_.file_name, path.empty() ? "/" : path, problem));
  }

  const json& object(const json& value, const std::string& path) const {
    if (!value.is_object()) fail(path, fmt::format("expected an object, found {}", kind_of(value)));
    return value;
  }

  static const json* find(const json& object, const char* key) {
    const auto it = object.find(key);
    return it == object.end() ? nullptr : &*it;
  }

  const json* get(const json& object, const char* key, const std::string& path, bool required) const {
    const json* value = find(object, key);
    if (!value && required) fail(path, fmt::format("'{}' is missing", key));
    return value;
  }

  // A non-negative integer (tinygltf reads a property of another type as absent).
  std::optional<u64> uint(const json& object, const char* key, const std::string& path, bool required, u64 min = 0,
                          u64 max = std::numeric_limits<u64>::max()) const {
    const json* value = get(object, key, path, required);
    if (!value) return std::nullopt;
    const std::string where = at(path, key);
    if (value->is_number_unsigned()) {
      const u64 x = value->get<u64>();
      if (x < min || x > max) fail(where, fmt::format("{} is out of range ({} to {})", x, min, max));
      return x;
    }
    if (value->is_number_integer()) fail(where, fmt::format("{} is negative", value->get<std::int64_t>()));
    fail(where, fmt::format("expected a non-negative integer, found {}", kind_of(*value)));
  }

  void index_in(u64 index, const std::string& where, std::size_t count, const char* array) const {
    if (index >= count) fail(where, fmt::format("index {} is out of range (/{} has {} entries)", index, array, count));
  }

  // An index into one of the file's arrays, or -1.
  std::int64_t index(const json& object, const char* key, const std::string& path, std::size_t count, const char* array,
                     bool required = false) const {
    const std::optional<u64> x = uint(object, key, path, required);
    if (!x) return -1;
    index_in(*x, at(path, key), count, array);
    return static_cast<std::int64_t>(*x);
  }

  // An array of indices into one of the file's arrays.
  std::vector<u64> indices(const json& object, const char* key, const std::string& path, std::size_t count, const char* array, bool required = false,
                           std::size_t min_items = 0) const {
    std::vector<u64> out;
    const json* list = array_of(object, key, path, required, min_items);
    if (!list) return out;
    const std::string where = at(path, key);
    for (std::size_t i = 0; i < list->size(); ++i) {
      const json& item = (*list)[i];
      if (item.is_number_integer() && !item.is_number_unsigned()) fail(at(where, i), fmt::format("{} is negative", item.get<std::int64_t>()));
      if (!item.is_number_unsigned()) fail(at(where, i), fmt::format("expected an index, found {}", kind_of(item)));
      index_in(item.get<u64>(), at(where, i), count, array);
      out.push_back(item.get<u64>());
    }
    return out;
  }

  std::optional<double> number(const json& object, const char* key, const std::string& path, bool required,
                               double min = -std::numeric_limits<double>::infinity(), double max = std::numeric_limits<double>::infinity()) const {
    const json* value = get(object, key, path, required);
    if (!value) return std::nullopt;
    if (!value->is_number()) fail(at(path, key), fmt::format("expected a number, found {}", kind_of(*value)));
    const double x = value->get<double>();
    if (x < min || x > max) fail(at(path, key), fmt::format("{} is out of range ({} to {})", x, min, max));
    return x;
  }

  // An array of `length` numbers (any length where 0), each in [min, max].
  std::vector<double> numbers(const json& object, const char* key, const std::string& path, std::size_t length,
                              double min = -std::numeric_limits<double>::infinity(), double max = std::numeric_limits<double>::infinity()) const {
    std::vector<double> out;
    const json* list = array_of(object, key, path, false);
    if (!list) return out;
    const std::string where = at(path, key);
    if (length != 0 && list->size() != length) fail(where, fmt::format("expected {} numbers, found {}", length, list->size()));
    for (std::size_t i = 0; i < list->size(); ++i) {
      const json& item = (*list)[i];
      if (!item.is_number()) fail(at(where, i), fmt::format("expected a number, found {}", kind_of(item)));
      const double x = item.get<double>();
      if (x < min || x > max) fail(at(where, i), fmt::format("{} is out of range ({} to {})", x, min, max));
      out.push_back(x);
    }
    return out;
  }

  std::optional<std::string> string(const json& object, const char* key, const std::string& path, bool required) const {
    const json* value = get(object, key, path, required);
    if (!value) return std::nullopt;
    if (!value->is_string()) fail(at(path, key), fmt::format("expected a string, found {}", kind_of(*value)));
    return value->get<std::string>();
  }

  // A string that must be one of `choices`.
  template <std::size_t N>
  std::optional<std::string> choice(const json& object, const char* key, const std::string& path, bool required,
                                    const std::array<const char*, N>& choices) const {
    const std::optional<std::string> value = string(object, key, path, required);
    if (!value) return value;
    for (const char* c : choices)
      if (*value == c) return value;
    std::string list;
    for (const char* c : choices) list += (list.empty() ? "" : ", ") + std::string(c);
    fail(at(path, key), fmt::format("'{}' is not one of {}", *value, list));
  }

  void boolean(const json& object, const char* key, const std::string& path) const {
    const json* value = find(object, key);
    if (value && !value->is_boolean()) fail(at(path, key), fmt::format("expected true or false, found {}", kind_of(*value)));
  }

  const json* array_of(const json& object, const char* key, const std::string& path, bool required, std::size_t min_items = 0) const {
    const json* value = get(object, key, path, required);
    if (!value) return nullptr;
    if (!value->is_array()) fail(at(path, key), fmt::format("expected an array, found {}", kind_of(*value)));
    if (value->size() < min_items) fail(at(path, key), fmt::format("expected at least {} entries, found {}", min_items, value->size()));
    return value;
  }

  // An enumerated integer property.
  void enumerated(const json& object, const char* key, const std::string& path, std::initializer_list<u64> values) const {
    const std::optional<u64> x = uint(object, key, path, false);
    if (!x) return;
    for (const u64 v : values)
      if (*x == v) return;
    fail(at(path, key), fmt::format("{} is not a valid value here", *x));
  }

  // `extensions` (an object of objects; their names are noted) and `extras` (anything).
  void extensions(const json& object, const std::string& path) {
    const json* value = find(object, "extensions");
    if (!value) return;
    const std::string where = at(path, "extensions");
    this->object(*value, where);
    for (auto it = value->begin(); it != value->end(); ++it) {
      this->object(it.value(), at(where, it.key()));
      seen_extensions_.insert(it.key());
    }
  }

  // A data URI as tinygltf decodes it; returns the number of bytes it holds.
  u64 data_uri(const std::string& uri, const std::string& where) const {
    std::size_t payload = std::string::npos;
    for (const std::string_view prefix : kDataUriPrefixes)
      if (uri.compare(0, prefix.size(), prefix) == 0) payload = prefix.size();
    if (payload == std::string::npos) {
      const std::size_t comma = uri.find(',');
      fail(where, fmt::format("a data URI of the kind '{}' is not read (only base64 data of application/octet-stream, "
                              "application/gltf-buffer, image/png, image/jpeg, image/bmp or image/gif)",
                              uri.substr(0, std::min<std::size_t>(comma, 64))));
    }
    // tinygltf's decoder counts the length in an int.
    if (uri.size() - payload > static_cast<std::size_t>(std::numeric_limits<int>::max()))
      fail(where, fmt::format("a data URI of {} characters, more than can be read", uri.size()));
    const auto base64 = [](char c) { return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '+' || c == '/'; };
    std::size_t end = payload;
    while (end < uri.size() && base64(uri[end])) ++end;
    const std::size_t digits = end - payload;
    std::size_t padding = 0;
    while (end < uri.size() && uri[end] == '=' && padding < 2) ++end, ++padding;
    if (end != uri.size()) fail(where, fmt::format("the data URI is not valid base64 (a '{}' at character {})", uri[end], end));
    if (digits % 4 == 1) fail(where, "the data URI is not valid base64 (its length is wrong)");
    return digits / 4 * 3 + (digits % 4 == 0 ? 0 : digits % 4 - 1);
  }

  // A URI naming a file beside the model: returns its path as tinygltf asks for it.
  std::string file_uri(const std::string& uri, const std::string& where) const {
    if (uri.find("://") != std::string::npos)
      fail(where, fmt::format("'{}' is not a file beside the model (only relative file names and data URIs are read)", uri));
    const std::string decoded = decode_uri(uri);
    if (decoded.empty() || decoded.find('\0') != std::string::npos) fail(where, fmt::format("'{}' is not a file name", uri));
    // tinygltf joins every URI to the model's folder: an absolute path would be read as a name within it.
    if (decoded.front() == '/') fail(where, fmt::format("'{}' is an absolute path; file names are read relative to the model's folder", clip(uri)));
    const std::string path = input_.folder_prefix + decoded;
    if (const std::string outside = outside_model_folder(input_.folder_prefix, path, input_.references); !outside.empty())
      fail(where, fmt::format("'{}' {}", clip(uri), outside));
    return path;
  }

  const JsonCheckInput& input() const { return input_; }
  const std::set<std::string>& seen_extensions() const { return seen_extensions_; }

 private:
  const JsonCheckInput& input_;
  std::set<std::string> seen_extensions_;
};

// The top-level arrays: each is an array of objects.
struct Arrays {
  const json* accessors = nullptr;
  const json* animations = nullptr;
  const json* buffers = nullptr;
  const json* buffer_views = nullptr;
  const json* cameras = nullptr;
  const json* images = nullptr;
  const json* materials = nullptr;
  const json* meshes = nullptr;
  const json* nodes = nullptr;
  const json* samplers = nullptr;
  const json* scenes = nullptr;
  const json* skins = nullptr;
  const json* textures = nullptr;
};

std::size_t size_of(const json* array) { return array ? array->size() : 0; }

void check_texture_info(Checker& c, const json& value, const std::string& path, const Arrays& arrays) {
  const json& info = c.object(value, path);
  c.index(info, "index", path, size_of(arrays.textures), "textures", true);
  c.uint(info, "texCoord", path, false, 0, 1u << 16);
  c.extensions(info, path);
}

void check_asset(Checker& c, const json& root) {
  const json& asset = c.object(*c.get(root, "asset", "", true), "/asset");
  const std::string version = *c.string(asset, "version", "/asset", true);
  if (version.substr(0, version.find('.')) != "2") c.fail("/asset/version", fmt::format("glTF {} is not read (only glTF 2.x is)", version));
  const std::optional<std::string> min_version = c.string(asset, "minVersion", "/asset", false);
  if (min_version && *min_version != "2.0") c.fail("/asset/minVersion", fmt::format("the file needs glTF {}; only 2.0 is read", *min_version));
  c.string(asset, "generator", "/asset", false);
  c.string(asset, "copyright", "/asset", false);
  c.extensions(asset, "/asset");
}

void check_required_extensions(Checker& c, const json& root) {
  for (const char* key : {"extensionsUsed", "extensionsRequired"}) {
    const json* list = c.array_of(root, key, "", false);
    if (!list) continue;
    for (std::size_t i = 0; i < list->size(); ++i)
      if (!(*list)[i].is_string()) c.fail(at(at("", key), i), fmt::format("expected an extension's name, found {}", kind_of((*list)[i])));
  }
  const json* required = Checker::find(root, "extensionsRequired");
  if (!required) return;
  for (std::size_t i = 0; i < required->size(); ++i) {
    const std::string name = (*required)[i].get<std::string>();
    bool read = false;
    for (const std::string_view r : kExtensionsRead) read = read || name == r;
    if (read) continue;
    std::string what;
    if (name == "KHR_draco_mesh_compression")
      what = " (Draco-compressed meshes are not decoded)";
    else if (name == "KHR_mesh_quantization")
      what = " (only float positions and normals are read)";
    else if (name == "KHR_texture_transform")
      what = " (texture transforms are not applied)";
    c.fail(at("/extensionsRequired", i), fmt::format("the file requires the extension {}, which is not read{}", name, what));
  }
}

std::vector<u64> check_buffers(Checker& c, const Arrays& arrays, JsonFacts& facts) {
  std::vector<u64> lengths;
  if (!arrays.buffers) return lengths;
  const JsonCheckInput& input = c.input();
  for (std::size_t i = 0; i < arrays.buffers->size(); ++i) {
    const std::string path = at("/buffers", i);
    const json& buffer = c.object((*arrays.buffers)[i], path);
    const u64 length = *c.uint(buffer, "byteLength", path, true, 1);
    lengths.push_back(length);
    c.string(buffer, "name", path, false);
    c.extensions(buffer, path);
    const std::optional<std::string> uri = c.string(buffer, "uri", path, false);
    if (!uri) {
      if (!input.binary || i != 0) c.fail(path, "'uri' is missing (only the first buffer of a .glb may leave it out, for the BIN chunk)");
      if (!input.bin_chunk_length) c.fail(path, "the buffer is the .glb's BIN chunk, but the file has none");
      if (length > *input.bin_chunk_length)
        c.fail(at(path, "byteLength"), fmt::format("{} bytes, more than the BIN chunk's {}", length, *input.bin_chunk_length));
      continue;
    }
    const std::string where = at(path, "uri");
    if (uri->compare(0, 5, "data:") == 0) {
      const u64 held = c.data_uri(*uri, where);
      if (held != length) c.fail(path, fmt::format("the data URI holds {} bytes, but byteLength is {}", held, length));
      continue;
    }
    const std::string file = c.file_uri(*uri, where);
    facts.external_buffers.push_back(file);
    struct stat status {};
    if (::stat(file.c_str(), &status) != 0) {
      if (errno == ENOENT || errno == ENOTDIR) c.fail(where, fmt::format("buffer file '{}' does not exist", file));
      c.fail(where, fmt::format("cannot read buffer file '{}': {}", file, std::strerror(errno)));
    }
    if (S_ISDIR(status.st_mode)) c.fail(where, fmt::format("buffer file '{}' is a folder", file));
    if (!S_ISREG(status.st_mode)) c.fail(where, fmt::format("buffer file '{}' is not a regular file", file));
    if (static_cast<u64>(status.st_size) != length)
      c.fail(path, fmt::format("buffer file '{}' holds {} bytes, but byteLength is {}", file, status.st_size, length));
  }
  return lengths;
}

struct ViewRange {
  u64 length = 0;
  std::optional<u64> stride;
};

std::vector<ViewRange> check_buffer_views(Checker& c, const Arrays& arrays, const std::vector<u64>& buffer_lengths) {
  std::vector<ViewRange> views;
  if (!arrays.buffer_views) return views;
  for (std::size_t i = 0; i < arrays.buffer_views->size(); ++i) {
    const std::string path = at("/bufferViews", i);
    const json& view = c.object((*arrays.buffer_views)[i], path);
    const std::int64_t buffer = c.index(view, "buffer", path, buffer_lengths.size(), "buffers", true);
    const u64 offset = c.uint(view, "byteOffset", path, false).value_or(0);
    const u64 length = *c.uint(view, "byteLength", path, true, 1);
    const std::optional<u64> stride = c.uint(view, "byteStride", path, false, 4, 252);
    if (stride && *stride % 4 != 0) c.fail(at(path, "byteStride"), fmt::format("{} is not a multiple of 4", *stride));
    c.uint(view, "target", path, false);
    c.string(view, "name", path, false);
    c.extensions(view, path);
    const u64 buffer_length = buffer_lengths[static_cast<std::size_t>(buffer)];
    if (offset > buffer_length || length > buffer_length - offset)
      c.fail(path, fmt::format("its {} bytes from byte {} reach beyond the end of buffer {} ({} bytes)", length, offset, buffer, buffer_length));
    views.push_back({length, stride});
  }
  return views;
}

void check_accessors(Checker& c, const Arrays& arrays, const std::vector<ViewRange>& views) {
  if (!arrays.accessors) return;
  static constexpr std::array<const char*, 7> kTypes = {"SCALAR", "VEC2", "VEC3", "VEC4", "MAT2", "MAT3", "MAT4"};
  for (std::size_t i = 0; i < arrays.accessors->size(); ++i) {
    const std::string path = at("/accessors", i);
    const json& accessor = c.object((*arrays.accessors)[i], path);
    const std::int64_t view = c.index(accessor, "bufferView", path, views.size(), "bufferViews");
    const u64 offset = c.uint(accessor, "byteOffset", path, false).value_or(0);
    const u64 component_type = *c.uint(accessor, "componentType", path, true);
    if (component_type != 5120 && component_type != 5121 && component_type != 5122 && component_type != 5123 && component_type != 5125 &&
        component_type != 5126)
      c.fail(at(path, "componentType"), fmt::format("{} is not a component type of glTF 2.0", component_type));
    c.boolean(accessor, "normalized", path);
    const u64 count = *c.uint(accessor, "count", path, true, 1);
    const std::string type = *c.choice(accessor, "type", path, true, kTypes);
    c.numbers(accessor, "max", path, component_count(type));
    c.numbers(accessor, "min", path, component_count(type));
    c.string(accessor, "name", path, false);
    c.extensions(accessor, path);
    if (const json* sparse = Checker::find(accessor, "sparse")) {
      const std::string where = at(path, "sparse");
      c.object(*sparse, where);
      c.uint(*sparse, "count", where, true, 1, static_cast<u64>(std::numeric_limits<int>::max()));
      const json& sparse_indices = c.object(*c.get(*sparse, "indices", where, true), at(where, "indices"));
      c.index(sparse_indices, "bufferView", at(where, "indices"), views.size(), "bufferViews", true);
      c.uint(sparse_indices, "byteOffset", at(where, "indices"), false, 0, static_cast<u64>(std::numeric_limits<int>::max()));
      c.uint(sparse_indices, "componentType", at(where, "indices"), true);
      c.enumerated(sparse_indices, "componentType", at(where, "indices"), {5121, 5123, 5125});
      const json& values = c.object(*c.get(*sparse, "values", where, true), at(where, "values"));
      c.index(values, "bufferView", at(where, "values"), views.size(), "bufferViews", true);
      c.uint(values, "byteOffset", at(where, "values"), false, 0, static_cast<u64>(std::numeric_limits<int>::max()));
    }
    if (view < 0) continue;  // zeros (or sparse values alone): the reader refuses to read it
    const ViewRange& range = views[static_cast<std::size_t>(view)];
    const u64 element = element_size(component_type, type);
    const u64 stride = range.stride.value_or(element);
    if (stride < element)
      c.fail(path, fmt::format("its elements of {} bytes overlap in buffer view {}, whose byteStride is {}", element, view, stride));
    const unsigned __int128 end = static_cast<unsigned __int128>(offset) + static_cast<unsigned __int128>(count - 1) * stride + element;
    if (end > range.length)
      c.fail(path, fmt::format("its {} elements of {} bytes (from byte {}, {} bytes apart) need more than the {} bytes of buffer view {}", count,
                               element, offset, stride, range.length, view));
  }
}

void check_images(Checker& c, const Arrays& arrays, std::size_t views, JsonFacts& facts) {
  if (!arrays.images) return;
  for (std::size_t i = 0; i < arrays.images->size(); ++i) {
    const std::string path = at("/images", i);
    const json& image = c.object((*arrays.images)[i], path);
    const std::optional<std::string> uri = c.string(image, "uri", path, false);
    const std::int64_t view = c.index(image, "bufferView", path, views, "bufferViews");
    c.string(image, "mimeType", path, false);
    c.string(image, "name", path, false);
    c.extensions(image, path);
    if (uri && view >= 0) c.fail(path, "it has both 'uri' and 'bufferView'");
    if (!uri && view < 0) c.fail(path, "it has neither 'uri' nor 'bufferView'");
    if (!uri) continue;
    if (uri->compare(0, 5, "data:") == 0)
      c.data_uri(*uri, at(path, "uri"));
    else
      facts.external_images.push_back(c.file_uri(*uri, at(path, "uri")));
  }
}

void check_samplers_and_textures(Checker& c, const Arrays& arrays) {
  for (std::size_t i = 0; i < size_of(arrays.samplers); ++i) {
    const std::string path = at("/samplers", i);
    const json& sampler = c.object((*arrays.samplers)[i], path);
    c.enumerated(sampler, "magFilter", path, {9728, 9729});
    c.enumerated(sampler, "minFilter", path, {9728, 9729, 9984, 9985, 9986, 9987});
    c.enumerated(sampler, "wrapS", path, {33071, 33648, 10497});
    c.enumerated(sampler, "wrapT", path, {33071, 33648, 10497});
    c.string(sampler, "name", path, false);
    c.extensions(sampler, path);
  }
  for (std::size_t i = 0; i < size_of(arrays.textures); ++i) {
    const std::string path = at("/textures", i);
    const json& texture = c.object((*arrays.textures)[i], path);
    c.index(texture, "sampler", path, size_of(arrays.samplers), "samplers");
    c.index(texture, "source", path, size_of(arrays.images), "images");
    c.string(texture, "name", path, false);
    c.extensions(texture, path);
  }
}

void check_materials(Checker& c, const Arrays& arrays) {
  static constexpr std::array<const char*, 3> kAlphaModes = {"OPAQUE", "MASK", "BLEND"};
  for (std::size_t i = 0; i < size_of(arrays.materials); ++i) {
    const std::string path = at("/materials", i);
    const json& material = c.object((*arrays.materials)[i], path);
    c.string(material, "name", path, false);
    c.extensions(material, path);
    if (const json* pbr = Checker::find(material, "pbrMetallicRoughness")) {
      const std::string where = at(path, "pbrMetallicRoughness");
      c.object(*pbr, where);
      c.numbers(*pbr, "baseColorFactor", where, 4, 0, 1);
      c.number(*pbr, "metallicFactor", where, false, 0, 1);
      c.number(*pbr, "roughnessFactor", where, false, 0, 1);
      for (const char* key : {"baseColorTexture", "metallicRoughnessTexture"})
        if (const json* info = Checker::find(*pbr, key)) check_texture_info(c, *info, at(where, key), arrays);
      c.extensions(*pbr, where);
    }
    if (const json* info = Checker::find(material, "normalTexture")) {
      check_texture_info(c, *info, at(path, "normalTexture"), arrays);
      c.number(*info, "scale", at(path, "normalTexture"), false);
    }
    if (const json* info = Checker::find(material, "occlusionTexture")) {
      check_texture_info(c, *info, at(path, "occlusionTexture"), arrays);
      c.number(*info, "strength", at(path, "occlusionTexture"), false, 0, 1);
    }
    if (const json* info = Checker::find(material, "emissiveTexture")) check_texture_info(c, *info, at(path, "emissiveTexture"), arrays);
    c.numbers(material, "emissiveFactor", path, 3, 0, 1);
    c.choice(material, "alphaMode", path, false, kAlphaModes);
    c.number(material, "alphaCutoff", path, false, 0);
    c.boolean(material, "doubleSided", path);
    if (const json* extensions = Checker::find(material, "extensions")) {
      if (const json* strength = Checker::find(*extensions, "KHR_materials_emissive_strength")) {
        const std::string where = at(at(path, "extensions"), "KHR_materials_emissive_strength");
        c.number(*strength, "emissiveStrength", where, false, 0);
      }
    }
  }
}

void check_meshes(Checker& c, const Arrays& arrays, JsonFacts& facts) {
  for (std::size_t i = 0; i < size_of(arrays.meshes); ++i) {
    const std::string path = at("/meshes", i);
    const json& mesh = c.object((*arrays.meshes)[i], path);
    const json& primitives = *c.array_of(mesh, "primitives", path, true, 1);
    for (std::size_t k = 0; k < primitives.size(); ++k) {
      const std::string where = at(at(path, "primitives"), k);
      const json& primitive = c.object(primitives[k], where);
      const json& attributes = c.object(*c.get(primitive, "attributes", where, true), at(where, "attributes"));
      for (auto it = attributes.begin(); it != attributes.end(); ++it) {
        const std::string attribute = at(at(where, "attributes"), it.key());
        if (!it.value().is_number_unsigned()) c.fail(attribute, fmt::format("expected an accessor's index, found {}", kind_of(it.value())));
        c.index_in(it.value().get<u64>(), attribute, size_of(arrays.accessors), "accessors");
      }
      c.index(primitive, "indices", where, size_of(arrays.accessors), "accessors");
      c.index(primitive, "material", where, size_of(arrays.materials), "materials");
      c.uint(primitive, "mode", where, false, 0, 6);
      if (const json* targets = c.array_of(primitive, "targets", where, false)) {
        for (std::size_t t = 0; t < targets->size(); ++t) {
          const std::string target_path = at(at(where, "targets"), t);
          const json& target = c.object((*targets)[t], target_path);
          for (auto it = target.begin(); it != target.end(); ++it) {
            if (!it.value().is_number_unsigned())
              c.fail(at(target_path, it.key()), fmt::format("expected an accessor's index, found {}", kind_of(it.value())));
            c.index_in(it.value().get<u64>(), at(target_path, it.key()), size_of(arrays.accessors), "accessors");
          }
        }
      }
      c.extensions(primitive, where);
    }
    c.numbers(mesh, "weights", path, 0);
    c.string(mesh, "name", path, false);
    c.extensions(mesh, path);
    facts.primitives.push_back(primitives.size());
  }
}

void check_cameras(Checker& c, const Arrays& arrays) {
  static constexpr std::array<const char*, 2> kTypes = {"perspective", "orthographic"};
  for (std::size_t i = 0; i < size_of(arrays.cameras); ++i) {
    const std::string path = at("/cameras", i);
    const json& camera = c.object((*arrays.cameras)[i], path);
    const std::string type = *c.choice(camera, "type", path, true, kTypes);
    const std::string where = at(path, type);
    const json& projection = c.object(*c.get(camera, type.c_str(), path, true), where);
    if (type == "perspective") {
      const double yfov = *c.number(projection, "yfov", where, true, 0, std::numbers::pi);
      if (yfov <= 0 || yfov >= std::numbers::pi) c.fail(at(where, "yfov"), fmt::format("{} is not an angle between 0 and pi", yfov));
      const double znear = *c.number(projection, "znear", where, true, 0);
      if (znear <= 0) c.fail(at(where, "znear"), "must be greater than 0");
      const std::optional<double> zfar = c.number(projection, "zfar", where, false, 0);
      if (zfar && *zfar <= znear) c.fail(at(where, "zfar"), "must be greater than znear");
      const std::optional<double> aspect = c.number(projection, "aspectRatio", where, false, 0);
      if (aspect && *aspect <= 0) c.fail(at(where, "aspectRatio"), "must be greater than 0");
    } else {
      c.number(projection, "xmag", where, true);
      c.number(projection, "ymag", where, true);
      c.number(projection, "znear", where, true, 0);
      c.number(projection, "zfar", where, true, 0);
    }
    c.extensions(projection, where);
    c.string(camera, "name", path, false);
    c.extensions(camera, path);
  }
}

void check_skins_and_animations(Checker& c, const Arrays& arrays) {
  for (std::size_t i = 0; i < size_of(arrays.skins); ++i) {
    const std::string path = at("/skins", i);
    const json& skin = c.object((*arrays.skins)[i], path);
    c.index(skin, "inverseBindMatrices", path, size_of(arrays.accessors), "accessors");
    c.index(skin, "skeleton", path, size_of(arrays.nodes), "nodes");
    c.indices(skin, "joints", path, size_of(arrays.nodes), "nodes", true, 1);
    c.string(skin, "name", path, false);
    c.extensions(skin, path);
  }
  for (std::size_t i = 0; i < size_of(arrays.animations); ++i) {
    const std::string path = at("/animations", i);
    const json& animation = c.object((*arrays.animations)[i], path);
    const json& samplers = *c.array_of(animation, "samplers", path, true, 1);
    for (std::size_t s = 0; s < samplers.size(); ++s) {
      const std::string where = at(at(path, "samplers"), s);
      const json& sampler = c.object(samplers[s], where);
      c.index(sampler, "input", where, size_of(arrays.accessors), "accessors", true);
      c.index(sampler, "output", where, size_of(arrays.accessors), "accessors", true);
      c.string(sampler, "interpolation", where, false);
      c.extensions(sampler, where);
    }
    const json& channels = *c.array_of(animation, "channels", path, true, 1);
    for (std::size_t k = 0; k < channels.size(); ++k) {
      const std::string where = at(at(path, "channels"), k);
      const json& channel = c.object(channels[k], where);
      const std::optional<u64> sampler = c.uint(channel, "sampler", where, true);
      if (*sampler >= samplers.size())
        c.fail(at(where, "sampler"), fmt::format("index {} is out of range ({}/samplers has {} entries)", *sampler, path, samplers.size()));
      const json& target = c.object(*c.get(channel, "target", where, true), at(where, "target"));
      c.index(target, "node", at(where, "target"), size_of(arrays.nodes), "nodes");
      c.string(target, "path", at(where, "target"), true);
      c.extensions(target, at(where, "target"));
      c.extensions(channel, where);
    }
    c.string(animation, "name", path, false);
    c.extensions(animation, path);
  }
}

// Nodes, then the hierarchy: each node has one parent at most, no node is its own ancestor, and the scenes list
// root nodes, each once.
void check_nodes_and_scenes(Checker& c, const Arrays& arrays) {
  const std::size_t count = size_of(arrays.nodes);
  std::vector<std::int64_t> parent(count, -1);
  std::vector<std::size_t> slot(count, 0);  // where in its parent's children a node is listed
  for (std::size_t i = 0; i < count; ++i) {
    const std::string path = at("/nodes", i);
    const json& node = c.object((*arrays.nodes)[i], path);
    c.index(node, "camera", path, size_of(arrays.cameras), "cameras");
    c.index(node, "mesh", path, size_of(arrays.meshes), "meshes");
    c.index(node, "skin", path, size_of(arrays.skins), "skins");
    const std::vector<double> matrix = c.numbers(node, "matrix", path, 16);
    if (!matrix.empty() && (matrix[3] != 0 || matrix[7] != 0 || matrix[11] != 0 || matrix[15] != 1))
      c.fail(at(path, "matrix"), "not an affine transform (its last row is not 0 0 0 1)");
    const std::vector<double> rotation = c.numbers(node, "rotation", path, 4, -1, 1);
    if (!rotation.empty() && rotation[0] * rotation[0] + rotation[1] * rotation[1] + rotation[2] * rotation[2] + rotation[3] * rotation[3] < 1e-12)
      c.fail(at(path, "rotation"), "not a unit quaternion (it is zero)");
    c.numbers(node, "scale", path, 3);
    c.numbers(node, "translation", path, 3);
    if (!matrix.empty() && (Checker::find(node, "rotation") || Checker::find(node, "scale") || Checker::find(node, "translation")))
      c.fail(path, "it has both 'matrix' and translation, rotation or scale");
    c.numbers(node, "weights", path, 0);
    c.string(node, "name", path, false);
    c.extensions(node, path);
    const std::vector<u64> children = c.indices(node, "children", path, count, "nodes");
    for (std::size_t k = 0; k < children.size(); ++k) {
      const u64 child = children[k];
      const std::string where = at(at(path, "children"), k);
      if (child == i) c.fail(where, fmt::format("node {} is its own child", i));
      if (parent[child] == static_cast<std::int64_t>(i)) c.fail(where, fmt::format("node {} is listed twice among the children", child));
      if (parent[child] >= 0)
        c.fail(where, fmt::format("node {} is already a child of node {} (a node has one parent at most)", child, parent[child]));
      parent[child] = static_cast<std::int64_t>(i);
      slot[child] = k;
    }
  }
  // With one parent each, a loop is a chain of parents that comes back to where it started.
  std::vector<char> state(count, 0);  // 0 unseen, 1 on the chain being walked, 2 done
  std::vector<std::size_t> chain;
  for (std::size_t start = 0; start < count; ++start) {
    chain.clear();
    std::int64_t n = static_cast<std::int64_t>(start);
    while (n >= 0 && state[static_cast<std::size_t>(n)] == 0) {
      state[static_cast<std::size_t>(n)] = 1;
      chain.push_back(static_cast<std::size_t>(n));
      n = parent[static_cast<std::size_t>(n)];
    }
    if (n >= 0 && state[static_cast<std::size_t>(n)] == 1) {
      // n is its own ancestor: name the loop from n down.
      const std::size_t looped = static_cast<std::size_t>(n);
      std::string loop = std::to_string(looped);
      int shown = 0;
      for (std::int64_t a = parent[looped]; a >= 0 && static_cast<std::size_t>(a) != looped; a = parent[static_cast<std::size_t>(a)]) {
        if (++shown > 8) {
          loop = "... -> " + loop;
          break;
        }
        loop = std::to_string(a) + " -> " + loop;
      }
      loop = std::to_string(looped) + " -> " + loop;
      c.fail(at(at(at("/nodes", static_cast<std::size_t>(parent[looped])), "children"), slot[looped]),
             fmt::format("node {} is its own ancestor: the hierarchy loops ({})", looped, loop));
    }
    for (const std::size_t x : chain) state[x] = 2;
  }
  for (std::size_t s = 0; s < size_of(arrays.scenes); ++s) {
    const std::string path = at("/scenes", s);
    const json& scene = c.object((*arrays.scenes)[s], path);
    const std::vector<u64> nodes = c.indices(scene, "nodes", path, count, "nodes");
    std::set<u64> listed;
    for (std::size_t k = 0; k < nodes.size(); ++k) {
      const std::string where = at(at(path, "nodes"), k);
      if (parent[nodes[k]] >= 0) c.fail(where, fmt::format("node {} is not a root node (it is a child of node {})", nodes[k], parent[nodes[k]]));
      if (!listed.insert(nodes[k]).second) c.fail(where, fmt::format("node {} is listed twice", nodes[k]));
    }
    c.string(scene, "name", path, false);
    c.extensions(scene, path);
  }
}

}  // namespace

JsonFacts check_gltf_json(const json& root, const JsonCheckInput& input) {
  Checker c(input);
  c.object(root, "");
  check_asset(c, root);
  check_required_extensions(c, root);
  Arrays arrays;
  const auto array = [&](const char* key) {
    const json* list = c.array_of(root, key, "", false);
    if (list)
      for (std::size_t i = 0; i < list->size(); ++i) c.object((*list)[i], at(at("", key), i));
    return list;
  };
  arrays.accessors = array("accessors");
  arrays.animations = array("animations");
  arrays.buffers = array("buffers");
  arrays.buffer_views = array("bufferViews");
  arrays.cameras = array("cameras");
  arrays.images = array("images");
  arrays.materials = array("materials");
  arrays.meshes = array("meshes");
  arrays.nodes = array("nodes");
  arrays.samplers = array("samplers");
  arrays.scenes = array("scenes");
  arrays.skins = array("skins");
  arrays.textures = array("textures");
  c.extensions(root, "");
  c.index(root, "scene", "", size_of(arrays.scenes), "scenes");

  JsonFacts facts;
  const std::vector<u64> buffer_lengths = check_buffers(c, arrays, facts);
  const std::vector<ViewRange> views = check_buffer_views(c, arrays, buffer_lengths);
  check_accessors(c, arrays, views);
  check_images(c, arrays, views.size(), facts);
  check_samplers_and_textures(c, arrays);
  check_materials(c, arrays);
  check_meshes(c, arrays, facts);
  check_cameras(c, arrays);
  check_skins_and_animations(c, arrays);
  check_nodes_and_scenes(c, arrays);

  std::set<std::string> used(c.seen_extensions());
  if (const json* list = Checker::find(root, "extensionsUsed"))
    for (const json& name : *list) used.insert(name.get<std::string>());
  for (const std::string& name : used) {
    bool read = false;
    for (const std::string_view r : kExtensionsRead) read = read || name == r;
    if (!read) facts.extensions_not_read.push_back(name);
  }
  facts.accessors = size_of(arrays.accessors);
  facts.buffers = size_of(arrays.buffers);
  facts.buffer_views = size_of(arrays.buffer_views);
  facts.cameras = size_of(arrays.cameras);
  facts.images = size_of(arrays.images);
  facts.materials = size_of(arrays.materials);
  facts.nodes = size_of(arrays.nodes);
  facts.scenes = size_of(arrays.scenes);
  facts.textures = size_of(arrays.textures);
  return facts;
}

}  // namespace pt::gltf
