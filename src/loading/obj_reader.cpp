// OBJ model files and their MTL material libraries -> MeshFile, parsed by tinyobjloader. The files are read here,
// through the checked input (a FIFO or device is never opened), and handed to tinyobjloader as streams; what it
// does not check is checked on its output: indices in range, finite numbers, materials and textures that exist.
// Where a check fails, the line is found by a second look at the text, made only then.
#include <tiny_obj_loader.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <istream>
#include <map>
#include <optional>
#include <set>
#include <streambuf>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include <fmt/format.h>

#include "base/errors.hpp"
#include "loading/model_file_input.hpp"
#include "loading/model_files.hpp"
#include "loading/polygon_cutting.hpp"

namespace pt {

namespace {

static_assert(std::is_same_v<tinyobj::real_t, double>, "link tinyobjloader_double: coordinates are read as doubles");

// tinyobjloader reads a `usemtl` name up to the first blank, where MTL names may hold blanks ("newmtl Hard Shiny
// Plastic"): blanks inside the names on both sides are replaced by this byte before it sees them.
constexpr char kBlankInName = '\x1f';

bool is_blank(char c) { return c == ' ' || c == '\t'; }

std::string_view trim(std::string_view text) {
  while (!text.empty() && (is_blank(text.front()) || text.front() == '\r')) text.remove_prefix(1);
  while (!text.empty() && (is_blank(text.back()) || text.back() == '\r')) text.remove_suffix(1);
  return text;
}

std::string encode_name(std::string_view name) {
  std::string encoded(trim(name));
  std::replace_if(encoded.begin(), encoded.end(), is_blank, kBlankInName);
  return encoded;
}

std::string decode_name(std::string name) {
  std::replace(name.begin(), name.end(), kBlankInName, ' ');
  return name;
}

// The lines of a text as tinyobjloader splits them (at "\n", "\r\n" or a lone "\r"), numbered from 1.
class Lines {
 public:
  explicit Lines(std::string_view text) : text_(text) {}
  bool next(std::string_view& line) {
    if (at_ >= text_.size()) return false;
    std::size_t stop = at_;
    while (stop < text_.size() && text_[stop] != '\n' && text_[stop] != '\r') ++stop;
    line = text_.substr(at_, stop - at_);
    at_ = stop;
    if (at_ < text_.size()) at_ += (text_[at_] == '\r' && at_ + 1 < text_.size() && text_[at_ + 1] == '\n') ? 2 : 1;
    ++number_;
    return true;
  }
  u64 number() const { return number_; }

 private:
  std::string_view text_;
  std::size_t at_ = 0;
  u64 number_ = 0;
};

// A statement's keyword (after leading blanks, up to the next blank) and what follows it.
std::string_view keyword_of(std::string_view line, std::string_view* rest = nullptr) {
  std::size_t at = 0;
  while (at < line.size() && is_blank(line[at])) ++at;
  const std::size_t start = at;
  while (at < line.size() && !is_blank(line[at])) ++at;
  if (rest) *rest = line.substr(at);
  return line.substr(start, at - start);
}

// Whether a line is a statement of this keyword as tinyobjloader sees one: the keyword and a blank after it.
bool is_statement(std::string_view line, std::string_view keyword, std::string_view* rest = nullptr) {
  std::string_view after;
  const bool match = keyword_of(line, &after) == keyword && !after.empty();
  if (rest) *rest = after;
  return match;
}

std::vector<std::string_view> words_of(std::string_view text) {
  std::vector<std::string_view> words;
  std::size_t at = 0;
  while (at < text.size()) {
    while (at < text.size() && is_blank(text[at])) ++at;
    const std::size_t start = at;
    while (at < text.size() && !is_blank(text[at])) ++at;
    if (at > start) words.push_back(text.substr(start, at - start));
  }
  return words;
}

// Prepares the text in place, keeping its length and lines: blanks inside `usemtl` names are marked (see
// kBlankInName), and two tinyobjloader extensions the renderer has no use for become comments: skin weights (`vw`,
// whose reader converts unchecked numbers to int) and subdivision tags (`t`, each of which may make room for 3 x 8192
// values, copied into every mesh after it: a few KB of them would take gigabytes).
void prepare_text(std::string& text) {
  std::size_t at = 0;
  while (at < text.size()) {
    std::size_t stop = at;
    while (stop < text.size() && text[stop] != '\n' && text[stop] != '\r') ++stop;
    std::size_t k = at;
    while (k < stop && is_blank(text[k])) ++k;
    const std::string_view line(text.data() + k, stop - k);
    if ((line.size() > 2 && line.starts_with("vw") && is_blank(line[2])) || (line.size() > 1 && line[0] == 't' && is_blank(line[1]))) {
      text[k] = '#';
    } else if (line.size() > 6 && line.starts_with("usemtl") && is_blank(line[6])) {
      std::size_t first = k + 6, last = stop;
      while (first < last && is_blank(text[first])) ++first;
      while (last > first && is_blank(text[last - 1])) --last;
      std::replace_if(text.begin() + static_cast<std::ptrdiff_t>(first), text.begin() + static_cast<std::ptrdiff_t>(last), is_blank, kBlankInName);
    }
    at = stop + 1;
  }
}

// The line of the `ordinal`-th statement (from 0) with this keyword, or 0.
u64 line_of_statement(std::string_view text, std::string_view keyword, u64 ordinal) {
  Lines lines(text);
  std::string_view line;
  u64 seen = 0;
  while (lines.next(line))
    if (is_statement(line, keyword) && seen++ == ordinal) return lines.number();
  return 0;
}

// An std::streambuf over text in memory, for tinyobjloader's stream readers.
class MemoryBuffer : public std::streambuf {
 public:
  // The buffer is only read from: std::streambuf wants non-const pointers.
  explicit MemoryBuffer(const std::string& text) {
    char* begin = const_cast<char*>(text.data());
    setg(begin, begin, begin + text.size());
  }
};

// What tinyobjloader does not say about a material: which of its statements the library gives (its defaults differ
// from ours), and where it is defined.
struct MaterialSource {
  std::filesystem::path library;  // the MTL file; textures are found relative to its folder
  u64 line = 0;                   // of its newmtl statement
  bool has_kd = false, has_ke = false, has_pr = false, has_pm = false;
  // The lines of its texture statements that messages name (0: not given).
  u64 norm_line = 0, bump_line = 0, map_pm_line = 0, map_pr_line = 0;
};

// Reads the MTL libraries an OBJ file names, relative to its folder, through the checked input. A library that
// cannot be read is an error, not a warning: a model that silently loses its materials renders wrong.
class MaterialLibraries : public tinyobj::MaterialReader {
 public:
  MaterialLibraries(const std::filesystem::path& obj_path, const std::string& obj_text, ModelReferences references)
      : obj_path_(obj_path), obj_text_(obj_text), references_(references) {}

