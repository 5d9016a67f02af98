// Where a value of a parsed scene was written in its file, found again for an error message.
#include <fmt/format.h>

#include "scene/json_positions.hpp"
#include "scene/scene.hpp"

namespace pt {

std::string source_position(const SceneDescription& scene, const std::string& pointer) {
  if (!scene.written.text) return scene.source;
  const TextPosition at = JsonPositions(*scene.written.text).find(pointer);
  return at.line ? fmt::format("{}:{}:{}", scene.source, at.line, at.column) : scene.source;
}

}  // namespace pt
