// PLY model files -> MeshFile, read by our own parser: ASCII, binary_little_endian and binary_big_endian bodies,
// elements in any order, unknown elements and properties skipped. Every count the header declares is checked
// against the limits and against the bytes the file holds before anything is allocated for it, so a small file
// that claims billions of faces costs nothing; every index and number is checked as it is read.
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <type_traits>
#include <vector>

#include <fmt/format.h>

#include "base/errors.hpp"
#include "loading/model_file_input.hpp"
#include "loading/model_files.hpp"

namespace pt {

namespace {

using i64 = std::int64_t;

enum class Scalar : u8 { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

struct ScalarName {
  std::string_view name;
  Scalar type;
};

// The PLY names first (in the order of Scalar, so that name_of can index them), then the sized aliases.
constexpr ScalarName kScalarNames[] = {
    {"char", Scalar::kInt8},   {"uchar", Scalar::kUint8},   {"short", Scalar::kInt16},     {"ushort", Scalar::kUint16},
    {"int", Scalar::kInt32},   {"uint", Scalar::kUint32},   {"float", Scalar::kFloat32},   {"double", Scalar::kFloat64},
    {"int8", Scalar::kInt8},   {"uint8", Scalar::kUint8},   {"int16", Scalar::kInt16},     {"uint16", Scalar::kUint16},
    {"int32", Scalar::kInt32}, {"uint32", Scalar::kUint32}, {"float32", Scalar::kFloat32}, {"float64", Scalar::kFloat64}};

std::optional<Scalar> scalar_named(std::string_view name) {
  for (const ScalarName& entry : kScalarNames)
    if (entry.name == name) return entry.type;
  return std::nullopt;
}

std::string_view name_of(Scalar type) { return kScalarNames[static_cast<int>(type)].name; }

u32 size_of(Scalar type) {
  switch (type) {
    case Scalar::kInt8:
    case Scalar::kUint8: return 1;
    case Scalar::kInt16:
    case Scalar::kUint16: return 2;
    case Scalar::kInt32:
    case Scalar::kUint32:
    case Scalar::kFloat32: return 4;
    case Scalar::kFloat64: return 8;
  }
  return 1;
}

bool is_integer(Scalar type) { return type != Scalar::kFloat32 && type != Scalar::kFloat64; }

i64 smallest(Scalar type) {
  switch (type) {
    case Scalar::kInt8: return -128;
    case Scalar::kInt16: return -32768;
    case Scalar::kInt32: return -2147483648LL;
    default: return 0;
  }
}

i64 largest(Scalar type) {
  switch (type) {
    case Scalar::kInt8: return 127;
    case Scalar::kUint8: return 255;
    case Scalar::kInt16: return 32767;
    case Scalar::kUint16: return 65535;
    case Scalar::kInt32: return 2147483647LL;
    default: return 4294967295LL;
  }
}

// What a property is read for.
enum class Role : u8 { kSkip, kX, kY, kZ, kNx, kNy, kNz, kU, kV, kIndices };

struct Property {
  std::string name;
  bool list = false;
  Scalar count_type = Scalar::kUint8;  // a list's length
  Scalar type = Scalar::kFloat32;      // the value, or each item of a list
  Role role = Role::kSkip;
  u64 line = 0;
};

struct Element {
  std::string name;
  u64 count = 0;
  u64 line = 0;
  std::vector<Property> properties;
};

enum class Format { kAscii, kBinaryLittleEndian, kBinaryBigEndian };

bool is_ply_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

std::vector<std::string_view> split_words(std::string_view line) {
  std::vector<std::string_view> words;
  std::size_t at = 0;
  while (at < line.size()) {
    while (at < line.size() && is_ply_blank(line[at])) ++at;
    const std::size_t start = at;
    while (at < line.size() && !is_ply_blank(line[at])) ++at;
    if (at > start) words.push_back(line.substr(start, at - start));
  }
  return words;
}

bool parse_integer(std::string_view text, i64& value) {
  if (text.size() > 1 && text[0] == '+' && text[1] != '-') text.remove_prefix(1);
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  return error == std::errc() && end == text.data() + text.size();
}

bool parse_real(std::string_view text, double& value) {
  if (text.size() > 1 && text[0] == '+' && text[1] != '-') text.remove_prefix(1);
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (end != text.data() + text.size()) return false;
  if (error == std::errc::result_out_of_range) {
    // Beyond a double's range: strtod says which way (1e999 is infinite, to be refused where it is used; 1e-999 is 0).
    value = std::strtod(std::string(text).c_str(), nullptr);
    return true;
  }
  return error == std::errc();
}

// A value read as the declared type: a float property is rounded to float in ASCII too, so that the same mesh
// written as text and in binary reads the same.
double as_declared(double value, Scalar type) {
  if (type != Scalar::kFloat32 || !std::isfinite(value)) return value;
  if (std::fabs(value) > static_cast<double>(std::numeric_limits<float>::max()))
    return value > 0 ? std::numeric_limits<double>::infinity() : -std::numeric_limits<double>::infinity();
  return static_cast<double>(static_cast<float>(value));
}

class PlyReader {
 public:
  PlyReader(const std::filesystem::path& path, std::string content) : path_(path), file_(path.string()), content_(std::move(content)) {}