  // Called for each name of an `mtllib` statement. tinyobjloader stops at the first library that loads; returning
  // false after loading one makes it read the others of the statement too (its "failed to load" warning is dropped).
  bool operator()(const std::string& name, std::vector<tinyobj::material_t>* materials, std::map<std::string, int>* names, std::string* warnings,
                  std::string*) override {
    if (name.empty()) return false;  // a trailing blank after the names
    std::filesystem::path path = obj_path_.parent_path() / name;
    if (name.find('\\') != std::string::npos && !std::filesystem::exists(path)) {
      std::string forward = name;  // written on Windows
      std::replace(forward.begin(), forward.end(), '\\', '/');
      path = obj_path_.parent_path() / forward;
    }
    if (const std::string outside = outside_model_folder(obj_path_.parent_path(), path, references_); !outside.empty())
      throw InputError(fmt::format("{}: line {}: material library '{}' {}", obj_path_.string(), mtllib_line(name), path.string(), outside));
    const std::string key = path.lexically_normal().string();
    if (!loaded_.insert(key).second) return false;
    std::string text;
    try {
      text = read_model_input(path, "", "file");
    } catch (const InputError& error) {  // ": cannot open the file: ...", after the place, found only now
      throw InputError(fmt::format("{}: line {}: material library '{}'{}", obj_path_.string(), mtllib_line(name), path.string(), error.what()));
    }
    const std::map<std::string, MaterialSource> sources = scan(text, path);

    MemoryBuffer buffer(text);
    std::istream stream(&buffer);
    std::map<std::string, int> defined;
    std::string library_warnings;
    const std::size_t first = materials->size();
    tinyobj::LoadMtl(&defined, materials, &stream, &library_warnings, nullptr);
    for (std::size_t i = first; i < materials->size(); ++i) {
      const auto found = sources.find((*materials)[i].name);
      sources_.push_back(found != sources.end() ? found->second : MaterialSource{path});
    }
    for (const auto& [material, index] : defined) names->insert({encode_name(material), index});
    for (const std::string_view line : split_lines(library_warnings)) *warnings += fmt::format("{}: {}\n", path.filename().string(), line);
    return false;
  }

  const std::vector<MaterialSource>& sources() const { return sources_; }

  static std::vector<std::string_view> split_lines(std::string_view text) {
    std::vector<std::string_view> lines;
    Lines reader(text);
    std::string_view line;
    while (reader.next(line))
      if (!trim(line).empty()) lines.push_back(trim(line));
    return lines;
  }

 private:
  u64 mtllib_line(const std::string& name) const {
    Lines lines(obj_text_);
    std::string_view line, rest;
    while (lines.next(line))
      if (is_statement(line, "mtllib", &rest) && rest.find(name) != std::string_view::npos) return lines.number();
    return 0;
  }

  // Per material name (as tinyobjloader reads it), the statements it gives and where it starts.
  static std::map<std::string, MaterialSource> scan(std::string_view text, const std::filesystem::path& library) {
    std::map<std::string, MaterialSource> sources;
    MaterialSource* current = nullptr;
    Lines lines(text);
    std::string_view line, rest;
    while (lines.next(line)) {
      while (!line.empty() && is_blank(line.back())) line.remove_suffix(1);
      const std::string_view keyword = keyword_of(line, &rest);
      if (rest.empty()) continue;  // tinyobjloader reads no statement without a blank after its keyword
      if (keyword == "newmtl") {
        // tinyobjloader's name: everything after "newmtl" and one blank
        const std::size_t start = static_cast<std::size_t>(keyword.data() - line.data()) + 7;
        const std::string name(start <= line.size() ? line.substr(start) : std::string_view());
        const auto [entry, added] = sources.try_emplace(name, MaterialSource{library, lines.number()});
        current = added ? &entry->second : nullptr;  // a second definition of a name is not the one used
      } else if (current) {
        if (keyword == "Kd")
          current->has_kd = true;
        else if (keyword == "Ke")
          current->has_ke = true;
        else if (keyword == "Pr")
          current->has_pr = true;
        else if (keyword == "Pm")
          current->has_pm = true;
        else if (keyword == "norm")
          current->norm_line = lines.number();
        else if (keyword == "map_Bump" || keyword == "map_bump" || keyword == "bump")
          current->bump_line = lines.number();
        else if (keyword == "map_Pm")
          current->map_pm_line = lines.number();
        else if (keyword == "map_Pr")
          current->map_pr_line = lines.number();
      }
    }
    return sources;
  }

