// Where a value of a JSON text starts (line and column), found from its JSON pointer when an error needs it: the
// text is scanned again then, so that nothing is stored per value while a scene is read.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

namespace pt {

struct TextPosition {
  std::size_t line = 0, column = 0;  // 1-based; 0 when unknown
};

// A key as a JSON-pointer token: '~' becomes "~0" and '/' becomes "~1" (RFC 6901).
std::string escape_pointer_token(const std::string& token);

// The offset of the first character of the value at `pointer` in `text`, which must be JSON that nlohmann::json
// accepts; of a key given twice, the last (the one nlohmann keeps). Nothing when the pointer names no value.
// Takes one pass over the text, in memory bounded by its nesting.
std::optional<std::size_t> find_value_offset(std::string_view text, const std::string& pointer);

class JsonPositions {
 public:
  // Keeps a view of the text (which must outlive this); the work is done by find, for errors only.
  explicit JsonPositions(std::string_view text) : text_(text) {}
  TextPosition find(const std::string& pointer) const;
  static TextPosition position_of_offset(std::string_view text, std::size_t offset);

 private:
  std::string_view text_;
};

}  // namespace pt
