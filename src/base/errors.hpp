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

// A value from an input quoted in a message (a name, a key, a file name): at most 60 characters of it, control
// characters escaped. A 50 MB string in a scene must not become a 50 MB message.
inline std::string clip(std::string_view text) {
  return escape_control_characters(text.size() <= 60 ? text : text.substr(0, 57)) + (text.size() <= 60 ? "" : "...");
}

// The longest message an InputError keeps: room for a place, a few clipped values and the explanation. Longer ones
// (a value quoted whole by a library) are cut, what is cut said.
inline constexpr std::size_t kMaxErrorMessage = 1000;

inline std::string one_line_message(std::string_view message) {
  if (message.size() <= kMaxErrorMessage) return escape_control_characters(message);
  std::size_t keep = kMaxErrorMessage - 40;
  while (keep > 0 && (static_cast<unsigned char>(message[keep]) & 0xc0) == 0x80) --keep;  // not inside a UTF-8 character
  return escape_control_characters(message.substr(0, keep)) + "... (" + std::to_string(message.size() - keep) + " more characters)";
}

// Bad input: the message names the file and the place in it. Thrown only by host code, never in kernels. Its
// message is always one line (escape_control_characters) of at most about kMaxErrorMessage characters, whatever the
// input put into it.
class InputError : public std::runtime_error {
 public:
  explicit InputError(std::string_view message) : std::runtime_error(one_line_message(message)) {}
  explicit InputError(const std::string& message) : InputError(std::string_view(message)) {}
  explicit InputError(const char* message) : InputError(std::string_view(message)) {}
};

// Errors of a backend (no device, out of memory, a failed launch): one clear line, never a crash.
class BackendError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace pt