  std::filesystem::path obj_path_;
  const std::string& obj_text_;
  ModelReferences references_;
  std::set<std::string> loaded_;
  std::vector<MaterialSource> sources_;  // one per material, in tinyobjloader's order
};

struct CornerKey {
  int v, vt, vn;
  bool operator==(const CornerKey&) const = default;
};

struct CornerHash {
  std::size_t operator()(const CornerKey& key) const {
    u64 h = static_cast<u64>(static_cast<u32>(key.v)) * 0x9e3779b97f4a7c15ULL;
    h ^= static_cast<u64>(static_cast<u32>(key.vt)) * 0xc2b2ae3d27d4eb4fULL;
    h ^= static_cast<u64>(static_cast<u32>(key.vn)) * 0x165667b19e3779f9ULL;
    return static_cast<std::size_t>(h ^ (h >> 29));
  }
};

// The leading integer of a vertex reference's part, as tinyobjloader's atoi reads it.
long long leading_integer(std::string_view text) {
  std::string digits;
  std::size_t at = 0;
  if (at < text.size() && (text[at] == '-' || text[at] == '+')) digits += text[at++];
  while (at < text.size() && text[at] >= '0' && text[at] <= '9' && digits.size() < 20) digits += text[at++];
  return std::strtoll(digits.c_str(), nullptr, 10);
}

class ObjReader {
 public:
  ObjReader(const std::filesystem::path& path, std::string text, ModelReferences references)
      : path_(path), file_(path.string()), text_(std::move(text)), references_(references) {}

  MeshFile read() {
    prepare_text(text_);
    Parsed parsed = parse(false);
    // tinyobjloader counts a face's corners in a byte: a face of more than 255 corners has its count from the text
    // (count_face_corners). Should the text's faces not match tinyobjloader's, the file is read again with
    // tinyobjloader's own triangulation (which may cut concave faces wrong, and takes time quadratic in the corners).
    if (!count_face_corners(parsed.shapes)) {
      parsed = parse(true);
      warnings_.push_back("faces of more than 255 corners are cut into triangles by tinyobjloader, which may cut concave ones wrong");
      face_corners_.clear();
      for (const tinyobj::shape_t& shape : parsed.shapes)
        face_corners_.emplace_back(shape.mesh.num_face_vertices.begin(), shape.mesh.num_face_vertices.end());
    }
    const bool bad_indices = sort_warnings(parsed.warnings);
    check_numbers(parsed.attrib);
    check_indices(parsed.attrib, parsed.shapes, bad_indices);
    build_meshes(parsed.attrib, parsed.shapes);
    build_materials(parsed.materials, parsed.sources);
    if (!parsed.attrib.colors.empty()) warnings_.push_back("vertex colours are not rendered");
    out_.path = path_;
    for (std::string& warning : warnings_) out_.warnings.push_back(escape_control_characters(warning));  // text from the file, for a terminal
    return std::move(out_);
  }

 private:
  struct Parsed {
    tinyobj::attrib_t attrib;
    std::vector<tinyobj::shape_t> shapes;
    std::vector<tinyobj::material_t> materials;
    std::vector<MaterialSource> sources;  // one per material
    std::string warnings;
  };

  // Each face's corners, per shape, in tinyobjloader's order: its byte counts where none is above 255 (the usual
  // case), else the counts of the text's `f` lines, taken only where they match tinyobjloader's faces (the same
  // counts modulo 256, the same total per shape). False where they do not.
  bool count_face_corners(const std::vector<tinyobj::shape_t>& shapes) {
    face_corners_.clear();
    bool exact = true;
    for (const tinyobj::shape_t& shape : shapes) {
      u64 corners = 0;
      for (const unsigned char count : shape.mesh.num_face_vertices) corners += count;
      exact = exact && corners == shape.mesh.indices.size();
      face_corners_.emplace_back(shape.mesh.num_face_vertices.begin(), shape.mesh.num_face_vertices.end());
    }
    if (exact) return true;
    // The text's faces as tinyobjloader reads them: a line whose first word is `f`, its corners separated by spaces,
    // tabs and carriage returns; faces of fewer than 3 corners it drops.
    std::vector<u32> counts;
    for (std::size_t at = 0; at < text_.size();) {
      std::size_t end = text_.find('\n', at);
      if (end == std::string::npos) end = text_.size();
      std::size_t i = at;
      while (i < end && (text_[i] == ' ' || text_[i] == '\t')) ++i;
      if (i + 1 < end && text_[i] == 'f' && (text_[i + 1] == ' ' || text_[i + 1] == '\t')) {
        u32 words = 0;
        for (i += 2; i < end;) {
          while (i < end && (text_[i] == ' ' || text_[i] == '\t' || text_[i] == '\r')) ++i;
          if (i == end) break;
          ++words;
          while (i < end && text_[i] != ' ' && text_[i] != '\t' && text_[i] != '\r') ++i;
        }
        if (words >= 3) counts.push_back(words);
      }
      at = end + 1;
    }
    std::size_t next = 0;
    for (std::size_t s = 0; s < shapes.size(); ++s) {
      u64 corners = 0;
      for (u32& count : face_corners_[s]) {
        if (next == counts.size() || (counts[next] & 0xFFu) != count) return false;
        count = counts[next++];
        corners += count;
      }
      if (corners != shapes[s].mesh.indices.size()) return false;
    }
    return next == counts.size();
  }

