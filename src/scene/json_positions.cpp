// Finds one value of a JSON text by its pointer: nlohmann's SAX parser runs over the text while a stack of the
// enclosing arrays and objects says how much of the pointer the current place matches.
#include "scene/json_positions.hpp"

#include <cstdint>
#include <vector>

#include <nlohmann/json.hpp>

#include "scene/json_scan.hpp"

namespace pt {

std::string escape_pointer_token(const std::string& token) {
  std::string out;
  for (char c : token) {
    if (c == '~')
      out += "~0";
    else if (c == '/')
      out += "~1";
    else
      out += c;
  }
  return out;
}

namespace {

// The pointer's tokens with their escapes undone ("/a~1b/0" -> {"a/b", "0"}).
std::vector<std::string> pointer_tokens(const std::string& pointer) {
  std::vector<std::string> tokens;
  for (std::size_t i = 0; i < pointer.size();) {
    // Every token follows a '/'; a pointer that does not start with one names no value (handled by the caller).
    std::size_t next = pointer.find('/', i + 1);
    if (next == std::string::npos) next = pointer.size();
    std::string token;
    for (std::size_t j = i + 1; j < next; ++j) {
      if (pointer[j] == '~' && j + 1 < next && (pointer[j + 1] == '0' || pointer[j + 1] == '1')) {
        token += pointer[j + 1] == '0' ? '~' : '/';
        ++j;
      } else {
        token += pointer[j];
      }
    }
    tokens.push_back(std::move(token));
    i = next;
  }
  return tokens;
}

// Follows the SAX events; `matched` counts the enclosing containers, from the outside, whose current key or index
// equals the pointer's token at that depth, so each event costs O(1) beyond reading the key.
class ValueFinder {
 public:
  ValueFinder(std::string_view text, const std::size_t* consumed, std::vector<std::string> tokens)
      : text_(text), consumed_(consumed), tokens_(std::move(tokens)) {}

  std::optional<std::size_t> found() const { return found_; }

  bool null() { return scalar(); }
  bool boolean(bool) { return scalar(); }
  bool number_integer(std::int64_t) { return scalar(); }
  bool number_unsigned(std::uint64_t) { return scalar(); }
  bool number_float(double, const std::string&) { return scalar(); }
  bool string(std::string&) { return scalar(); }
  bool binary(nlohmann::json::binary_t&) { return scalar(); }
  bool start_object(std::size_t) { return open(false); }
  bool start_array(std::size_t) { return open(true); }
  bool key(std::string& k) {
    Frame& top = frames_.back();
    top.key = std::move(k);
    reselect();
    last_end_ = *consumed_;
    return true;
  }
  bool end_object() { return close(); }
  bool end_array() { return close(); }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception&) { return false; }

 private:
  struct Frame {
    bool is_array;
    std::size_t index;
    std::string key;
  };

  void note_value() {
    if (matched_ == frames_.size() && frames_.size() == tokens_.size()) found_ = start_of_next_value(text_, last_end_);
  }
  bool scalar() {
    note_value();
    advance();
    last_end_ = *consumed_;
    return true;
  }
  bool open(bool is_array) {
    if (frames_.size() >= kMaxJsonNesting) return false;
    note_value();
    frames_.push_back({is_array, 0, {}});
    if (is_array) reselect();
    last_end_ = *consumed_;
    return true;
  }
  bool close() {
    frames_.pop_back();
    if (matched_ > frames_.size()) matched_ = frames_.size();
    advance();
    last_end_ = *consumed_;
    return true;
  }
  void advance() {
    if (!frames_.empty() && frames_.back().is_array) {
      ++frames_.back().index;
      reselect();
    }
  }
  // The innermost container's key or index has changed: whether the match reaches through it.
  void reselect() {
    const std::size_t depth = frames_.size() - 1;
    if (matched_ < depth) return;
    const Frame& top = frames_.back();
    const bool same = depth < tokens_.size() && (top.is_array ? tokens_[depth] == std::to_string(top.index) : tokens_[depth] == top.key);
    matched_ = same ? depth + 1 : depth;
  }

  std::string_view text_;
  const std::size_t* consumed_;
  std::vector<std::string> tokens_;
  std::vector<Frame> frames_;
  std::size_t matched_ = 0;
  std::size_t last_end_ = 0;
  std::optional<std::size_t> found_;
};

}  // namespace

std::optional<std::size_t> find_value_offset(std::string_view text, const std::string& pointer) {
  if (!pointer.empty() && pointer[0] != '/') return std::nullopt;
  std::size_t consumed = 0;
  ValueFinder finder(text, &consumed, pointer_tokens(pointer));
  CountingIterator first(text.data(), &consumed), last(text.data() + text.size(), &consumed);
  nlohmann::json::sax_parse(first, last, &finder);
  return finder.found();
}

TextPosition JsonPositions::find(const std::string& pointer) const {
  const std::optional<std::size_t> offset = find_value_offset(text_, pointer);
  return offset ? position_of_offset(text_, *offset) : TextPosition{};
}

TextPosition JsonPositions::position_of_offset(std::string_view text, std::size_t offset) {
  TextPosition position{1, 1};
  for (std::size_t i = 0; i < offset && i < text.size(); ++i) {
    if (text[i] == '\n') {
      ++position.line;
      position.column = 1;
    } else {
      ++position.column;
    }
  }
  return position;
}

}  // namespace pt
