// Reading a model file (or a file it names, such as an MTL library) whole into memory, through the checked input of
// base/input_file.hpp: a folder, FIFO or device given as one is refused with what it is, never read.
#pragma once

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <string>
#include <string_view>

#include <fmt/format.h>

#include "base/errors.hpp"
#include "base/input_file.hpp"

namespace pt {

// The content of `path`. `prefix` starts every message (the file itself, or "MODEL: material library 'NAME'" for a
// file the model names); `kind` says what the file should be ("PLY file", "material library").
inline std::string read_model_input(const std::filesystem::path& path, std::string_view prefix, std::string_view kind) {
  InputFile input = InputFile::open(path);
  switch (input.problem()) {
    case InputFile::Problem::kNone: break;
    case InputFile::Problem::kMissing: throw InputError(fmt::format("{}: cannot open the {}: no such file", prefix, kind));
    case InputFile::Problem::kFolder: throw InputError(fmt::format("{}: is a folder, not a {}", prefix, kind));
    case InputFile::Problem::kNotRegular: throw InputError(fmt::format("{}: is {}, not a {}", prefix, input.reason(), kind));
    case InputFile::Problem::kCannotOpen: throw InputError(fmt::format("{}: cannot open the {}: {}", prefix, kind, input.reason()));
  }
  std::string content;
  if (!input.read_all(content)) throw InputError(fmt::format("{}: cannot read the {}: {}", prefix, kind, std::strerror(errno)));
  return content;
}

// Names from a model file in messages: at most 60 characters of them, control characters escaped (warnings are
// printed as they are; InputError escapes its message itself).
inline std::string clip(std::string_view text) {
  return escape_control_characters(text.size() <= 60 ? text : text.substr(0, 57)) + (text.size() <= 60 ? "" : "...");
}

}  // namespace pt