  Parsed parse(bool triangulate) const {
    Parsed parsed;
    MaterialLibraries libraries(path_, text_, references_);
    std::string errors;
    MemoryBuffer buffer(text_);
    std::istream stream(&buffer);
    const bool ok = tinyobj::LoadObj(&parsed.attrib, &parsed.shapes, &parsed.materials, &parsed.warnings, &errors, &stream, &libraries, triangulate,
                                     /*default_vcols_fallback=*/false);
    if (!ok || !errors.empty()) fail_from_library(errors);
    parsed.sources = libraries.sources();
    return parsed;
  }

  [[noreturn]] void fail(std::string_view message) const { throw InputError(fmt::format("{}: {}", file_, message)); }
  [[noreturn]] void fail_at_line(u64 line, std::string_view message) const {
    if (line == 0) fail(message);
    throw InputError(fmt::format("{}: line {}: {}", file_, line, message));
  }

  // tinyobjloader's errors: "Failed parse `f' line(e.g. zero value for face index. line 29.)" and the like.
  [[noreturn]] void fail_from_library(const std::string& errors) const {
    const std::vector<std::string_view> lines = MaterialLibraries::split_lines(errors);
    const std::string_view first = lines.empty() ? std::string_view("tinyobjloader cannot read it") : lines.front();
    const std::size_t at = first.rfind("line ");
    const u64 line = at == std::string_view::npos ? 0 : static_cast<u64>(std::max(0LL, leading_integer(first.substr(at + 5))));
    if (first.starts_with("Failed parse `") && first.size() > 15 && line > 0)
      fail_at_line(line, fmt::format("cannot read the '{}' statement: a vertex index is 0 or not a number (OBJ counts vertices from 1)", first[14]));
    fail(first);
  }

  // Sorts tinyobjloader's warnings: those about indices say the file is broken (returns true); the rest are kept,
  // each once, with how often it came.
  bool sort_warnings(const std::string& warnings) {
    bool bad_indices = false;
    u64 short_faces = 0;
    std::vector<std::pair<std::string, u64>> kept;
    for (const std::string_view line : MaterialLibraries::split_lines(warnings)) {
      if (line == ".") continue;  // tinyobjloader writes "Degenerated face found\n."
      if (line.find("out of bounds") != std::string_view::npos || line.find("invalid vertex index") != std::string_view::npos) {
        bad_indices = true;
      } else if (line.starts_with("Degenerated face")) {
        ++short_faces;
      } else if (line.starts_with("Failed to load material file")) {
        // see MaterialLibraries::operator()
      } else {
        std::string text = decode_name(std::string(line));
        if (line.starts_with("material [ '")) {
          const std::size_t end = line.find("' ]");
          const std::string name = decode_name(std::string(line.substr(12, end == std::string_view::npos ? std::string_view::npos : end - 12)));
          const u64 at = usemtl_line(name);
          text = fmt::format("{}material '{}' is not defined by a material library; its faces get a default material",
                             at ? fmt::format("line {}: ", at) : "", clip(name));
        }
        const auto same = std::find_if(kept.begin(), kept.end(), [&](const auto& entry) { return entry.first == text; });
        if (same == kept.end())
          kept.emplace_back(std::move(text), 1);
        else
          ++same->second;
      }
    }
    if (short_faces > 0) warnings_.push_back(fmt::format("{} faces of fewer than 3 vertices skipped", short_faces));
    for (const auto& [text, count] : kept) warnings_.push_back(count > 1 ? fmt::format("{} ({} times)", text, count) : text);
    return bad_indices;
  }

  u64 usemtl_line(const std::string& name) const {
    const std::string encoded = encode_name(name);
    Lines lines(text_);
    std::string_view line, rest;
    while (lines.next(line))
      if (is_statement(line, "usemtl", &rest) && trim(rest) == encoded) return lines.number();
    return 0;
  }

  // Numbers too large for a double (1e999) are read as infinite: refused, with the statement's line. (tinyobjloader
  // reads what is not a number at all, `nan` included, as 0.)
  void check_numbers(const tinyobj::attrib_t& attrib) const {
    const auto check = [&](const std::vector<tinyobj::real_t>& values, std::size_t stride, std::string_view keyword, std::string_view what) {
      for (std::size_t i = 0; i < values.size(); ++i)
        if (!std::isfinite(values[i])) fail_at_line(line_of_statement(text_, keyword, i / stride), fmt::format("{} is not finite", what));
    };
    check(attrib.vertices, 3, "v", "vertex position");
    check(attrib.normals, 3, "vn", "normal");
    check(attrib.texcoords, 2, "vt", "texture coordinate");
  }

  // Every index a triangle uses must name a vertex, normal or texture coordinate of the file; tinyobjloader only
  // warns, and drops quadrilaterals with a bad vertex index (which its warnings tell).
  void check_indices(const tinyobj::attrib_t& attrib, const std::vector<tinyobj::shape_t>& shapes, bool bad_indices) const {
    const auto within = [](int index, std::size_t count) { return index >= 0 && static_cast<std::size_t>(index) < count; };
    const std::size_t positions = attrib.vertices.size() / 3, normals = attrib.normals.size() / 3, uvs = attrib.texcoords.size() / 2;
    for (const tinyobj::shape_t& shape : shapes)
      for (const tinyobj::index_t& index : shape.mesh.indices)
        if (!within(index.vertex_index, positions) || (index.normal_index != -1 && !within(index.normal_index, normals)) ||
            (index.texcoord_index != -1 && !within(index.texcoord_index, uvs)))
          bad_indices = true;
    if (!bad_indices) return;
    locate_bad_index(positions, uvs, normals);
    fail("a face refers to a vertex, normal or texture coordinate the file does not have");
  }

