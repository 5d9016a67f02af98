// The first pass over a glTF file's JSON, before tinygltf reads it: every property the reader or tinygltf takes is
// checked for its type, range and references, so that a malformed file is refused with the JSON path of its fault
// instead of being read differently (tinygltf skips a property of the wrong type, and cuts integers to an int).
// Also checked here: the byte ranges of buffer views and accessors, the node hierarchy (one parent at most, no
// loops), data URIs, external buffer files, and the extensions a file requires. Private to the glTF reader.
#pragma once

#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

#include "kernel/platform.hpp"
#include "loading/model_files.hpp"

namespace pt::gltf {

// The deepest nesting of arrays and objects read: glTF's own structure goes about ten deep.
inline constexpr std::size_t kMaxJsonNesting = 64;

// Throws InputError ("FILE: JSON nesting deeper than ...") unless the text nests at most kMaxJsonNesting deep, so
// that neither JSON library recurses further than that (tinygltf copies `extras` and `extensions` recursively).
void check_json_nesting(const std::string& file_name, const char* text, std::size_t size);

// A file reference as tinygltf decodes it (percent escapes; a '+' as a space), so that the file checked here is the
// file tinygltf asks for.
std::string decode_uri(const std::string& uri);

// What the JSON is read against.
struct JsonCheckInput {
  std::string file_name;                                           // for messages
  std::string folder_prefix;                                       // the folder of the file, ending in '/': external files are relative to it
  bool binary = false;                                             // a .glb
  std::optional<u64> bin_chunk_length;                             // a .glb's BIN chunk, if it has one
  ModelReferences references = ModelReferences::kInsideItsFolder;  // which external files may be named
};

// What the reader needs from the JSON besides the checks.
struct JsonFacts {
  std::vector<std::string> external_buffers;     // folder_prefix + decoded URI of each buffer given by a file reference
  std::vector<std::string> external_images;      // the same for images
  std::vector<std::string> extensions_not_read;  // each extension the file uses that is not read (they warn)
  std::vector<std::size_t> primitives;           // the number of primitives of each mesh
  std::size_t accessors = 0, buffers = 0, buffer_views = 0, cameras = 0, images = 0, materials = 0, nodes = 0, scenes = 0, textures = 0;
};

// Throws InputError ("FILE: /JSON/PATH: PROBLEM") at the first fault.
JsonFacts check_gltf_json(const nlohmann::json& root, const JsonCheckInput& input);

}  // namespace pt::gltf
