// The outline pass: nlohmann's SAX parser runs once over the text; values outside the long lists are built into a
// JSON value as nlohmann's own DOM parser would, and each list entry is skipped, its text range noted.
#include "loading/json_outline.hpp"

#include <cstdint>
#include <functional>
#include <utility>

#include <fmt/format.h>

#include "base/errors.hpp"
#include "scene/json_positions.hpp"
#include "scene/json_scan.hpp"

namespace pt {

namespace {

using Json = nlohmann::json;

class OutlineBuilder {
 public:
  OutlineBuilder(std::string_view text, const std::string& source, const std::size_t* consumed, JsonOutline* outline,
                 const std::function<void(std::size_t)>& passed)
      : text_(text), source_(source), consumed_(consumed), outline_(outline), passed_(passed) {}

  const std::string& error() const { return error_; }

  bool null() { return scalar(Json(nullptr)); }
  bool boolean(bool v) { return scalar(Json(v)); }
  bool number_integer(std::int64_t v) { return scalar(Json(v)); }
  bool number_unsigned(std::uint64_t v) { return scalar(Json(v)); }
  bool number_float(double v, const std::string&) { return scalar(Json(v)); }
  bool string(std::string& v) { return scalar(Json(std::move(v))); }
  bool binary(Json::binary_t&) { return scalar(Json()); }  // binary values do not occur in JSON text
  bool start_object(std::size_t) { return open(false); }
  bool start_array(std::size_t) { return open(true); }
  bool key(std::string& k) {
    frames_.back().key = std::move(k);
    last_end_ = *consumed_;
    return true;
  }
  bool end_object() { return close(); }
  bool end_array() { return close(); }

  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception& e) {
    if (const auto* syntax = dynamic_cast<const Json::parse_error*>(&e)) {
      const TextPosition at = JsonPositions::position_of_offset(text_, syntax->byte > 0 ? syntax->byte - 1 : 0);
      std::string what = e.what();
      // nlohmann's message starts with its own error id and position ("[json.exception.parse_error.101] parse
      // error at line 8, column 55: "): keep only the description, the position is already in front.
      if (const auto column = what.find(", column "); column != std::string::npos)
        if (const auto colon = what.find(": ", column); colon != std::string::npos) what = what.substr(colon + 2);
      error_ = fmt::format("{}:{}:{}: invalid JSON: {}", source_, at.line, at.column, what);
    } else {
      // The only other failure of the parser: a number too large for a double ("1e999"), which it has just read.
      const std::size_t begin = start_of_next_value(text_, last_end_);
      const std::string_view literal = text_.substr(begin, end_of_scalar(text_, begin) - begin);
      error_ = fmt::format("{}: {}: the number {} is beyond the range of a double (about 1.8e308)", place(begin), pointer(), literal);
    }
    return false;
  }

 private:
  // What the entries of a container are: parts of the document, or list entries read later from their text.
  enum class Entries { kInDocument, kObjectList, kMaterialList, kTextureList };

  struct Frame {
    bool is_array;
    std::size_t index;
    std::string key;
    Entries entries;
  };

  std::string place(std::size_t offset) const {
    const TextPosition at = JsonPositions::position_of_offset(text_, offset);
    return fmt::format("{}:{}:{}", source_, at.line, at.column);
  }
  // The JSON path of the value being read.
  std::string pointer() const {
    std::string p;
    for (const Frame& f : frames_) {
      p += '/';
      p += f.is_array ? std::to_string(f.index) : escape_pointer_token(f.key);
    }
    return p.empty() ? "(top level)" : p;
  }

  bool refuse(std::string message) {
    error_ = std::move(message);
    return false;
  }

  // Counts a value against the budget of the part it belongs to; an entry of a list starts a new part.
  bool count_value(bool starts_entry) {
    if (starts_entry) entry_values_ = 0;
    std::size_t& count = (in_entry_ || starts_entry) ? entry_values_ : rest_values_;
    if (++count <= kMaxJsonValuesPerEntry) return true;
    return refuse(fmt::format("{}: {}: more than {} JSON values in one {} (see docs/scene-format.md)", place(start_of_next_value(text_, last_end_)),
                              pointer(), kMaxJsonValuesPerEntry, in_entry_ || starts_entry ? "entry of a list" : "scene outside its lists"));
  }

  bool entries_are_listed() const { return !in_entry_ && !frames_.empty() && frames_.back().entries != Entries::kInDocument; }