  // Finds the first face with an index out of range, as tinyobjloader reads indices: from 1, or negative counting
  // back from the last one read so far.
  void locate_bad_index(std::size_t positions, std::size_t uvs, std::size_t normals) const {
    static constexpr std::string_view kWhat[3] = {"vertex", "texture coordinate", "normal"};
    static constexpr std::string_view kPlural[3] = {"vertices", "texture coordinates", "normals"};
    const std::size_t totals[3] = {positions, uvs, normals};
    std::size_t seen[3] = {0, 0, 0};
    Lines lines(text_);
    std::string_view line, rest;
    while (lines.next(line)) {
      if (is_statement(line, "v"))
        ++seen[0];
      else if (is_statement(line, "vt"))
        ++seen[1];
      else if (is_statement(line, "vn"))
        ++seen[2];
      if (!is_statement(line, "f", &rest)) continue;
      for (const std::string_view reference : words_of(rest)) {
        std::string_view parts[3];
        std::size_t part = 0, start = 0;
        for (std::size_t i = 0; i <= reference.size() && part < 3; ++i)
          if (i == reference.size() || reference[i] == '/') {
            parts[part++] = reference.substr(start, i - start);
            start = i + 1;
          }
        for (int k = 0; k < 3; ++k) {
          if (k > 0 && parts[k].empty()) continue;
          const long long index = leading_integer(parts[k]);
          if (index > 0 && static_cast<unsigned long long>(index) > totals[k])
            fail_at_line(lines.number(), fmt::format("{} index {} out of range (the file has {} {})", kWhat[k], index, totals[k], kPlural[k]));
          if (index < 0 && static_cast<unsigned long long>(-index) > seen[k])
            fail_at_line(lines.number(), fmt::format("{} index {} out of range (only {} {} before it)", kWhat[k], index, seen[k], kPlural[k]));
        }
      }
    }
  }

  // One TriangleMesh per shape with faces; a vertex per distinct (position, texture coordinate, normal) triple;
  // polygons cut into triangles by cut_polygon.
  void build_meshes(const tinyobj::attrib_t& attrib, const std::vector<tinyobj::shape_t>& shapes) {
    u64 corners = 0, lines = 0, points = 0, vertices = 0, fanned = 0;
    for (const tinyobj::shape_t& shape : shapes) {
      corners += shape.mesh.indices.size();
      lines += shape.lines.num_line_vertices.size();
      points += shape.points.indices.size();
    }
    if (corners == 0)
      fail(fmt::format("has no faces ({} vertices, {} lines, {} points; only faces are rendered)", attrib.vertices.size() / 3, lines, points));
    // A polygon of n corners makes n - 2 triangles: fewer than its corners.
    if (corners > 3 * kMaxMeshTriangles)
      fail(fmt::format("has faces of {} corners in all, more than the {} triangles a model file may have can use", corners, kMaxMeshTriangles));
    if (lines + points > 0) warnings_.push_back(fmt::format("lines and points are not rendered ({} lines, {} points)", lines, points));

    std::unordered_map<CornerKey, u32, CornerHash> vertex_of;
    std::vector<Vec3d> polygon;
    std::vector<std::array<u32, 3>> cut;
    u64 triangles = 0;
    for (const tinyobj::shape_t& shape : shapes) {
      const std::vector<tinyobj::index_t>& indices = shape.mesh.indices;
      if (indices.size() < 3) continue;
      TriangleMesh mesh;
      const std::string_view name = trim(shape.name);
      mesh.name = name.empty() ? fmt::format("mesh {}", out_.meshes.size()) : std::string(name);
      vertex_of.clear();
      vertex_of.reserve(indices.size());
      std::vector<u32> vertex;  // of each corner
      vertex.reserve(indices.size());
      u64 with_normal = 0, with_uv = 0;
      for (const tinyobj::index_t& index : indices) {
        const CornerKey key{index.vertex_index, index.texcoord_index, index.normal_index};
        const auto [entry, added] = vertex_of.try_emplace(key, static_cast<u32>(mesh.positions.size()));
        vertex.push_back(entry->second);
        if (!added) continue;
        if (++vertices > kMaxMeshVertices)
          fail(fmt::format("has more than {} distinct vertices (position, normal and texture coordinate), the most a model file may have",
                           kMaxMeshVertices));
        const double* at = &attrib.vertices[3 * static_cast<std::size_t>(key.v)];
        mesh.positions.push_back({at[0], at[1], at[2]});
        if (key.vn >= 0) {
          at = &attrib.normals[3 * static_cast<std::size_t>(key.vn)];
          mesh.normals.push_back({at[0], at[1], at[2]});
          ++with_normal;
        } else {
          mesh.normals.push_back({0, 0, 0});
        }
        if (key.vt >= 0) {
          at = &attrib.texcoords[2 * static_cast<std::size_t>(key.vt)];
          mesh.uvs.push_back({at[0], at[1]});
          ++with_uv;
        } else {
          mesh.uvs.push_back({0, 0});
        }
      }
      std::vector<int>& material_ids = material_ids_.emplace_back();
      std::size_t first = 0;
      const std::vector<u32>& face_corners = face_corners_[static_cast<std::size_t>(&shape - shapes.data())];
      for (std::size_t face = 0; face < face_corners.size(); ++face) {
        const std::size_t count = face_corners[face];
        polygon.clear();
        for (std::size_t k = 0; k < count; ++k) polygon.push_back(mesh.positions[vertex[first + k]]);
        cut.clear();
        if (!cut_polygon(polygon, cut).ears_found) ++fanned;
        for (const auto& triangle : cut) {
          mesh.triangles.push_back({vertex[first + triangle[0]], vertex[first + triangle[1]], vertex[first + triangle[2]]});
          material_ids.push_back(face < shape.mesh.material_ids.size() ? shape.mesh.material_ids[face] : -1);
        }
        first += count;
      }
      triangles += mesh.triangles.size();
      if (triangles > kMaxMeshTriangles) fail(fmt::format("has more than {} triangles, the most a model file may have", kMaxMeshTriangles));
      const std::size_t count = mesh.positions.size();
      if (with_normal == 0) {
        mesh.normals.clear();
      } else if (with_normal < count) {
        warnings_.push_back(fmt::format("mesh '{}': some faces have normals and some not: the file's normals are not used for it", clip(mesh.name)));
        mesh.normals.clear();
      } else {
        u64 zero = 0;
        for (Vec3d& normal : mesh.normals) {
          const double norm = length(normal);
          if (norm > 0 && std::isfinite(norm))
            normal = normal / norm;
          else
            ++zero;
        }
        if (zero > 0) {
          warnings_.push_back(fmt::format("mesh '{}': {} normals of zero length: the file's normals are not used for it", clip(mesh.name), zero));
          mesh.normals.clear();
        }
      }
      if (with_uv == 0)
        mesh.uvs.clear();
      else if (with_uv < count)
        warnings_.push_back(fmt::format("mesh '{}': some faces have texture coordinates and some not (those get 0, 0)", clip(mesh.name)));
      out_.meshes.push_back(std::move(mesh));
      out_.placements.push_back(MeshPlacement{static_cast<u32>(out_.meshes.size() - 1), AffineTransform{}});
    }
    if (fanned > 0) warnings_.push_back(fmt::format("{} faces are not simple polygons (they cross themselves): cut as fans", fanned));
  }