  MeshFile read() {
    parse_header();
    assign_roles();
    check_counts();
    if (format_ == Format::kAscii) {
      AsciiSource source(*this);
      read_body(source);
      source.finish();
    } else {
      BinarySource source(*this, format_ == Format::kBinaryBigEndian);
      read_body(source);
      source.finish();
    }
    return finish();
  }

  [[noreturn]] void fail(std::string_view message) const { throw InputError(fmt::format("{}: {}", file_, message)); }
  [[noreturn]] void fail_at_line(u64 line, std::string_view message) const { throw InputError(fmt::format("{}: line {}: {}", file_, line, message)); }

 private:
  // ---- Header ----

  void parse_header() {
    if (content_.empty()) fail("not a PLY file (it is empty)");
    std::size_t at = 0;
    u64 line = 0;
    bool saw_format = false, ended = false;
    u64 ignored_lines = 0, first_ignored = 0;
    std::string first_ignored_text;
    while (at < content_.size()) {
      const std::size_t newline = content_.find('\n', at);
      const std::size_t stop = newline == std::string::npos ? content_.size() : newline;
      std::string_view text(content_.data() + at, stop - at);
      at = newline == std::string::npos ? content_.size() : newline + 1;
      ++line;
      if (!text.empty() && text.back() == '\r') text.remove_suffix(1);
      if (line == 1) {
        const std::vector<std::string_view> words = split_words(text);
        if (words.size() != 1 || words[0] != "ply") fail("not a PLY file (its first line is not 'ply')");
        continue;
      }
      const std::vector<std::string_view> words = split_words(text);
      if (words.empty()) continue;
      const std::string_view keyword = words[0];
      if (keyword == "comment" || keyword == "obj_info") continue;
      if (keyword == "end_header") {
        ended = true;
        break;
      }
      if (keyword == "format") {
        if (saw_format) fail_at_line(line, "a second format line");
        if (words.size() != 3) fail_at_line(line, "expected 'format ascii|binary_little_endian|binary_big_endian 1.0'");
        if (words[1] == "ascii")
          format_ = Format::kAscii;
        else if (words[1] == "binary_little_endian")
          format_ = Format::kBinaryLittleEndian;
        else if (words[1] == "binary_big_endian")
          format_ = Format::kBinaryBigEndian;
        else
          fail_at_line(line, fmt::format("unknown format '{}' (expected ascii, binary_little_endian or binary_big_endian)", clip(words[1])));
        if (words[2] != "1.0" && words[2] != "1") fail_at_line(line, fmt::format("PLY version '{}' is not supported (only 1.0)", clip(words[2])));
        saw_format = true;
      } else if (keyword == "element") {
        if (words.size() != 3) fail_at_line(line, "expected 'element NAME COUNT'");
        i64 count = 0;
        if (!parse_integer(words[2], count) || count < 0)
          fail_at_line(line, fmt::format("the count of element '{}' is '{}', not a whole number", clip(words[1]), clip(words[2])));
        for (const Element& element : elements_)
          if (element.name == words[1] && (element.name == "vertex" || element.name == "face"))
            fail_at_line(line, fmt::format("a second '{}' element (the first is on line {})", element.name, element.line));
        elements_.push_back(Element{std::string(words[1]), static_cast<u64>(count), line, {}});
      } else if (keyword == "property") {
        if (elements_.empty()) fail_at_line(line, "a property before any element");
        Property property;
        property.line = line;
        if (words.size() >= 2 && words[1] == "list") {
          if (words.size() != 5) fail_at_line(line, "expected 'property list LENGTH_TYPE ITEM_TYPE NAME'");
          property.list = true;
          property.count_type = scalar_type(words[2], line);
          property.type = scalar_type(words[3], line);
          property.name = std::string(words[4]);
          if (!is_integer(property.count_type))
            fail_at_line(line, fmt::format("the length of list '{}' is of a floating-point type ({})", clip(property.name), words[2]));
        } else {
          if (words.size() != 3) fail_at_line(line, "expected 'property TYPE NAME' or 'property list LENGTH_TYPE ITEM_TYPE NAME'");
          property.type = scalar_type(words[1], line);
          property.name = std::string(words[2]);
        }
        Element& element = elements_.back();
        for (const Property& other : element.properties)
          if (other.name == property.name)
            fail_at_line(line, fmt::format("a second property '{}' in element '{}' (the first is on line {})", clip(property.name),
                                           clip(element.name), other.line));
        element.properties.push_back(std::move(property));
      } else {
        // Not a PLY keyword: some writers put a comment without the word (Blender 2.4 "Created by ..."). Skipped.
        if (ignored_lines++ == 0) {
          first_ignored = line;
          first_ignored_text = clip(text);
        }
      }
    }
    if (!ended) fail_at_line(line, "the header does not end (no end_header line)");
    if (!saw_format) fail_at_line(line, "the header has no format line");
    if (ignored_lines > 0)
      warnings_.push_back(fmt::format("header line {} ('{}') is not a PLY keyword and was skipped{}", first_ignored, first_ignored_text,
                                      ignored_lines > 1 ? fmt::format(", with {} more such lines", ignored_lines - 1) : std::string()));
    body_ = at;
    body_line_ = line + 1;
  }

