// Reading a model file (or a file it names, such as an MTL library) whole into memory, through the checked input of
// base/input_file.hpp: a folder, FIFO or device given as one is refused with what it is, never read.
#pragma once

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <string>
#include <string_view>
#include <system_error>

#include <fmt/format.h>

#include "base/errors.hpp"
#include "base/input_file.hpp"
#include "loading/model_files.hpp"

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

// Empty when `path` (a file that the model file in `model_folder` names) may be read; otherwise why not, a phrase
// that follows the name in a message. Symbolic links are resolved on both sides, so that a link in the folder
// cannot lead out of it.
inline std::string outside_model_folder(const std::filesystem::path& model_folder, const std::filesystem::path& path, ModelReferences references) {
  if (references == ModelReferences::kAnywhere) return "";
  std::error_code error;
  const std::filesystem::path folder = std::filesystem::weakly_canonical(model_folder.empty() ? "." : model_folder, error);
  const std::filesystem::path file = error ? std::filesystem::path() : std::filesystem::weakly_canonical(path, error);
  if (!error) {
    const std::filesystem::path relative = file.lexically_relative(folder);
    if (!relative.empty() && *relative.begin() != ".." && relative != ".") return "";
  }
  return "lies outside the model's folder (--trust-model-paths lets a model read it)";
}

}  // namespace pt