  // The materials the faces use, in the libraries' order, and a default one for faces without (or with an
  // undefined) material; their textures, each file read once.
  void build_materials(const std::vector<tinyobj::material_t>& materials, const std::vector<MaterialSource>& sources) {
    std::vector<i32> remap(materials.size(), -1);
    bool needs_default = false;
    for (const std::vector<int>& ids : material_ids_)
      for (const int id : ids) {
        if (id >= 0 && static_cast<std::size_t>(id) < materials.size())
          remap[static_cast<std::size_t>(id)] = 0;
        else
          needs_default = true;
      }
    std::map<std::string, std::vector<std::string>> unrendered;  // feature -> the materials that have it
    for (std::size_t i = 0; i < materials.size(); ++i) {
      if (remap[i] < 0) continue;
      remap[i] = static_cast<i32>(out_.materials.size());
      out_.materials.push_back(convert(materials[i], i < sources.size() ? sources[i] : MaterialSource{}, unrendered));
    }
    const u32 default_material = static_cast<u32>(out_.materials.size());
    if (needs_default || out_.materials.empty()) {
      MeshMaterial material;
      material.name = "default";
      out_.materials.push_back(material);
    }
    for (const auto& [feature, names] : unrendered) {
      std::string list;
      for (std::size_t k = 0; k < names.size() && k < 3; ++k) list += fmt::format("{}'{}'", k ? ", " : "", clip(names[k]));
      if (names.size() > 3) list += fmt::format(" and {} more", names.size() - 3);
      warnings_.push_back(fmt::format("{} (material{} {})", feature, names.size() > 1 ? "s" : "", list));
    }
    for (std::size_t m = 0; m < out_.meshes.size(); ++m) {
      const std::vector<int>& ids = material_ids_[m];
      std::vector<u32>& per_triangle = out_.meshes[m].materials;
      per_triangle.resize(out_.meshes[m].triangles.size(), default_material);
      for (std::size_t t = 0; t < per_triangle.size() && t < ids.size(); ++t)
        if (ids[t] >= 0 && static_cast<std::size_t>(ids[t]) < materials.size())
          per_triangle[t] = static_cast<u32>(remap[static_cast<std::size_t>(ids[t])]);
      if (std::all_of(per_triangle.begin(), per_triangle.end(), [](u32 id) { return id == 0; })) per_triangle.clear();
    }
  }