  Scalar scalar_type(std::string_view name, u64 line) const {
    if (const std::optional<Scalar> type = scalar_named(name)) return *type;
    fail_at_line(line, fmt::format("unknown property type '{}' (expected char, uchar, short, ushort, int, uint, float, double, "
                                   "or int8, uint8, int16, uint16, int32, uint32, float32, float64)",
                                   clip(name)));
  }

  Property* find(Element& element, std::string_view name) {
    for (Property& property : element.properties)
      if (property.name == name) return &property;
    return nullptr;
  }

  // Marks the properties that are read, and checks that the ones a mesh needs are there and usable.
  void assign_roles() {
    for (std::size_t i = 0; i < elements_.size(); ++i) {
      if (elements_[i].name == "vertex") vertex_ = static_cast<int>(i);
      if (elements_[i].name == "face") face_ = static_cast<int>(i);
    }
    if (vertex_ < 0) fail("has no vertex element");
    Element& vertex = elements_[vertex_];
    const auto take_scalar = [&](Property* property, Role role) {
      if (property->list) fail_at_line(property->line, fmt::format("vertex property '{}' is a list, not a number", property->name));
      property->role = role;
    };
    for (const auto& [name, role] : {std::pair{"x", Role::kX}, std::pair{"y", Role::kY}, std::pair{"z", Role::kZ}}) {
      Property* property = find(vertex, name);
      if (!property) fail_at_line(vertex.line, fmt::format("the vertex element has no property '{}'", name));
      take_scalar(property, role);
    }
    Property* normal[3] = {find(vertex, "nx"), find(vertex, "ny"), find(vertex, "nz")};
    const int normal_count = (normal[0] != nullptr) + (normal[1] != nullptr) + (normal[2] != nullptr);
    if (normal_count == 3) {
      take_scalar(normal[0], Role::kNx);
      take_scalar(normal[1], Role::kNy);
      take_scalar(normal[2], Role::kNz);
      has_normals_ = true;
    } else if (normal_count > 0) {
      fail_at_line(vertex.line, fmt::format("the vertex element has {} of the normal's properties nx, ny, nz: give all three or none",
                                            normal_count == 1 ? "only one" : "only two"));
    }
    constexpr std::pair<std::string_view, std::string_view> kUvNames[] = {
        {"u", "v"}, {"s", "t"}, {"texture_u", "texture_v"}, {"texture_s", "texture_t"}};
    for (const auto& [u_name, v_name] : kUvNames) {
      Property* u = find(vertex, u_name);
      Property* v = find(vertex, v_name);
      if (u && v) {
        take_scalar(u, Role::kU);
        take_scalar(v, Role::kV);
        has_uvs_ = true;
        break;
      }
    }
    if (!has_uvs_)
      for (const auto& [u_name, v_name] : kUvNames)
        if ((find(vertex, u_name) != nullptr) != (find(vertex, v_name) != nullptr)) {
          warnings_.push_back(fmt::format("the vertex element has '{}' without '{}': no texture coordinates are read",
                                          find(vertex, u_name) ? u_name : v_name, find(vertex, u_name) ? v_name : u_name));
          break;
        }

    if (face_ < 0)
      fail(fmt::format("has no faces (the header declares no face element, only {} vertices): point clouds are not rendered", vertex.count));
    Element& face = elements_[face_];
    Property* indices = find(face, "vertex_indices");
    if (!indices) indices = find(face, "vertex_index");
    if (!indices) fail_at_line(face.line, "the face element has no list 'vertex_indices' (or 'vertex_index')");
    if (!indices->list) fail_at_line(indices->line, fmt::format("face property '{}' is not a list", indices->name));
    if (!is_integer(indices->type))
      fail_at_line(indices->line, fmt::format("the vertex indices are of a floating-point type ({})", name_of(indices->type)));
    indices->role = Role::kIndices;

    for (const Element* element : {&vertex, &face}) {
      std::string skipped;
      for (const Property& property : element->properties)
        if (property.role == Role::kSkip) skipped += (skipped.empty() ? "" : ", ") + clip(property.name);
      if (!skipped.empty()) warnings_.push_back(fmt::format("{} properties not read: {}", element->name, skipped));
    }
    std::string skipped;
    for (const Element& element : elements_)
      if (&element != &vertex && &element != &face)
        skipped += fmt::format("{}{} ({})", skipped.empty() ? "" : ", ", clip(element.name), element.count);
    if (!skipped.empty()) warnings_.push_back(fmt::format("elements not read: {}", skipped));
  }

