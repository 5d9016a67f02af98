// Helpers shared by the passes over a scene's JSON text (json_outline.cpp, json_positions.cpp): an iterator that
// tells how far nlohmann's lexer has read, where a value starts and ends, and the nesting limit.
#pragma once

#include <cstddef>
#include <iterator>
#include <string_view>

namespace pt {

// Arrays and objects nested deeper than this are refused before anything is built for them: scenes need fewer
// than ten levels, and a bound keeps every pass over the text linear in its size (docs/scene-format.md).
inline constexpr std::size_t kMaxJsonNesting = 256;

// A character iterator that tells a shared counter how far the lexer has read (SAX events carry no positions).
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

// Where the next value starts, given where the previous SAX event ended: past whitespace, ',' and ':'. (After a
// number the lexer has read one character more, always one of these or a closing bracket, which no value follows.)
inline std::size_t start_of_next_value(std::string_view text, std::size_t previous_end) {
  std::size_t i = previous_end < text.size() ? previous_end : text.size();
  while (i < text.size() && std::string_view(" \t\r\n,:").find(text[i]) != std::string_view::npos) ++i;
  return i;
}

// One past the last character of the scalar (string, number or literal) that starts at `begin`.
inline std::size_t end_of_scalar(std::string_view text, std::size_t begin) {
  std::size_t i = begin;
  if (i < text.size() && text[i] == '"') {
    for (++i; i < text.size() && text[i] != '"'; ++i)
      if (text[i] == '\\') ++i;
    return i < text.size() ? i + 1 : text.size();
  }
  while (i < text.size() && std::string_view(" \t\r\n,:]}").find(text[i]) == std::string_view::npos) ++i;
  return i;
}

}  // namespace pt