  MeshMaterial convert(const tinyobj::material_t& from, const MaterialSource& source, std::map<std::string, std::vector<std::string>>& unrendered) {
    const std::string where = source.line > 0
                                  ? fmt::format("{}: line {}: material '{}'", source.library.filename().string(), source.line, clip(from.name))
                                  : fmt::format("{}: material '{}'", source.library.filename().string(), clip(from.name));
    const auto color = [&](const tinyobj::real_t(&c)[3], std::string_view statement) {
      const Vec3d value{c[0], c[1], c[2]};
      if (!std::isfinite(value.x) || !std::isfinite(value.y) || !std::isfinite(value.z) || value.x < 0 || value.y < 0 || value.z < 0)
        fail(fmt::format("{}: {} is not a colour (finite and not negative)", where, statement));
      return value;
    };
    MeshMaterial material;
    material.name = from.name;
    if (source.has_kd)
      material.base_color = color(from.diffuse, "Kd");
    else if (!from.diffuse_texname.empty())
      material.base_color = {1, 1, 1};  // the texture as it is (tinyobjloader makes it 0.6)
    if (material.base_color.x > 1 || material.base_color.y > 1 || material.base_color.z > 1) {
      material.base_color = {std::min(material.base_color.x, 1.0), std::min(material.base_color.y, 1.0), std::min(material.base_color.z, 1.0)};
      unrendered["diffuse colours (Kd) above 1 are clamped to 1"].push_back(from.name);
    }
    if (source.has_ke)
      material.emission = color(from.emission, "Ke");
    else if (!from.emissive_texname.empty())
      material.emission = {1, 1, 1};
    const auto factor = [&](double value, std::string_view statement, double fallback) {
      if (!std::isfinite(value)) fail(fmt::format("{}: {} is not finite", where, statement));
      if (value < 0 || value > 1) unrendered[fmt::format("{} outside [0, 1] is clamped to it", statement)].push_back(from.name);
      return std::isfinite(value) ? std::clamp(value, 0.0, 1.0) : fallback;
    };
    if (source.has_pm) material.metallic = factor(from.metallic, "Pm", 0);
    if (source.has_pr) material.roughness = factor(from.roughness, "Pr", 1);
    // The metallic-roughness model where the MTL asks for more than a diffuse colour: PBR statements (Pm, Pr), or
    // specular highlights (Ks above zero). Ks's colour has no place in the model: such a material is a dielectric
    // (metallic 0, F0 = 0.04) unless Pm says otherwise. Without Pr its roughness comes from the Phong exponent Ns
    // by Walter et al. 2007's correspondence of Phong and microfacet lobes, alpha = sqrt(2 / (Ns + 2)), and glTF's
    // alpha = roughness^2. Materials with neither stay diffuse, as they were.
    const bool specular = from.specular[0] > 0 || from.specular[1] > 0 || from.specular[2] > 0;
    material.metallic_roughness_model = source.has_pm || source.has_pr || specular;
    if (specular && !source.has_pr) {
      const double ns = std::isfinite(from.shininess) ? std::max(0.0, static_cast<double>(from.shininess)) : 0.0;
      material.roughness = std::sqrt(std::sqrt(2.0 / (ns + 2.0)));
    }
    material.base_color_texture = texture(from.diffuse_texname, from.diffuse_texopt, "map_Kd", source, where, unrendered, from.name);
    material.emission_texture = texture(from.emissive_texname, from.emissive_texopt, "map_Ke", source, where, unrendered, from.name);
    read_metallic_roughness_maps(from, source, unrendered, material);
    read_normal_map(from, source, unrendered, material);
    // A normal map or a metallic or roughness map asks for more than a diffuse colour, as Pm and Pr do.
    if (material.normal_texture >= 0 || material.metallic_roughness_texture >= 0) material.metallic_roughness_model = true;

    if (!from.displacement_texname.empty()) unrendered["displacement maps (disp) are not rendered"].push_back(from.name);
    if (from.dissolve < 1 || !from.alpha_texname.empty()) unrendered["transparency (d, Tr, map_d) is not rendered"].push_back(from.name);
    if (!from.specular_texname.empty()) unrendered["specular maps (map_Ks) are not rendered"].push_back(from.name);
    if (specular && !source.has_pm)
      unrendered["specular highlights (Ks) take a dielectric's reflectance (F0 = 0.04), not the colour Ks gives"].push_back(from.name);
    return material;
  }

  // A statement's place for messages: the library, the statement's line (or the material's where it is not known)
  // and the material.
  static std::string statement_place(const MaterialSource& source, u64 line, const std::string& material) {
    const u64 at = line > 0 ? line : source.line;
    return at > 0 ? fmt::format("{}: line {}: material '{}'", source.library.filename().string(), at, clip(material))
                  : fmt::format("{}: material '{}'", source.library.filename().string(), clip(material));
  }

  // The PBR extension's metallic and roughness maps (map_Pm, map_Pr), each a greyscale image (its red channel is
  // read, or the one -imfchan r, g or b names), combined here into one texture of glTF's layout: roughness in green,
  // metallic in blue, read as linear data. Images of different sizes are sampled at the nearest texel onto the larger
  // width and the larger height. A constant Pm or Pr given with its map multiplies it, as Kd multiplies map_Kd;
  // without the constant the map is taken as it is; without a map the constant stands alone (a full channel times it).
  void read_metallic_roughness_maps(const tinyobj::material_t& from, const MaterialSource& source,
                                    std::map<std::string, std::vector<std::string>>& unrendered, MeshMaterial& material) {
    if (from.metallic_texname.empty() && from.roughness_texname.empty()) return;
    const i32 metallic = texture(from.metallic_texname, from.metallic_texopt, "map_Pm", source,
                                 statement_place(source, source.map_pm_line, from.name), unrendered, from.name);
    const i32 roughness = texture(from.roughness_texname, from.roughness_texopt, "map_Pr", source,
                                  statement_place(source, source.map_pr_line, from.name), unrendered, from.name);
    const auto channel = [](const tinyobj::texture_option_t& options) { return options.imfchan == 'g' ? 1 : options.imfchan == 'b' ? 2 : 0; };
    const std::array<int, 4> key{metallic, channel(from.metallic_texopt), roughness, channel(from.roughness_texopt)};
    if (const auto found = combined_.find(key); found != combined_.end()) {
      material.metallic_roughness_texture = found->second;
    } else {
      const TextureImage* m = metallic >= 0 ? &out_.textures[static_cast<std::size_t>(metallic)] : nullptr;
      const TextureImage* r = roughness >= 0 ? &out_.textures[static_cast<std::size_t>(roughness)] : nullptr;
      TextureImage packed;
      packed.width = std::max(m ? m->width : 0u, r ? r->width : 0u);
      packed.height = std::max(m ? m->height : 0u, r ? r->height : 0u);
      packed.srgb.assign(3 * static_cast<std::size_t>(packed.width) * packed.height, 255);
      const auto sample = [&](const TextureImage& image, int c, u32 x, u32 y) {
        const u64 sx = u64{x} * image.width / packed.width, sy = u64{y} * image.height / packed.height;
        return image.srgb[3 * (sy * image.width + sx) + static_cast<u64>(c)];
      };
      for (u32 y = 0; y < packed.height; ++y)
        for (u32 x = 0; x < packed.width; ++x) {
          u8* texel = &packed.srgb[3 * (static_cast<std::size_t>(y) * packed.width + x)];
          texel[0] = 0;
          if (r) texel[1] = sample(*r, key[3], x, y);
          if (m) texel[2] = sample(*m, key[1], x, y);
        }
      out_.textures.push_back(std::move(packed));
      material.metallic_roughness_texture = static_cast<i32>(out_.textures.size() - 1);
      combined_.emplace(key, material.metallic_roughness_texture);
    }
    if (metallic >= 0 && !source.has_pm) material.metallic = 1;
    if (roughness >= 0 && !source.has_pr) material.roughness = 1;
  }