  // Before anything is allocated: the limits, and whether the file can hold what its header declares (each value
  // takes at least its size in binary and two characters, a digit and a separator, in ASCII).
  void check_counts() const {
    const Element& vertex = elements_[vertex_];
    const Element& face = elements_[face_];
    if (vertex.count > kMaxMeshVertices)
      fail_at_line(vertex.line,
                   fmt::format("the header declares {} vertices, more than the {} a model file may have", vertex.count, kMaxMeshVertices));
    if (face.count > kMaxMeshTriangles)
      fail_at_line(face.line,
                   fmt::format("the header declares {} faces, more than the {} triangles a model file may have", face.count, kMaxMeshTriangles));
    const u64 body_bytes = content_.size() - body_;
    u64 budget = format_ == Format::kAscii ? body_bytes + 1 : body_bytes;  // the last value needs no separator
    for (const Element& element : elements_) {
      u64 least = 0;
      for (const Property& property : element.properties)
        least += format_ == Format::kAscii ? 2 : size_of(property.list ? property.count_type : property.type);
      if (least == 0) continue;
      if (element.count > budget / least)
        fail_at_line(element.line,
                     fmt::format("the header declares {} '{}' elements, which take at least {} bytes each {}, but the file has only {} "
                                 "bytes after the header for them and the elements before (it is cut short, or the count is wrong)",
                                 element.count, clip(element.name), least, format_ == Format::kAscii ? "as text" : "in binary", body_bytes));
      budget -= element.count * least;
    }
  }

  // ---- Body ----

  // Reads values from an ASCII body: one element a line, values separated by blanks; "line N: face 3" as the place.
  class AsciiSource {
   public:
    explicit AsciiSource(const PlyReader& reader)
        : reader_(reader),
          at_(reader.content_.data() + reader.body_),
          end_(reader.content_.data() + reader.content_.size()),
          line_(reader.body_line_) {}

