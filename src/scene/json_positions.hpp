// Where each value of a JSON text starts (line and column), keyed by its JSON pointer, so that errors found
// after parsing can still point into the file.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <unordered_map>

namespace pt {

struct TextPosition {
  std::size_t line = 0, column = 0;  // 1-based; 0 when unknown
};

// A key as a JSON-pointer token: '~' becomes "~0" and '/' becomes "~1" (RFC 6901).
std::string escape_pointer_token(const std::string& token);

class JsonPositions {
 public:
  // Records positions for a text that nlohmann::json accepts; for other texts the map stays partial.
  explicit JsonPositions(std::string_view text);
  TextPosition find(const std::string& pointer) const;
  static TextPosition position_of_offset(std::string_view text, std::size_t offset);

 private:
  std::unordered_map<std::string, std::size_t> offsets_;
  std::string_view text_;
};

}  // namespace pt