  // A tangent-space normal map: `norm` (the PBR extension's), or `map_Bump`/`bump` where the image is one. Many
  // exporters (Blender's among them) write normal maps as map_Bump; a height map there is not rendered (bump
  // mapping is not implemented), with a warning naming its line. -bm scales the map's x and y (Blender writes its
  // normal map strength there).
  void read_normal_map(const tinyobj::material_t& from, const MaterialSource& source, std::map<std::string, std::vector<std::string>>& unrendered,
                       MeshMaterial& material) {
    if (!from.normal_texname.empty()) {
      material.normal_texture = texture(from.normal_texname, from.normal_texopt, "norm", source, statement_place(source, source.norm_line, from.name),
                                        unrendered, from.name);
      material.normal_scale = from.normal_texopt.bump_multiplier;
      if (!from.bump_texname.empty()) unrendered["bump maps given beside a normal map (norm) are not rendered"].push_back(from.name);
      return;
    }
    if (from.bump_texname.empty()) return;
    const std::string place = statement_place(source, source.bump_line, from.name);
    const i32 image = texture(from.bump_texname, from.bump_texopt, "map_Bump", source, place, unrendered, from.name);
    // -imfchan other than the default 'l' picks one channel: a height map by its own account.
    if (from.bump_texopt.imfchan == 'l' && is_normal_map(out_.textures[static_cast<std::size_t>(image)])) {
      material.normal_texture = image;
      material.normal_scale = from.bump_texopt.bump_multiplier;
      return;
    }
    warnings_.push_back(fmt::format("{}: bump map '{}' is a height map, not a tangent-space normal map: height maps are not rendered", place,
                                    clip(from.bump_texname)));
  }

  // Whether an image holds tangent-space normals: not grey (a height map is), and most texels, read as 2c - 1, of
  // nearly unit length and pointing out of the surface (blue above one half).
  static bool is_normal_map(const TextureImage& image) {
    const std::size_t texels = image.srgb.size() / 3;
    std::size_t grey = 0, unit = 0;
    for (std::size_t i = 0; i < texels; ++i) {
      const u8* c = &image.srgb[3 * i];
      if (c[0] == c[1] && c[1] == c[2]) ++grey;
      const double x = c[0] / 127.5 - 1, y = c[1] / 127.5 - 1, z = c[2] / 127.5 - 1;
      const double length2 = x * x + y * y + z * z;
      if (z > 0 && length2 > 0.64 && length2 < 1.44) ++unit;
    }
    return texels > 0 && grey < texels && unit >= texels * 9 / 10;
  }

  i32 texture(const std::string& name, const tinyobj::texture_option_t& options, std::string_view statement, const MaterialSource& source,
              const std::string& where, std::map<std::string, std::vector<std::string>>& unrendered, const std::string& material) {
    if (name.empty()) return -1;
    const std::filesystem::path folder = source.library.parent_path();
    std::filesystem::path path = folder / name;
    if (name.find('\\') != std::string::npos && !std::filesystem::exists(path)) {
      std::string forward = name;  // written on Windows
      std::replace(forward.begin(), forward.end(), '\\', '/');
      path = folder / forward;
    }
    if (options.origin_offset[0] != 0 || options.origin_offset[1] != 0 || options.origin_offset[2] != 0 || options.scale[0] != 1 ||
        options.scale[1] != 1 || options.scale[2] != 1 || options.turbulence[0] != 0 || options.turbulence[1] != 0 || options.turbulence[2] != 0)
      unrendered["texture options -o, -s and -t are not applied"].push_back(material);
    if (const std::string outside = outside_model_folder(path_.parent_path(), path, references_); !outside.empty())
      fail(fmt::format("{}: {}: '{}' {}", where, statement, path.string(), outside));
    const std::string key = path.lexically_normal().string();
    if (const auto found = textures_.find(key); found != textures_.end()) return found->second;
    try {
      out_.textures.push_back(read_texture_image(path));
    } catch (const InputError& error) {
      fail(fmt::format("{}: {}: {}", where, statement, error.what()));
    }
    const i32 index = static_cast<i32>(out_.textures.size() - 1);
    textures_.emplace(key, index);
    return index;
  }

  std::filesystem::path path_;
  std::string file_;
  std::string text_;
  ModelReferences references_;
  MeshFile out_;
  std::vector<std::string> warnings_;
  std::vector<std::vector<int>> material_ids_;  // per mesh, per triangle: tinyobjloader's material, or -1
  std::vector<std::vector<u32>> face_corners_;  // per shape, per face: its corners (count_face_corners)
  std::map<std::string, i32> textures_;
  std::map<std::array<int, 4>, i32> combined_;  // metallic and roughness images (and channels) -> their packed texture
};

}  // namespace

MeshFile read_obj_file(const std::filesystem::path& path, ModelReferences references) {
  return ObjReader(path, read_model_input(path, path.string(), "OBJ file"), references).read();
}

}  // namespace pt