    void begin(const Element& element, u64 index) {
      element_ = &element;
      index_ = index;
      skip_space();
      if (at_ == end_)
        reader_.fail_at_line(line_, fmt::format("the file ends before {} {} (the header declares {})", clip(element.name), index, element.count));
    }
    void end() {
      while (at_ < end_ && is_ply_blank(*at_)) ++at_;
      if (at_ < end_ && *at_ != '\n') fail(fmt::format("more values than the header declares for a {}", clip(element_->name)));
    }
    double real(const Property& property, Scalar type) {
      const std::string_view text = token(property);
      if (is_integer(type)) return static_cast<double>(integer_from(text, property, type));
      double value = 0;
      if (!parse_real(text, value)) fail(fmt::format("'{}' is not a number (property '{}')", clip(text), clip(property.name)));
      return as_declared(value, type);
    }
    i64 integer(const Property& property, Scalar type) { return integer_from(token(property), property, type); }
    void skip(const Property& property) { token(property); }
    u64 list_length(const Property& property) {
      const i64 length = integer(property, property.count_type);
      if (length < 0) fail(fmt::format("list '{}' has a negative length ({})", clip(property.name), length));
      return static_cast<u64>(length);
    }
    void skip_list(const Property& property) {
      const u64 length = list_length(property);
      for (u64 i = 0; i < length; ++i) skip(property);
    }
    std::string place() const { return fmt::format("line {}: {} {}", line_, clip(element_->name), index_); }
    [[noreturn]] void fail(std::string_view message) const { reader_.fail(fmt::format("{}: {}", place(), message)); }
    // After the last element: anything but blanks is reported and ignored.
    void finish() {
      skip_space();
      if (at_ < end_) reader_.warnings_.push_back(fmt::format("line {}: text after the last element the header declares is ignored", line_));
    }

   private:
    void skip_space() {
      while (at_ < end_ && (is_ply_blank(*at_) || *at_ == '\n')) {
        if (*at_ == '\n') ++line_;
        ++at_;
      }
    }
    std::string_view token(const Property& property) {
      while (at_ < end_ && is_ply_blank(*at_)) ++at_;
      const char* start = at_;
      while (at_ < end_ && !is_ply_blank(*at_) && *at_ != '\n') ++at_;
      if (at_ == start) fail(fmt::format("fewer values than the header declares (none for '{}')", clip(property.name)));
      return {start, static_cast<std::size_t>(at_ - start)};
    }
    i64 integer_from(std::string_view text, const Property& property, Scalar type) const {
      i64 value = 0;
      if (!parse_integer(text, value))
        fail(fmt::format("'{}' is not a whole number (property '{}' is {})", clip(text), clip(property.name), name_of(type)));
      if (value < smallest(type) || value > largest(type))
        fail(fmt::format("{} is out of range for property '{}' ({})", value, clip(property.name), name_of(type)));
      return value;
    }

    const PlyReader& reader_;
    const char* at_;
    const char* end_;
    u64 line_;
    const Element* element_ = nullptr;
    u64 index_ = 0;
  };

  // Reads values from a binary body in either byte order; "face 3" as the place.
  class BinarySource {
   public:
    BinarySource(const PlyReader& reader, bool big_endian)
        : reader_(reader),
          at_(reinterpret_cast<const unsigned char*>(reader.content_.data()) + reader.body_),
          end_(reinterpret_cast<const unsigned char*>(reader.content_.data()) + reader.content_.size()),
          swap_(big_endian != (std::endian::native == std::endian::big)) {}