  // A value directly under the top-level object decides whether the list of that name is read entry by entry; a
  // later value under the same key replaces it (nlohmann keeps the last), so the list is reset either way.
  Entries list_kind(Json::value_t type) {
    if (in_entry_ || frames_.size() != 1 || frames_[0].is_array) return Entries::kInDocument;
    const std::string& key = frames_[0].key;
    if (key == "objects") {
      outline_->objects.reset();
      if (type != Json::value_t::array) return Entries::kInDocument;
      outline_->objects.emplace();
      return Entries::kObjectList;
    }
    if (key == "materials" || key == "textures") {
      auto& list = key == "materials" ? outline_->materials : outline_->textures;
      list.reset();
      if (type != Json::value_t::object) return Entries::kInDocument;
      list.emplace();
      return key == "materials" ? Entries::kMaterialList : Entries::kTextureList;
    }
    return Entries::kInDocument;
  }

  void add_entry(TextRange range) {
    if (passed_) passed_(range.begin);
    const Frame& list = frames_.back();
    if (list.entries == Entries::kObjectList)
      outline_->objects->push_back(range);
    else
      (list.entries == Entries::kMaterialList ? *outline_->materials : *outline_->textures)[list.key] = range;
  }

  // Puts a value into the document where the parser is; returns it (stable until its container closes).
  Json* place_in_document(Json&& value) {
    if (containers_.empty()) {
      outline_->root = std::move(value);
      return &outline_->root;
    }
    Json& parent = *containers_.back();
    if (parent.is_array()) {
      parent.push_back(std::move(value));
      return &parent.back();
    }
    Json& slot = parent[frames_.back().key];
    slot = std::move(value);
    return &slot;
  }

  bool scalar(Json&& value) {
    const bool starts_entry = entries_are_listed();
    if (!count_value(starts_entry)) return false;
    if (starts_entry) {
      const std::size_t begin = start_of_next_value(text_, last_end_);
      add_entry({begin, end_of_scalar(text_, begin)});
    } else if (!in_entry_) {
      list_kind(value.type());
      place_in_document(std::move(value));
    }
    advance();
    last_end_ = *consumed_;
    return true;
  }

  bool open(bool is_array) {
    if (frames_.size() >= kMaxJsonNesting)
      return refuse(fmt::format("{}: invalid JSON: arrays and objects nested more than {} deep", place(start_of_next_value(text_, last_end_)),
                                kMaxJsonNesting));
    const bool starts_entry = entries_are_listed();
    if (!count_value(starts_entry)) return false;
    Entries entries = Entries::kInDocument;
    if (starts_entry) {
      in_entry_ = true;
      entry_depth_ = frames_.size();
      entry_begin_ = start_of_next_value(text_, last_end_);
    } else if (!in_entry_) {
      entries = list_kind(is_array ? Json::value_t::array : Json::value_t::object);
      containers_.push_back(place_in_document(is_array ? Json::array() : Json::object()));
    }
    frames_.push_back({is_array, 0, {}, entries});
    last_end_ = *consumed_;
    return true;
  }

  bool close() {
    frames_.pop_back();
    if (in_entry_) {
      if (frames_.size() == entry_depth_) {
        in_entry_ = false;
        add_entry({entry_begin_, *consumed_});
      }
    } else {
      containers_.pop_back();
    }
    advance();
    last_end_ = *consumed_;
    return true;
  }

  void advance() {
    if (!frames_.empty() && frames_.back().is_array) ++frames_.back().index;
  }

  std::string_view text_;
  const std::string& source_;
  const std::size_t* consumed_;
  JsonOutline* outline_;
  const std::function<void(std::size_t)>& passed_;
  std::vector<Frame> frames_;
  std::vector<Json*> containers_;  // the open arrays and objects of the document, innermost last
  bool in_entry_ = false;          // inside a list entry (nothing is built)
  std::size_t entry_depth_ = 0;    // frames_.size() outside the entry being skipped
  std::size_t entry_begin_ = 0;
  std::size_t entry_values_ = 0, rest_values_ = 0;
  std::size_t last_end_ = 0;  // how far the lexer had read at the previous event
  std::string error_;
};

}  // namespace

JsonOutline read_json_outline(std::string_view text, const std::string& source, const std::function<void(std::size_t)>& passed) {
  JsonOutline outline;
  std::size_t consumed = 0;
  OutlineBuilder builder(text, source, &consumed, &outline, passed);
  CountingIterator first(text.data(), &consumed), last(text.data() + text.size(), &consumed);
  if (!Json::sax_parse(first, last, &builder)) throw InputError(builder.error());
  return outline;
}

}  // namespace pt
