// The two kinds of error the program reports as one line and a non-zero exit: bad input, and a failing backend.
#pragma once

#include <stdexcept>
#include <string>
#include <string_view>

namespace pt {

// A message made safe to print as one line: control characters (bytes below 0x20, DEL, and the C1 controls
// U+0080 to U+009F in UTF-8) are written as escapes (\n, \r, \t, \x1b, \u009b), so that text taken from an input
// (a key, a name, a file path) can neither start a new line nor send a terminal an escape sequence.
inline std::string escape_control_characters(std::string_view text) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  out.reserve(text.size());
  for (std::size_t i = 0; i < text.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (c == '\n')
      out += "\\n";
    else if (c == '\r')
      out += "\\r";
    else if (c == '\t')
      out += "\\t";
    else if (c < 0x20 || c == 0x7f)
      out += {'\\', 'x', kHex[c >> 4], kHex[c & 15]};
    else if (c == 0xc2 && i + 1 < text.size() && static_cast<unsigned char>(text[i + 1]) >= 0x80 && static_cast<unsigned char>(text[i + 1]) <= 0x9f) {
      const unsigned char code = static_cast<unsigned char>(text[++i]);
      out += {'\\', 'u', '0', '0', kHex[code >> 4], kHex[code & 15]};
    } else
      out += static_cast<char>(c);
  }
  return out;
}

// Bad input: the message names the file and the place in it. Thrown only by host code, never in kernels. Its
// message is always one line (escape_control_characters), whatever the input put into it.
class InputError : public std::runtime_error {
 public:
  explicit InputError(std::string_view message) : std::runtime_error(escape_control_characters(message)) {}
  explicit InputError(const std::string& message) : InputError(std::string_view(message)) {}
  explicit InputError(const char* message) : InputError(std::string_view(message)) {}
};

// Errors of a backend (no device, out of memory, a failed launch): one clear line, never a crash.
class BackendError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace pt