    void begin(const Element& element, u64 index) {
      element_ = &element;
      index_ = index;
    }
    void end() {}
    double real(const Property&, Scalar type) {
      need(size_of(type));
      switch (type) {
        case Scalar::kFloat32: {
          const u32 bits = load<u32>();
          float value;
          std::memcpy(&value, &bits, sizeof value);
          return value;
        }
        case Scalar::kFloat64: {
          const u64 bits = load<u64>();
          double value;
          std::memcpy(&value, &bits, sizeof value);
          return value;
        }
        default: return static_cast<double>(integer_unchecked(type));
      }
    }
    i64 integer(const Property&, Scalar type) {
      need(size_of(type));
      return integer_unchecked(type);
    }
    void skip(const Property& property) {
      need(size_of(property.type));
      at_ += size_of(property.type);
    }
    u64 list_length(const Property& property) {
      const i64 length = integer(property, property.count_type);
      if (length < 0) fail(fmt::format("list '{}' has a negative length ({})", clip(property.name), length));
      // The whole list must be there before it is read (or room is made for it).
      if (static_cast<u64>(length) > static_cast<u64>(end_ - at_) / size_of(property.type))
        fail(fmt::format("the file ends inside list '{}' of {} items (it is cut short)", clip(property.name), length));
      return static_cast<u64>(length);
    }
    void skip_list(const Property& property) { at_ += list_length(property) * size_of(property.type); }
    // Skips a whole element of scalars at once (its size was checked against the file with the header).
    bool skip_all(const Element& element) {
      u64 size = 0;
      for (const Property& property : element.properties) {
        if (property.list) return false;
        size += size_of(property.type);
      }
      if (element.count > static_cast<u64>(end_ - at_) / size) {
        begin(element, static_cast<u64>(end_ - at_) / size);
        fail("the file ends inside the element (it is cut short)");
      }
      at_ += element.count * size;
      return true;
    }
    std::string place() const { return fmt::format("{} {}", clip(element_->name), index_); }
    [[noreturn]] void fail(std::string_view message) const { reader_.fail(fmt::format("{}: {}", place(), message)); }
    void finish() {
      if (at_ < end_) reader_.warnings_.push_back(fmt::format("{} bytes after the last element the header declares are ignored", end_ - at_));
    }

   private:
    void need(u32 bytes) {
      if (static_cast<std::size_t>(end_ - at_) < bytes) fail("the file ends inside the element (it is cut short)");
    }
    template <class T>
    T load() {
      T value;
      std::memcpy(&value, at_, sizeof value);
      at_ += sizeof value;
      if (swap_) {
        if constexpr (sizeof(T) == 2) value = __builtin_bswap16(value);
        if constexpr (sizeof(T) == 4) value = __builtin_bswap32(value);
        if constexpr (sizeof(T) == 8) value = __builtin_bswap64(value);
      }
      return value;
    }
    i64 integer_unchecked(Scalar type) {
      switch (type) {
        case Scalar::kInt8: return static_cast<std::int8_t>(*at_++);
        case Scalar::kUint8: return *at_++;
        case Scalar::kInt16: return static_cast<std::int16_t>(load<std::uint16_t>());
        case Scalar::kUint16: return load<std::uint16_t>();
        case Scalar::kInt32: return static_cast<std::int32_t>(load<u32>());
        case Scalar::kUint32: return load<u32>();
        default: return 0;  // floating-point types are read by real()
      }
    }

    const PlyReader& reader_;
    const unsigned char* at_;
    const unsigned char* end_;
    bool swap_;
    const Element* element_ = nullptr;
    u64 index_ = 0;
  };

  template <class Source>
  void read_body(Source& source) {
    for (const Element& element : elements_) {
      if (element.properties.empty()) continue;
      if (&element == &elements_[vertex_])
        read_vertices(source, element);
      else if (&element == &elements_[face_])
        read_faces(source, element);
      else
        skip_element(source, element);
    }
  }

  template <class Source>
  void skip_element(Source& source, const Element& element) {
    if constexpr (std::is_same_v<Source, BinarySource>)
      if (source.skip_all(element)) return;
    for (u64 i = 0; i < element.count; ++i) {
      source.begin(element, i);
      for (const Property& property : element.properties) {
        if (property.list)
          source.skip_list(property);
        else
          source.skip(property);
      }
      source.end();
    }
  }

