// Records the text offset of every JSON value by running nlohmann's SAX parser over an input that counts the
// characters the lexer has consumed.
#include "scene/json_positions.hpp"

#include <iterator>
#include <vector>

#include <nlohmann/json.hpp>

namespace pt {

namespace {

// A character iterator that tells a shared counter how far the lexer has read.
class CountingIterator {
 public:
  using iterator_category = std::input_iterator_tag;
  using value_type = char;
  using difference_type = std::ptrdiff_t;
  using pointer = const char*;
  using reference = const char&;

  CountingIterator(const char* p, std::size_t* consumed) : p_(p), consumed_(consumed) {}
  reference operator*() const { return *p_; }
  CountingIterator& operator++() {
    ++p_;
    ++*consumed_;
    return *this;
  }
  CountingIterator operator++(int) {
    CountingIterator old = *this;
    ++*this;
    return old;
  }
  bool operator==(const CountingIterator& o) const { return p_ == o.p_; }
  bool operator!=(const CountingIterator& o) const { return p_ != o.p_; }

 private:
  const char* p_;
  std::size_t* consumed_;
};

}  // namespace

std::string escape_pointer_token(const std::string& token) {
  std::string out;
  for (char c : token) {
    if (c == '~') out += "~0";
    else if (c == '/') out += "~1";
    else out += c;
  }
  return out;
}

namespace {

class PositionRecorder : public nlohmann::json_sax<nlohmann::json> {
 public:
  PositionRecorder(const std::size_t* consumed, std::unordered_map<std::string, std::size_t>* offsets, std::string_view text)
      : consumed_(consumed), offsets_(offsets), text_(text) {}

  bool null() override { return value(); }
  bool boolean(bool) override { return value(); }
  bool number_integer(number_integer_t) override { return value(); }
  bool number_unsigned(number_unsigned_t) override { return value(); }
  bool number_float(number_float_t, const string_t&) override { return value(); }
  bool string(string_t&) override { return value(); }
  bool binary(binary_t&) override { return value(); }
  bool start_object(std::size_t) override {
    record(start_of_token('{'));
    frames_.push_back({false, 0, {}});
    return true;
  }
  bool key(string_t& k) override {
    frames_.back().key = k;
    return true;
  }
  bool end_object() override { return close(); }
  bool start_array(std::size_t) override {
    record(start_of_token('['));
    frames_.push_back({true, 0, {}});
    return true;
  }
  bool end_array() override { return close(); }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception&) override { return false; }

 private:
  struct Frame {
    bool is_array;
    std::size_t index;
    std::string key;
  };

  std::string pointer() const {
    std::string p;
    for (const Frame& f : frames_) p += "/" + (f.is_array ? std::to_string(f.index) : escape_pointer_token(f.key));
    return p;
  }
  // The lexer has read one character past a scalar; walk back over it and the scalar to its first character.
  std::size_t start_of_scalar() const {
    std::size_t end = *consumed_ > text_.size() ? text_.size() : *consumed_;
    std::size_t i = end;
    while (i > 0 && std::string_view(" \t\r\n,]}:").find(text_[i - 1]) != std::string_view::npos) --i;
    if (i > 0 && text_[i - 1] == '"') {
      --i;
      while (i > 0 && !(text_[i - 1] == '"' && (i < 2 || text_[i - 2] != '\\'))) --i;
      return i > 0 ? i - 1 : 0;
    }
    while (i > 0 && std::string_view(" \t\r\n,[{:").find(text_[i - 1]) == std::string_view::npos) --i;
    return i;
  }
  std::size_t start_of_token(char bracket) const {
    std::size_t i = *consumed_ > text_.size() ? text_.size() : *consumed_;
    while (i > 0 && text_[i - 1] != bracket) --i;
    return i > 0 ? i - 1 : 0;
  }
  // A key given twice keeps its last value (nlohmann's rule), so its last position is the one to report.
  void record(std::size_t offset) { (*offsets_)[pointer()] = offset; }
  bool value() {
    record(start_of_scalar());
    advance();
    return true;
  }
  bool close() {
    frames_.pop_back();
    advance();
    return true;
  }
  void advance() {
    if (!frames_.empty() && frames_.back().is_array) ++frames_.back().index;
  }

  const std::size_t* consumed_;
  std::unordered_map<std::string, std::size_t>* offsets_;
  std::string_view text_;
  std::vector<Frame> frames_;
};

}  // namespace

JsonPositions::JsonPositions(std::string_view text) : text_(text) {
  std::size_t consumed = 0;
  PositionRecorder recorder(&consumed, &offsets_, text);
  CountingIterator first(text.data(), &consumed), last(text.data() + text.size(), &consumed);
  nlohmann::json::sax_parse(first, last, &recorder);
}

TextPosition JsonPositions::find(const std::string& pointer) const {
  const auto it = offsets_.find(pointer);
  if (it == offsets_.end()) return {};
  return position_of_offset(text_, it->second);
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