  template <class Source>
  void read_vertices(Source& source, const Element& element) {
    mesh_.positions.resize(element.count);
    if (has_normals_) mesh_.normals.resize(element.count);
    if (has_uvs_) mesh_.uvs.resize(element.count);
    double values[static_cast<int>(Role::kIndices)] = {};
    for (u64 i = 0; i < element.count; ++i) {
      source.begin(element, i);
      for (const Property& property : element.properties) {
        if (property.list)
          source.skip_list(property);
        else if (property.role == Role::kSkip)
          source.skip(property);
        else
          values[static_cast<int>(property.role)] = source.real(property, property.type);
      }
      const Vec3d position{values[static_cast<int>(Role::kX)], values[static_cast<int>(Role::kY)], values[static_cast<int>(Role::kZ)]};
      if (!std::isfinite(position.x) || !std::isfinite(position.y) || !std::isfinite(position.z)) source.fail("position is not finite");
      mesh_.positions[i] = position;
      if (has_normals_) {
        const Vec3d normal{values[static_cast<int>(Role::kNx)], values[static_cast<int>(Role::kNy)], values[static_cast<int>(Role::kNz)]};
        if (!std::isfinite(normal.x) || !std::isfinite(normal.y) || !std::isfinite(normal.z)) source.fail("normal is not finite");
        const double norm = length(normal);
        if (norm > 0 && std::isfinite(norm))
          mesh_.normals[i] = normal / norm;
        else
          ++zero_normals_;
      }
      if (has_uvs_) {
        const double u = values[static_cast<int>(Role::kU)], v = values[static_cast<int>(Role::kV)];
        if (!std::isfinite(u) || !std::isfinite(v)) source.fail("texture coordinate is not finite");
        mesh_.uvs[i] = {u, v};
      }
      source.end();
    }
  }

  template <class Source>
  void read_faces(Source& source, const Element& element) {
    const u64 vertex_count = elements_[vertex_].count;
    mesh_.triangles.reserve(element.count);
    std::vector<u32> corners;
    for (u64 i = 0; i < element.count; ++i) {
      source.begin(element, i);
      corners.clear();
      for (const Property& property : element.properties) {
        if (property.role != Role::kIndices) {
          if (property.list)
            source.skip_list(property);
          else
            source.skip(property);
          continue;
        }
        const u64 length = source.list_length(property);
        for (u64 k = 0; k < length; ++k) {
          const i64 index = source.integer(property, property.type);
          if (index < 0 || static_cast<u64>(index) >= vertex_count)
            source.fail(fmt::format("vertex index {} out of range (the file has {} vertices)", index, vertex_count));
          corners.push_back(static_cast<u32>(index));
        }
      }
      source.end();
      if (corners.size() < 3) {
        ++short_faces_;
        continue;
      }
      if (mesh_.triangles.size() + (corners.size() - 2) > kMaxMeshTriangles)
        source.fail(fmt::format("more than {} triangles, the most a model file may have", kMaxMeshTriangles));
      // A fan around the first corner: exact for the convex polygons PLY writers produce.
      for (std::size_t k = 1; k + 1 < corners.size(); ++k) mesh_.triangles.push_back({corners[0], corners[k], corners[k + 1]});
    }
  }

  MeshFile finish() {
    if (short_faces_ > 0) warnings_.push_back(fmt::format("{} faces of fewer than 3 vertices skipped", short_faces_));
    if (mesh_.triangles.empty()) fail(fmt::format("has no faces of 3 or more vertices (the header declares {} faces)", elements_[face_].count));
    if (zero_normals_ > 0) {
      warnings_.push_back(fmt::format("{} vertex normals of zero length: the file's normals are not used", zero_normals_));
      mesh_.normals.clear();
    }
    MeshFile out;
    out.path = path_;
    mesh_.name = "mesh 0";
    out.meshes.push_back(std::move(mesh_));
    MeshMaterial material;
    material.name = "default";
    out.materials.push_back(material);
    out.placements.push_back(MeshPlacement{0, AffineTransform{}});
    out.warnings = std::move(warnings_);
    return out;
  }

  std::filesystem::path path_;
  std::string file_;
  std::string content_;
  Format format_ = Format::kAscii;
  std::vector<Element> elements_;
  std::size_t body_ = 0;  // the offset of the body, after end_header's line
  u64 body_line_ = 0;     // the line the body starts on (ASCII)
  int vertex_ = -1, face_ = -1;
  bool has_normals_ = false, has_uvs_ = false;
  TriangleMesh mesh_;
  u64 short_faces_ = 0, zero_normals_ = 0;
  mutable std::vector<std::string> warnings_;
};

}  // namespace

MeshFile read_ply_file(const std::filesystem::path& path) { return PlyReader(path, read_model_input(path, path.string(), "PLY file")).read(); }

}  // namespace pt
